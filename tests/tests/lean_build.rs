//! The lean grid build on real meshes: each grid subdivided on its own from its base
//! neighbourhood gives exactly the scene of subdividing the whole mesh first.

use gridrt::grid::{build, build_lean, lean_build_applies, GridBuild, GridOptions};
use gridrt::input::load_mesh_quiet;
use gridrt::subdiv::{subdivide, Scheme};
use gridrt_tests::meshes_dir_or_skip;

#[test]
fn the_lean_build_equals_the_whole_mesh_build_on_the_shared_meshes() {
    let Some(dir) = meshes_dir_or_skip("the_lean_build_equals_the_whole_mesh_build_on_the_shared_meshes") else {
        return;
    };
    for (file, levels) in [("bunny.obj", 3), ("teapot.obj", 4)] {
        let path = dir.join(file);
        let (mut mesh, _) = load_mesh_quiet(&path).unwrap();
        mesh.into_local_frame();
        assert!(lean_build_applies(&mesh), "{file}");
        let options = GridOptions::default();
        let mut sub = subdivide(&mesh, levels, Scheme::Loop);
        sub.quantize_inner();
        let whole = build(&mesh, &sub, &options).unwrap();
        let lean = build_lean(
            &mesh,
            &GridBuild {
                options,
                ..GridBuild::new(levels)
            },
        )
        .unwrap();
        assert!(lean == whole, "{file}: the lean build differs");
    }
}
