//! Our binned SAH builder against obvhs on the baseline's real input: the level-3 Loop micro-triangles of the test
//! meshes. Run with `cargo bench -p gridrt --bench bvh_build [-- MESH_SUBSTRING...]`.
//!
//! Both trees are judged by the one cost function, `bvh::sah_cost` (traversal 1, intersection 1, relative to the
//! root's area), after converting obvhs's `Bvh2Node`s to our `BvhNode` layout (which has the same
//! adjacent-children convention). obvhs 0.4 has no top-down binned SAH builder: its BVH2 builder is PLOC
//! (bottom-up) + reinsertion + an SAH leaf collapse. The "leaf<=4, Ct=1" variants set the collapse to our exact
//! leaf criterion (collapse when `A_parent * n <= A_parent * 1 + A_l * n_l + A_r * n_r`, at most 4 primitives), so
//! they are the configurations most like ours; the unmodified presets (leaf <= 8, collapse cost 3) are shown too.
//! obvhs is built with its `parallel` feature; both builders run on one thread and on all of them.

use std::path::Path;
use std::time::Instant;

use gridrt::bvh::{self, Aabb, Bvh};
use gridrt_shared::glam::{Vec3, Vec3A};
use gridrt_shared::layout::BvhNode;
use obvhs::BvhBuildParams;

const MESHES: [&str; 4] = ["bunny.obj", "teapot.obj", "dragon_res4.ply", "dragon_res3.ply"];
const RUNS: usize = 5;

struct Row {
    builder: String,
    threads: usize,
    ms: f64,
    nodes: usize,
    max_leaf: u32,
    depth: usize,
    sah: f32,
    note: String,
}

/// Median wall time of `RUNS` builds, and the first tree; `note` says whether every run gave the same tree.
fn time_builds(mut build: impl FnMut() -> Bvh) -> (f64, Bvh, bool) {
    let mut times = Vec::with_capacity(RUNS);
    let mut first: Option<Bvh> = None;
    let mut same = true;
    for _ in 0..RUNS {
        let start = Instant::now();
        let bvh = build();
        times.push(start.elapsed().as_secs_f64() * 1e3);
        match &first {
            None => first = Some(bvh),
            Some(f) => same &= f.nodes == bvh.nodes && f.order == bvh.order,
        }
    }
    times.sort_by(f64::total_cmp);
    (times[RUNS / 2], first.unwrap(), same)
}

/// Walks the tree from the root: every primitive in exactly one leaf and inside it, children inside parents,
/// every stored node reachable. Returns (max leaf size, depth).
fn check(bvh: &Bvh, boxes: &[Aabb]) -> Result<(u32, usize), String> {
    let node_box = |n: &BvhNode| Aabb {
        min: Vec3::from(n.min),
        max: Vec3::from(n.max),
    };
    let mut seen = vec![0u8; boxes.len()];
    let (mut reached, mut max_leaf, mut depth) = (0usize, 0u32, 0usize);
    let mut stack = vec![(0usize, 1usize)];
    while let Some((i, d)) = stack.pop() {
        let n = bvh.nodes.get(i).ok_or(format!("node {i} out of range"))?;
        reached += 1;
        depth = depth.max(d);
        if n.is_leaf() {
            max_leaf = max_leaf.max(n.count);
            let range = n.first as usize..(n.first + n.count) as usize;
            for &p in bvh.order.get(range).ok_or("leaf range out of bounds")? {
                seen[p as usize] += 1;
                if !node_box(n).contains(&boxes[p as usize]) {
                    return Err(format!("primitive {p} outside its leaf"));
                }
            }
        } else {
            for c in [n.first as usize, n.first as usize + 1] {
                let child = bvh.nodes.get(c).ok_or(format!("child {c} out of range"))?;
                if !node_box(n).contains(&node_box(child)) {
                    return Err(format!("node {c} outside its parent"));
                }
                stack.push((c, d + 1));
            }
        }
    }
    if let Some(p) = seen.iter().position(|&s| s != 1) {
        return Err(format!("primitive {p} is in {} leaves", seen[p]));
    }
    if reached != bvh.nodes.len() {
        return Err(format!(
            "{} of {} nodes unreachable",
            bvh.nodes.len() - reached,
            bvh.nodes.len()
        ));
    }
    Ok((max_leaf, depth))
}

fn row(builder: &str, threads: usize, boxes: &[Aabb], (ms, bvh, same): (f64, &Bvh, bool)) -> Row {
    let (max_leaf, depth, mut note) = match check(bvh, boxes) {
        Ok((l, d)) => (l, d, "covers all".to_string()),
        Err(e) => (0, 0, format!("INVALID: {e}")),
    };
    if !same {
        note += ", nondeterministic";
    }
    Row {
        builder: builder.to_string(),
        threads,
        ms,
        nodes: bvh.nodes.len(),
        max_leaf,
        depth,
        sah: bvh::sah_cost(&bvh.nodes, &gridrt::triangles::build_params()),
        note,
    }
}

fn from_obvhs(b: obvhs::bvh2::Bvh2) -> Bvh {
    let nodes = b
        .nodes
        .iter()
        .map(|n| BvhNode {
            min: n.aabb().min.to_array(),
            first: n.first_index,
            max: n.aabb().max.to_array(),
            count: n.prim_count,
        })
        .collect();
    Bvh {
        nodes,
        order: b.primitive_indices,
    }
}

/// Our leaf criterion in obvhs's collapse: at most 4 primitives, traversal cost 1 against intersection cost 1.
fn matched(p: BvhBuildParams) -> BvhBuildParams {
    BvhBuildParams {
        max_prims_per_leaf: 4,
        collapse_traversal_cost: 1.0,
        ..p
    }
}

/// Every filter must name (part of) the mesh or the builder.
fn wanted(filters: &[String], mesh: &str, builder: &str) -> bool {
    filters
        .iter()
        .all(|f| mesh.contains(f.as_str()) || builder.contains(f.as_str()))
}

fn bench_mesh(path: &Path, name: &str, filters: &[String]) -> anyhow::Result<(usize, Vec<Row>)> {
    let mesh = gridrt::input::load_mesh(path)?;
    let sub = gridrt::subdiv::subdivide(&mesh, 3, gridrt::subdiv::Scheme::Loop);
    let tris = sub.micro_triangles(3);
    let positions = &sub.positions;
    let boxes: Vec<Aabb> = tris
        .iter()
        .map(|t| Aabb::from_points(t.iter().map(|&v| positions[v as usize])))
        .collect();
    let params = gridrt::triangles::build_params();
    let mut rows = Vec::new();

    let all = rayon::current_num_threads();
    let mut one_thread: Option<Bvh> = None;
    for threads in if all > 1 { vec![1, all] } else { vec![1] } {
        if !wanted(filters, name, "gridrt bvh::build") {
            continue;
        }
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build()?;
        let (ms, bvh, same) = pool.install(|| time_builds(|| bvh::build(&boxes, &params)));
        let mut r = row("gridrt bvh::build", threads, &boxes, (ms, &bvh, same));
        match &one_thread {
            None => one_thread = Some(bvh),
            Some(t) if t.nodes == bvh.nodes && t.order == bvh.order => r.note += ", same tree as 1 thread",
            Some(_) => r.note += ", DIFFERENT tree than 1 thread",
        }
        rows.push(r);
    }

    let theirs: Vec<obvhs::aabb::Aabb> = boxes
        .iter()
        .map(|b| obvhs::aabb::Aabb::new(Vec3A::from(b.min), Vec3A::from(b.max)))
        .collect();
    let configs = [
        ("obvhs fast_build, leaf<=4, Ct=1", matched(BvhBuildParams::fast_build())),
        (
            "obvhs medium_build, leaf<=4, Ct=1",
            matched(BvhBuildParams::medium_build()),
        ),
        ("obvhs fast_build (preset)", BvhBuildParams::fast_build()),
        ("obvhs medium_build (preset)", BvhBuildParams::medium_build()),
    ];
    for (builder, config) in configs {
        if !wanted(filters, name, builder) {
            continue;
        }
        for threads in if all > 1 { vec![1, all] } else { vec![1] } {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build()?;
            let (ms, bvh, same) = pool.install(|| {
                time_builds(|| {
                    from_obvhs(obvhs::bvh2::builder::build_bvh2(
                        &theirs,
                        config,
                        &mut Default::default(),
                    ))
                })
            });
            rows.push(row(builder, threads, &boxes, (ms, &bvh, same)));
        }
    }
    Ok((tris.len(), rows))
}

fn main() {
    let dir = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/meshes"));
    // cargo passes `--bench`; other arguments filter meshes and builders by name (see `wanted`).
    let filters: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with("--")).collect();
    println!("median of {RUNS} builds; SAH: bvh::sah_cost (Ct = Ci = 1, relative to root area)");
    println!("ratios are against \"obvhs medium_build, leaf<=4, Ct=1\"\n");
    println!("| mesh | triangles | builder | threads | build ms | nodes | max leaf | depth | SAH cost | time ratio | SAH ratio | check |");
    println!("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---|");
    for name in MESHES {
        if filters
            .iter()
            .any(|f| MESHES.iter().any(|m| m.contains(f.as_str())) && !name.contains(f.as_str()))
        {
            continue;
        }
        let path = dir.join(name);
        if !path.exists() {
            eprintln!("skipping {name}: {} not found", path.display());
            continue;
        }
        let (count, rows) = match bench_mesh(&path, name, &filters) {
            Ok(r) => r,
            Err(e) => {
                eprintln!("skipping {name}: {e:#}");
                continue;
            }
        };
        let reference = rows.iter().find(|r| r.builder.starts_with("obvhs medium_build, leaf"));
        let ratio = |ours: f64, theirs: f64| reference.map_or("-".to_string(), |_| format!("{:.3}", ours / theirs));
        for r in &rows {
            println!(
                "| {name} | {count} | {} | {} | {:.1} | {} | {} | {} | {:.2} | {} | {} | {} |",
                r.builder,
                r.threads,
                r.ms,
                r.nodes,
                r.max_leaf,
                r.depth,
                r.sah,
                ratio(r.ms, reference.map_or(1.0, |t| t.ms)),
                ratio(r.sah as f64, reference.map_or(1.0, |t| t.sah as f64)),
                r.note
            );
        }
    }
}
