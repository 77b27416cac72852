//! Displacement directions: one unit vector per base vertex, along which its micro-vertices
//! move. The area-weighted mean of the normals of the triangles around the vertex (the sum of
//! their unnormalised cross products): smooth across the base surface, so the lines of
//! neighbouring micro-vertices do not cross where the surface bends gently.
//!
//! Where the normals cancel (a vertex on a fin of triangles facing both ways, as raw scans
//! have), the normal of its largest triangle is taken instead; a vertex of only zero-area
//! triangles gets +z. Every direction is finite and of unit length.

use gridrt_shared::glam::Vec3;

use crate::mesh::Mesh;

pub fn area_weighted_normals(base: &Mesh) -> Vec<Vec3> {
    let mut sums = vec![Vec3::ZERO; base.positions.len()];
    let mut largest = vec![Vec3::ZERO; base.positions.len()];
    for t in &base.triangles {
        let [a, b, c] = t.map(|i| base.positions[i as usize]);
        let n = (b - a).cross(c - a);
        for &i in t {
            sums[i as usize] += n;
            if n.length_squared() > largest[i as usize].length_squared() {
                largest[i as usize] = n;
            }
        }
    }
    (sums.iter().zip(&largest))
        .map(|(&sum, &large)| {
            // A sum much shorter than its largest term is mostly cancellation.
            let direction = if sum.length() > 1e-3 * large.length() {
                sum
            } else {
                large
            };
            direction.try_normalize().unwrap_or(Vec3::Z)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tent_points_its_ridge_up_and_its_sides_out() {
        // Two triangles meeting at the ridge from (0, 0, 1) to (0, 1, 1), sloping down to x = +-1.
        let base = Mesh {
            positions: vec![
                Vec3::new(0.0, 0.0, 1.0),
                Vec3::new(0.0, 1.0, 1.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(-1.0, 0.0, 0.0),
            ],
            triangles: vec![[0, 2, 1], [0, 1, 3]],
        };
        let d = area_weighted_normals(&base);
        assert!((d[0] - Vec3::Z).length() < 1e-6, "{}", d[0]);
        assert!(
            (d[2] - Vec3::new(1.0, 0.0, 1.0).normalize()).length() < 1e-6,
            "{}",
            d[2]
        );
        assert!(d.iter().all(|v| (v.length() - 1.0).abs() < 1e-6));
    }

    #[test]
    fn cancelling_and_degenerate_neighbourhoods_still_get_a_direction() {
        // The same triangle twice, facing both ways; and a vertex of one zero-area triangle.
        let base = Mesh {
            positions: vec![
                Vec3::ZERO,
                Vec3::X,
                Vec3::Y,
                Vec3::new(5.0, 0.0, 0.0),
                Vec3::new(6.0, 0.0, 0.0),
                Vec3::new(7.0, 0.0, 0.0),
            ],
            triangles: vec![[0, 1, 2], [0, 2, 1], [3, 4, 5]],
        };
        let d = area_weighted_normals(&base);
        assert!((d[0].z.abs() - 1.0).abs() < 1e-6, "{}", d[0]);
        assert_eq!(d[3], Vec3::Z);
    }
}
