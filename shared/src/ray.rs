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
    /// The axes `kx`, `ky` and `kz`, two bits each from bit 0 (see [`Ray::axis`]): one register
    /// where a matrix of the permutation and shear took nine, held by every traversal.
    pub axes: u32,
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
        Ray {
            origin,
            dir,
            inv_dir: Vec3::ONE / Vec3::new(nonzero(dir.x), nonzero(dir.y), nonzero(dir.z)),
            shear,
            axes: kx | ky << 2 | kz << 4,
        }
    }

    /// Axis `i` of the sheared frame: `kx`, `ky`, `kz` for `i` = 0, 1, 2.
    #[inline]
    pub fn axis(&self, i: u32) -> u32 {
        (self.axes >> (2 * i)) & 3
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

/// `v[k]` for `k` in 0..3: in a shader as selects, which every target handles without dynamic
/// vector indexing.
#[cfg(target_arch = "spirv")]
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

/// `v[k]` for `k` in 0..3: natively a read from the stack, where selects would branch on the
/// axis, which varies from ray to ray. The fourth entry only lets `k & 3` index without a
/// bounds check.
#[cfg(not(target_arch = "spirv"))]
#[inline]
pub fn component(v: Vec3, k: u32) -> f32 {
    [v.x, v.y, v.z, v.z][(k & 3) as usize]
}
