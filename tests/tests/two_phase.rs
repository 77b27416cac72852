//! The two-phase schedule's rounds, run natively: the resumable top-level walk and the queued
//! one-grid visits in two halves (spheres and footprints, then the leaf test over the window
//! the first half found), driven here the way the GPU drives them, find the one-pass walk's
//! hits bit for bit. Runs without a GPU, so the shared walk is checked on every machine.

use gridrt::grid::{GridOptions, TopFormat};
use gridrt::mesh::load_mesh;
use gridrt::mesh::scene::default_scene;
use gridrt::rays::{ao_rays, primary_rays, trace_cpu};
use gridrt::scene::Scene;
use gridrt::subdiv::Scheme;
use gridrt_shared::cost::Uncounted;
use gridrt_shared::glam::Vec3;
use gridrt_shared::grid_traverse::{OneVisitGrids, EMPTY_WINDOW};
use gridrt_shared::layout::{Hit, HitRecord, LeafEntry, RayRecord, WalkState, NO_HIT};
use gridrt_shared::ray::Ray;
use gridrt_shared::traverse::{BufferStack, LeafPrimitives, MAX_BVH_DEPTH};
use gridrt_tests::{build_pair, build_pair_with, meshes_dir_or_skip, Pair};

/// One ray through the rounds: each round walks to the next leaf, then every grid of that leaf
/// is visited on its own from the closest distance known when it was queued.
fn two_phase_hit(scene: &Scene, record: &RayRecord) -> (HitRecord, u32) {
    let Scene::Grids(grids) = scene else {
        panic!("the two-phase schedule traces grids");
    };
    assert!(grids.params.one_visit());
    let visits = OneVisitGrids(grids.view());
    let ray = Ray::new(Vec3::from(record.origin), Vec3::from(record.dir));
    let mut words = vec![0u32; 2 * MAX_BVH_DEPTH];
    let mut stack = BufferStack {
        words: &mut words,
        ray: 0,
        rays: 1,
    };
    let mut state = WalkState::default();
    let nodes = grids.top();
    let mut leaf = nodes.first_round::<true, _>(&ray, record.t_max, &mut state, &mut stack);
    let mut rounds = 0;
    loop {
        if leaf.count == 0 {
            let hit = HitRecord {
                t: state.t,
                prim: state.prim,
            };
            return (hit, rounds);
        }
        rounds += 1;
        // The queue entries of this round, each visited as GPU threads would: its spheres and
        // footprints first, then, for the visits that need one, its leaf test.
        let results = (leaf.first..leaf.first + leaf.count)
            .map(|grid| {
                let mut hit = Hit::miss(state.t);
                let mut scratch = visits.scratch(&ray);
                let window = visits.leaf_window(grid, &ray, state.t, &mut scratch, &mut Uncounted);
                if window != EMPTY_WINDOW {
                    let mut scratch = visits.scratch(&ray);
                    let packed = LeafEntry::new(0, window, 0);
                    visits.test_leaf_window(grid, packed.window(), &ray, &mut hit, &mut scratch, &mut Uncounted);
                }
                HitRecord {
                    t: hit.t,
                    prim: hit.prim,
                }
            })
            .collect::<Vec<HitRecord>>();
        state.first_entry = 0;
        state.entries = leaf.count;
        leaf = nodes.next_round::<true, _, _>(results.as_slice(), &ray, &mut state, &mut stack);
    }
}

fn check(name: &str, scene: &Scene, rays: &[RayRecord]) {
    let one_pass = trace_cpu(scene, rays);
    let mut rounds = 0u64;
    for (i, (record, expected)) in rays.iter().zip(&one_pass).enumerate() {
        let (hit, n) = two_phase_hit(scene, record);
        rounds += n as u64;
        assert!(
            hit.t.to_bits() == expected.t.to_bits() && hit.prim == expected.prim,
            "{name}: ray {i} hits {hit:?} in rounds, {expected:?} in one pass"
        );
    }
    let hits = one_pass.iter().filter(|h| h.prim != NO_HIT).count();
    eprintln!("{name}: {} rays, {hits} hits, {rounds} rounds", rays.len());
    assert!(rounds > 0, "{name}: no ray entered a leaf");
}

fn check_mesh(name: &str, mesh: &gridrt::mesh::Mesh) {
    check_pair(name, &build_pair(mesh, 3, 3, Scheme::Loop));
}

fn check_pair(name: &str, pair: &Pair) {
    let primary = primary_rays(&pair.bounds, 2, 64, 48);
    let first = trace_cpu(&pair.triangles, &primary);
    let ao = ao_rays(&primary, &first, 2, &pair.bounds, |p| pair.triangles.normal(p));
    check(&format!("{name} primary"), &pair.grids, &primary);
    check(&format!("{name} ao"), &pair.grids, &ao);
}

#[test]
fn rounds_find_the_one_pass_hits_on_the_default_scene() {
    check_mesh("default scene", &default_scene());
}

/// The rounds over a wide top level (the default of displaced grids), whose walk keeps leaf
/// entries on the stack beside nodes.
#[test]
fn rounds_find_the_one_pass_hits_under_a_wide_top_level() {
    let options = GridOptions {
        top: TopFormat::Wide,
        ..GridOptions::default()
    };
    let pair = build_pair_with(&default_scene(), 3, 3, Scheme::Loop, &options);
    let Scene::Grids(grids) = &pair.grids else {
        panic!("grids expected");
    };
    assert!(grids.has_wide_top(), "the default scene keeps a wide top level");
    check_pair("default scene, wide top level", &pair);
}

#[test]
fn rounds_find_the_one_pass_hits_on_the_teapot() {
    let Some(dir) = meshes_dir_or_skip("rounds_find_the_one_pass_hits_on_the_teapot") else {
        return;
    };
    check_mesh("teapot", &load_mesh(&dir.join("teapot.obj")).unwrap());
}
