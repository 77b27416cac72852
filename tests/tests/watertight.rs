//! Rays aimed exactly at the shared edges and vertices of a closed subdivided mesh never pass
//! through it, in either representation.

use gridrt::mesh::scene::default_scene;
use gridrt::scene::Scene;
use gridrt::subdiv::Scheme;
use gridrt_shared::glam::Vec3;
use gridrt_shared::ray::{Ray, T_FAR};
use gridrt_tests::{build_pair, Rng};

/// A ray from outside the bounds to a point on a closed surface must hit the surface no
/// later than that point.
fn leaks(scene: &Scene, origin: Vec3, target: Vec3) -> bool {
    let dir = target - origin;
    let distance = dir.length();
    let hit = scene.trace(&Ray::new(origin, dir / distance), T_FAR);
    !hit.is_hit() || hit.t > distance * (1.0 + 1e-5)
}

#[test]
fn closed_mesh_has_no_cracks() {
    let mesh = default_scene();
    for (levels, scheme) in [(3, Scheme::Loop), (2, Scheme::Flat)] {
        let pair = build_pair(&mesh, levels, levels, scheme);
        let b = pair.bounds;
        let center = b.center();
        let radius = (b.max - b.min).length();
        let mut rng = Rng::new(99);
        let micro = pair.sub.micro_triangles(levels);
        let mut targets = Vec::new();
        // Every third micro-triangle: its three vertices and three edge midpoints, the
        // latter being exactly on an edge up to rounding.
        for t in micro.iter().step_by(3) {
            let p = t.map(|v| pair.sub.positions[v as usize]);
            targets.extend_from_slice(&p);
            targets.extend([(p[0] + p[1]) * 0.5, (p[1] + p[2]) * 0.5, (p[2] + p[0]) * 0.5]);
        }
        let (mut grid_leaks, mut triangle_leaks) = (0, 0);
        for &target in &targets {
            // From a random point on a sphere around everything, so the ray comes from outside.
            let origin = center + rng.direction() * radius * 1.5;
            grid_leaks += leaks(&pair.grids, origin, target) as usize;
            triangle_leaks += leaks(&pair.triangles, origin, target) as usize;
        }
        eprintln!(
            "{scheme:?} L={levels}: {} rays at vertices and edges, {grid_leaks} leaks (grids), {triangle_leaks} (triangles)",
            targets.len()
        );
        assert_eq!(grid_leaks, 0);
        assert_eq!(triangle_leaks, 0);
    }
}
