//! The built-in default scene and small closed test shapes, generated in code (and [`fins`],
//! the one open, non-manifold test mesh).
//!
//! Every shape is a closed, manifold, outward-facing (counter-clockwise seen from outside) triangle mesh without
//! duplicate vertices, so the whole scene, a disjoint union of them, is too. Shapes are coarse on purpose: they
//! are meant to be refined by Loop subdivision, which rounds them (and shrinks convex ones a little). Y is up.

use std::f32::consts::TAU;

use gridrt_shared::glam::{Quat, Vec3};

use super::Mesh;

/// A torus, an icosahedron and an octahedron side by side along x, resting on a wide, thin ground slab whose top
/// is the plane y = 0 over x in [-4.5, 4.5], z in [-3, 3]. 560 triangles.
pub fn default_scene() -> Mesh {
    let mut scene = slab([-4.5, 4.5], [-3.0, 3.0], 0.2, [9, 6]);
    // Tilted so that the hole shows from a camera in front (+z) as well as from above.
    let torus = transformed(torus(1.0, 0.4, 16, 8), Quat::from_rotation_x(-1.0), Vec3::ZERO);
    let icosahedron = transformed(icosahedron(), Quat::from_rotation_y(0.3), Vec3::ZERO);
    let octahedron = transformed(octahedron(), Quat::from_rotation_y(0.5), Vec3::ZERO);
    for (shape, x, z) in [(torus, -2.6, 0.3), (icosahedron, 0.0, -0.3), (octahedron, 2.6, 0.3)] {
        // A small gap keeps the shapes from touching the slab, so the union stays a set of separate closed surfaces.
        let lift = 0.01 - shape.bounds().0.y;
        append(&mut scene, transformed(shape, Quat::IDENTITY, Vec3::new(x, lift, z)));
    }
    scene
}

/// Not closed, unlike the shapes: three triangles on one edge (0, 1), open boundaries, a base
/// vertex on four creases, and a vertex (6) no triangle uses. For tests of the crease rules.
pub fn fins() -> Mesh {
    Mesh {
        positions: vec![
            Vec3::ZERO,
            Vec3::X,
            Vec3::new(0.5, 1.0, 0.0),
            Vec3::new(0.5, -1.0, 0.0),
            Vec3::new(0.5, 0.0, 1.0),
            Vec3::new(1.5, 0.7, 0.2),
            Vec3::new(9.0, 9.0, 9.0),
            Vec3::new(-0.5, 0.3, -0.4),
        ],
        triangles: vec![[0, 1, 2], [1, 0, 3], [0, 1, 4], [1, 5, 2], [2, 7, 0], [3, 0, 7]],
    }
}

/// A regular tetrahedron inscribed in the cube [-1, 1]^3: 4 vertices, 4 triangles.
pub fn tetrahedron() -> Mesh {
    let positions = vec![
        Vec3::new(1.0, 1.0, 1.0),
        Vec3::new(1.0, -1.0, -1.0),
        Vec3::new(-1.0, 1.0, -1.0),
        Vec3::new(-1.0, -1.0, 1.0),
    ];
    convex_from_edges(positions, 8f32.sqrt())
}

/// The cube [-1, 1]^3: 8 vertices (vertex i has x from bit 0, y from bit 1, z from bit 2), 12 triangles.
pub fn cube() -> Mesh {
    let positions = (0..8)
        .map(|i| Vec3::new(sign(i & 1), sign(i & 2), sign(i & 4)))
        .collect();
    let quads = [
        [0, 1, 3, 2],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 3, 7, 6],
        [0, 2, 6, 4],
        [1, 3, 7, 5],
    ];
    let triangles = quads.iter().flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]]).collect();
    orient_convex(Mesh { positions, triangles })
}

fn sign(bit: u32) -> f32 {
    if bit == 0 {
        -1.0
    } else {
        1.0
    }
}

/// A regular icosahedron with circumradius 1: 12 vertices, 20 triangles.
fn icosahedron() -> Mesh {
    let phi = (1.0 + 5f32.sqrt()) / 2.0;
    let mut positions = Vec::new();
    for a in [-1.0, 1.0] {
        for b in [-phi, phi] {
            positions.extend([Vec3::new(0.0, a, b), Vec3::new(a, b, 0.0), Vec3::new(b, 0.0, a)]);
        }
    }
    let radius = positions[0].length();
    convex_from_edges(positions.into_iter().map(|p| p / radius).collect(), 2.0 / radius)
}

/// A regular octahedron with circumradius 1: 6 vertices, 8 triangles.
pub fn octahedron() -> Mesh {
    let positions = [Vec3::X, Vec3::NEG_X, Vec3::Y, Vec3::NEG_Y, Vec3::Z, Vec3::NEG_Z].to_vec();
    convex_from_edges(positions, 2f32.sqrt())
}

/// A torus around the y axis: `major` radius of the centre circle, `minor` radius of the tube, `segments` quads
/// around the y axis and `sides` around the tube, each quad split into two triangles.
fn torus(major: f32, minor: f32, segments: u32, sides: u32) -> Mesh {
    let mut mesh = Mesh::default();
    for i in 0..segments {
        let u = TAU * i as f32 / segments as f32;
        for j in 0..sides {
            let v = TAU * j as f32 / sides as f32;
            let ring = major + minor * v.cos();
            mesh.positions
                .push(Vec3::new(ring * u.cos(), minor * v.sin(), ring * u.sin()));
        }
    }
    let id = |i: u32, j: u32| (i % segments) * sides + j % sides;
    for i in 0..segments {
        for j in 0..sides {
            // d/du x d/dv points into the tube, so the quad runs along v first to face outward.
            let [a, b, c, d] = [id(i, j), id(i, j + 1), id(i + 1, j + 1), id(i + 1, j)];
            mesh.triangles.extend([[a, b, c], [a, c, d]]);
        }
    }
    mesh
}

/// A closed box: top at y = 0 and bottom at y = -`thickness` over the `x` and `z` ranges, both faces split into a
/// `cells[0]` x `cells[1]` grid so that Loop subdivision keeps them flat and only rounds the rim. The sides are one
/// quad tall, sharing the grids' boundary vertices.
fn slab(x: [f32; 2], z: [f32; 2], thickness: f32, cells: [u32; 2]) -> Mesh {
    let [nx, nz] = cells;
    let per_face = (nx + 1) * (nz + 1);
    let id = |face: u32, i: u32, k: u32| face * per_face + k * (nx + 1) + i;
    let mut mesh = Mesh::default();
    for y in [0.0, -thickness] {
        for k in 0..=nz {
            for i in 0..=nx {
                let (fx, fz) = (i as f32 / nx as f32, k as f32 / nz as f32);
                mesh.positions
                    .push(Vec3::new(x[0] + (x[1] - x[0]) * fx, y, z[0] + (z[1] - z[0]) * fz));
            }
        }
    }
    let mut quad = |[a, b, c, d]: [u32; 4]| mesh.triangles.extend([[a, b, c], [a, c, d]]);
    for face in 0..2 {
        for k in 0..nz {
            for i in 0..nx {
                quad([
                    id(face, i, k),
                    id(face, i + 1, k),
                    id(face, i + 1, k + 1),
                    id(face, i, k + 1),
                ]);
            }
        }
    }
    // The grid boundary as one loop of (i, k), each side quad joining a boundary edge of the top to the bottom.
    let boundary: Vec<(u32, u32)> = (0..nx)
        .map(|i| (i, 0))
        .chain((0..nz).map(|k| (nx, k)))
        .chain((1..=nx).rev().map(|i| (i, nz)))
        .chain((1..=nz).rev().map(|k| (0, k)))
        .collect();
    for (n, &(i0, k0)) in boundary.iter().enumerate() {
        let (i1, k1) = boundary[(n + 1) % boundary.len()];
        quad([id(0, i0, k0), id(0, i1, k1), id(1, i1, k1), id(1, i0, k0)]);
    }
    orient_convex(mesh)
}

/// The faces of a convex polyhedron whose faces are all triangles with the given edge length: for the regular
/// tetrahedron, octahedron and icosahedron every triple of mutually adjacent vertices is a face.
fn convex_from_edges(positions: Vec<Vec3>, edge: f32) -> Mesh {
    let n = positions.len() as u32;
    let adjacent = |a: u32, b: u32| (positions[a as usize].distance(positions[b as usize]) - edge).abs() < 1e-4 * edge;
    let mut triangles = Vec::new();
    for a in 0..n {
        for b in a + 1..n {
            for c in b + 1..n {
                if adjacent(a, b) && adjacent(b, c) && adjacent(a, c) {
                    triangles.push([a, b, c]);
                }
            }
        }
    }
    orient_convex(Mesh { positions, triangles })
}

/// Turns every triangle of a convex body to face away from its centre; valid because each triangle lies in the
/// body's boundary, so its outward side is the one facing away from any interior point.
pub(crate) fn orient_convex(mut mesh: Mesh) -> Mesh {
    let center = mesh.positions.iter().copied().sum::<Vec3>() / mesh.positions.len() as f32;
    for t in &mut mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
        if (b - a).cross(c - a).dot((a + b + c) / 3.0 - center) < 0.0 {
            t.swap(1, 2);
        }
    }
    mesh
}

fn transformed(mut mesh: Mesh, rotation: Quat, offset: Vec3) -> Mesh {
    for p in &mut mesh.positions {
        *p = rotation * *p + offset;
    }
    mesh
}

fn append(to: &mut Mesh, part: Mesh) {
    let base = to.positions.len() as u32;
    to.positions.extend(part.positions);
    to.triangles
        .extend(part.triangles.into_iter().map(|t| t.map(|i| i + base)));
}

#[cfg(test)]
mod tests {
    use std::collections::{HashMap, HashSet};

    use super::*;

    /// Asserts a closed, consistently oriented, vertex-manifold mesh with positive volume; returns V - E + F.
    fn check_closed(name: &str, mesh: &Mesh) -> i64 {
        let mut directed = HashSet::new();
        for &[a, b, c] in &mesh.triangles {
            assert!(a != b && b != c && c != a, "{name}: degenerate triangle {a} {b} {c}");
            for edge in [(a, b), (b, c), (c, a)] {
                // Each directed edge once means no edge has more than two triangles and neighbours agree on order.
                assert!(directed.insert(edge), "{name}: directed edge {edge:?} appears twice");
            }
        }
        for &(a, b) in &directed {
            assert!(directed.contains(&(b, a)), "{name}: edge {a}-{b} has only one triangle");
        }
        // Around every vertex the triangles must form one fan closing on itself (no pinched vertices).
        let mut fans: Vec<HashMap<u32, u32>> = vec![HashMap::new(); mesh.positions.len()];
        for &[a, b, c] in &mesh.triangles {
            fans[a as usize].insert(b, c);
            fans[b as usize].insert(c, a);
            fans[c as usize].insert(a, b);
        }
        for (v, fan) in fans.iter().enumerate() {
            let start = *fan
                .keys()
                .next()
                .unwrap_or_else(|| panic!("{name}: vertex {v} is unused"));
            let (mut at, mut steps) = (fan[&start], 1);
            while at != start {
                at = fan[&at];
                steps += 1;
            }
            assert_eq!(steps, fan.len(), "{name}: vertex {v} is not manifold");
        }
        let distinct: HashSet<[u32; 3]> = mesh.positions.iter().map(|p| p.to_array().map(f32::to_bits)).collect();
        assert_eq!(
            distinct.len(),
            mesh.positions.len(),
            "{name}: duplicate vertex positions"
        );
        let volume: f32 = mesh
            .triangles
            .iter()
            .map(|t| t.map(|i| mesh.positions[i as usize]))
            .map(|[a, b, c]| a.dot(b.cross(c)) / 6.0)
            .sum();
        assert!(volume > 0.0, "{name}: signed volume {volume} is not positive");
        mesh.positions.len() as i64 - directed.len() as i64 / 2 + mesh.triangles.len() as i64
    }

    #[test]
    fn test_shapes_are_closed_and_outward() {
        assert_eq!((tetrahedron().positions.len(), tetrahedron().triangles.len()), (4, 4));
        assert_eq!((cube().positions.len(), cube().triangles.len()), (8, 12));
        assert_eq!((icosahedron().positions.len(), icosahedron().triangles.len()), (12, 20));
        assert_eq!((octahedron().positions.len(), octahedron().triangles.len()), (6, 8));
        for (name, mesh) in [
            ("tetrahedron", tetrahedron()),
            ("cube", cube()),
            ("icosahedron", icosahedron()),
        ] {
            assert_eq!(check_closed(name, &mesh), 2, "{name}: not a sphere");
        }
        assert_eq!(check_closed("octahedron", &octahedron()), 2);
        assert_eq!(check_closed("slab", &slab([-1.0, 2.0], [0.0, 1.0], 0.1, [3, 2])), 2);
        assert_eq!(check_closed("torus", &torus(1.0, 0.4, 16, 8)), 0);
        assert!((cube().bounds().0 + Vec3::ONE).length() < 1e-6);
    }

    #[test]
    fn default_scene_is_closed_small_and_grounded() {
        let scene = default_scene();
        // Three spheres (slab, icosahedron, octahedron) and a torus: 2 + 2 + 2 + 0.
        assert_eq!(check_closed("default scene", &scene), 6);
        assert!(scene.triangles.len() < 600, "{} triangles", scene.triangles.len());
        assert_eq!(scene.clone().validate("scene").unwrap().1, 0);
        let (lo, hi) = scene.bounds();
        assert!((lo.y + 0.2).abs() < 1e-6 && lo.x == -4.5 && hi.x == 4.5, "{lo} {hi}");
        // Everything but the slab floats just above its top face.
        let above = scene.positions.iter().filter(|p| p.y > 0.0).count();
        assert_eq!(above, 16 * 8 + 12 + 6);
        assert!(scene.positions.iter().all(|p| p.y <= 0.0 || p.y >= 0.0099));
        println!(
            "default scene: {} vertices, {} triangles, bounds {lo} .. {hi}",
            scene.positions.len(),
            scene.triangles.len()
        );
    }
}
