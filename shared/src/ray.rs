use crate::glam::Vec3;

/// "No bound" and "no intersection" distance. Finite on purpose: shader translators reject
/// infinite float constants, and every comparison works the same with the largest float.
pub const T_FAR: f32 = f32::MAX;

/// A ray plus the per-ray constants every box and triangle test needs, computed once.
#[repr(C)]
#[derive(Copy, Clone, Debug)]
pub struct Ray {
    pub origin: Vec3,
    pub dir: Vec3,
    /// Component-wise reciprocal of `dir` for the slab test; a zero component is replaced by a
    /// tiny one so the reciprocal stays finite and `0 * 1/dir` never makes a NaN (which GPU
    /// `min`/`max` would resolve arbitrarily).
    pub inv_dir: Vec3,
    /// Shear constants of the watertight triangle test: with `kz` the dominant axis of `dir`
    /// and `kx`, `ky` the other two (in winding order), `(dir[kx] / dir[kz], dir[ky] / dir[kz],
    /// 1 / dir[kz])`.
    pub shear: Vec3,
    /// The permutation and shear as the rows of a matrix, `e_kx - sx e_kz`, `e_ky - sy e_kz`
    /// and `sz e_kz`, so a vertex is sheared by three dot products instead of picking
    /// components by index (a branch per component on the CPU). Each row's other entries are
    /// 1 and 0, whose products are exact, so the dot products round exactly like
    /// `a[kx] - sx a[kz]` and friends.
    pub shear_rows: [Vec3; 3],
}

impl Ray {
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        let a = dir.abs();
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        // Keep the winding: swapping x and y when the dominant component is negative.
        if component(dir, kz) < 0.0 {
            core::mem::swap(&mut kx, &mut ky);
        }
        let dz = component(dir, kz);
        let shear = Vec3::new(component(dir, kx) / dz, component(dir, ky) / dz, 1.0 / dz);
        let unit = |k: u32| Vec3::new((k == 0) as u32 as f32, (k == 1) as u32 as f32, (k == 2) as u32 as f32);
        let shear_rows = [
            unit(kx) - unit(kz) * shear.x,
            unit(ky) - unit(kz) * shear.y,
            unit(kz) * shear.z,
        ];
        Ray {
            origin,
            dir,
            inv_dir: Vec3::ONE / Vec3::new(nonzero(dir.x), nonzero(dir.y), nonzero(dir.z)),
            shear,
            shear_rows,
        }
    }

    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }
}

#[inline]
fn nonzero(c: f32) -> f32 {
    const TINY: f32 = 1e-30;
    if c.abs() >= TINY {
        c
    } else if c < 0.0 {
        -TINY
    } else {
        TINY
    }
}

/// `v[k]` written as selects, which every target handles without dynamic vector indexing.
#[inline]
pub fn component(v: Vec3, k: u32) -> f32 {
    if k == 0 {
        v.x
    } else if k == 1 {
        v.y
    } else {
        v.z
    }
}
