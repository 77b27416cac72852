//! Rays aimed exactly at the shared edges and vertices of a closed subdivided mesh never pass
//! through it, in either representation.

use std::collections::HashMap;

use gridrt::mesh::scene::default_scene;
use gridrt::scene::Scene;
use gridrt::subdiv::Scheme;
use gridrt_shared::glam::Vec3;
use gridrt_shared::ray::{Ray, T_FAR};
use gridrt_tests::{build_pair, Rng};

/// A ray that crosses the surface at `target` must hit something no later than `target`.
fn leaks(scene: &Scene, origin: Vec3, dir: Vec3, distance: f32) -> bool {
    let hit = scene.trace(&Ray::new(origin, dir), T_FAR);
    !hit.is_hit() || hit.t > distance * (1.0 + 1e-5)
}

/// A direction within `max_angle` of `axis`.
fn in_cone(rng: &mut Rng, axis: Vec3, max_angle: f32) -> Vec3 {
    loop {
        let d = rng.direction();
        if d.angle_between(axis) <= max_angle {
            return d;
        }
    }
}

#[test]
fn closed_mesh_has_no_cracks() {
    let mesh = default_scene();
    for (levels, scheme) in [(3, Scheme::Loop), (2, Scheme::Flat), (3, Scheme::Flat)] {
        let pair = build_pair(&mesh, levels, levels, scheme);
        let radius = (pair.bounds.max - pair.bounds.min).length();
        let pos = |v: u32| pair.sub.positions[v as usize];
        let micro = pair.sub.micro_triangles(levels);
        let normals: Vec<Vec3> = micro
            .iter()
            .map(|t| (pos(t[1]) - pos(t[0])).cross(pos(t[2]) - pos(t[0])).normalize_or_zero())
            .collect();
        // The faces around each vertex and each edge.
        let mut around: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
        for (k, t) in micro.iter().enumerate() {
            for e in 0..3 {
                let (a, b) = (t[e], t[(e + 1) % 3]);
                around.entry((a, a)).or_default().push(k);
                around.entry((a.min(b), a.max(b))).or_default().push(k);
            }
        }
        let mut rng = Rng::new(99);
        let (mut rays, mut skipped, mut grid_leaks, mut triangle_leaks) = (0, 0, 0, 0);
        for (k, t) in micro.iter().enumerate().step_by(3) {
            if normals[k] == Vec3::ZERO {
                continue;
            }
            // The three vertices exactly, and the three edges at their midpoints.
            let targets = [
                ((t[0], t[0]), pos(t[0])),
                ((t[1], t[1]), pos(t[1])),
                ((t[2], t[2]), pos(t[2])),
                ((t[0].min(t[1]), t[0].max(t[1])), (pos(t[0]) + pos(t[1])) * 0.5),
                ((t[1].min(t[2]), t[1].max(t[2])), (pos(t[1]) + pos(t[2])) * 0.5),
                ((t[2].min(t[0]), t[2].max(t[0])), (pos(t[2]) + pos(t[0])) * 0.5),
            ];
            for (key, target) in targets {
                // Only rays that cross the surface there: facing every triangle around the
                // target the same way (grazing rays may touch it and legitimately go on).
                let side = if rng.next_u32() & 1 == 0 { 1.0 } else { -1.0 };
                let dir = in_cone(&mut rng, normals[k] * side, 15f32.to_radians());
                let crossing = around[&key].iter().all(|&f| normals[f].dot(dir) * side > 0.05);
                if !crossing {
                    skipped += 1;
                    continue;
                }
                let distance = radius * (0.2 + rng.next_f32());
                let origin = target + dir * distance;
                let dir = -dir;
                rays += 1;
                grid_leaks += leaks(&pair.grids, origin, dir, distance) as usize;
                triangle_leaks += leaks(&pair.triangles, origin, dir, distance) as usize;
            }
        }
        eprintln!(
            "{scheme:?} L={levels}: {rays} rays at vertices and edges ({skipped} grazing ones skipped), \
             {grid_leaks} leaks (grids), {triangle_leaks} (triangles)"
        );
        assert!(rays > 10 * skipped, "too many grazing rays skipped");
        assert_eq!(grid_leaks, 0);
        assert_eq!(triangle_leaks, 0);
    }
}
