//! Writes a hard-surface test model as OBJ: an arcade wall of round arches on square piers,
//! in millimetres, its outline extruded to a thickness. Flat faces meet at right angles
//! along every outline edge while each arch's underside curves in small steps, so Loop
//! subdivision rounds the whole wall into a blob unless the sharp edges are kept as creases
//! (`gridrt render arcade.obj --crease-angle 30`).
//!
//! `cargo run --release --example arcade -- [OUTPUT.obj] [ARCHES]`

use std::fmt::Write as _;

/// Millimetres.
const PIER: f64 = 600.0;
const SPAN: f64 = 2000.0;
const SPRING: f64 = 2000.0;
const HEIGHT: f64 = 3600.0;
const DEPTH: f64 = 700.0;
/// Straight segments per arch.
const ARCH_STEPS: usize = 24;

/// The wall's outline, counter-clockwise in the xy plane: along the ground, up each pier,
/// over each arch, down the next pier, then back along the top.
fn outline(arches: usize) -> Vec<[f64; 2]> {
    let mut points = Vec::new();
    for a in 0..arches {
        let x = a as f64 * (PIER + SPAN);
        points.extend([[x, 0.0], [x + PIER, 0.0], [x + PIER, SPRING]]);
        let centre = x + PIER + SPAN / 2.0;
        for s in 1..ARCH_STEPS {
            let angle = std::f64::consts::PI * (1.0 - s as f64 / ARCH_STEPS as f64);
            points.push([centre + SPAN / 2.0 * angle.cos(), SPRING + SPAN / 2.0 * angle.sin()]);
        }
        // Down the next pier, whose foot starts the next bay.
        points.push([x + PIER + SPAN, SPRING]);
    }
    let last = arches as f64 * (PIER + SPAN);
    points.extend([[last, 0.0], [last + PIER, 0.0], [last + PIER, HEIGHT], [0.0, HEIGHT]]);
    points
}

/// Twice the signed area of triangle `a b c` (positive when counter-clockwise).
fn cross(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// Triangulates a simple counter-clockwise polygon by clipping ears: each round cuts off a
/// convex corner whose triangle holds no other corner.
fn triangulate(polygon: &[[f64; 2]]) -> Vec<[usize; 3]> {
    let mut left: Vec<usize> = (0..polygon.len()).collect();
    let mut triangles = Vec::new();
    while left.len() > 3 {
        let n = left.len();
        let ear = (0..n)
            .find(|&k| {
                let [a, b, c] = [left[(k + n - 1) % n], left[k], left[(k + 1) % n]].map(|i| polygon[i]);
                cross(a, b, c) > 0.0
                    && left.iter().all(|&i| {
                        let p = polygon[i];
                        p == a
                            || p == b
                            || p == c
                            || cross(a, b, p) < 0.0
                            || cross(b, c, p) < 0.0
                            || cross(c, a, p) < 0.0
                    })
            })
            .expect("a simple polygon always has an ear");
        triangles.push([left[(ear + n - 1) % n], left[ear], left[(ear + 1) % n]]);
        left.remove(ear);
    }
    triangles.push([left[0], left[1], left[2]]);
    triangles
}

fn main() -> std::io::Result<()> {
    let mut args = std::env::args().skip(1);
    let output = args.next().unwrap_or_else(|| "arcade.obj".to_string());
    let arches = args.next().and_then(|a| a.parse().ok()).unwrap_or(3usize);
    let points = outline(arches);
    let n = points.len();
    let mut obj = format!("# an arcade of {arches} arches, millimetres\n");
    // Front (z = 0) vertices 1..=n, back (z = DEPTH) n+1..=2n.
    for z in [0.0, DEPTH] {
        for [x, y] in &points {
            writeln!(obj, "v {x:.3} {y:.3} {z:.1}").unwrap();
        }
    }
    for [a, b, c] in triangulate(&points) {
        // The front faces -z, the back +z.
        writeln!(obj, "f {} {} {}", a + 1, c + 1, b + 1).unwrap();
        writeln!(obj, "f {} {} {}", a + n + 1, b + n + 1, c + n + 1).unwrap();
    }
    // The sides: a quad along each outline edge, facing out of the wall.
    for k in 0..n {
        let (a, b) = (k + 1, (k + 1) % n + 1);
        writeln!(obj, "f {a} {b} {} {}", b + n, a + n).unwrap();
    }
    std::fs::write(&output, obj)?;
    println!("{output}: {arches} arches, {} vertices", 2 * n);
    Ok(())
}
