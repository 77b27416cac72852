//! Each command as one library call, as a program makes it: the same files and figures as the
//! command line's, and its refusals before any work.

use gridrt::backend::BackendChoice;
use gridrt::error::ErrorKind;
use gridrt::progress::{Progress, Silent};
use gridrt::request::bench::{bench_files, BenchRequest};
use gridrt::request::build::BuildRequest;
use gridrt::request::compare::compare_files;
use gridrt::request::export::{export_file, ExportRequest};
use gridrt::request::render::{render_files, Lod, RenderRequest};
use gridrt::request::stats::stats_file;
use gridrt::subdiv::Scheme;
use gridrt_tests::scratch;

/// What a call reported: its stages in order, and its lines.
#[derive(Default)]
struct Heard {
    stages: Vec<&'static str>,
    lines: Vec<String>,
}

impl Progress for Heard {
    fn stage(&mut self, name: &'static str, work: &mut dyn FnMut()) {
        self.stages.push(name);
        work()
    }

    fn say(&mut self, line: &str) {
        self.lines.push(line.to_string());
    }
}

#[test]
fn a_render_request_writes_every_frame_and_says_so() {
    let dir = scratch("request-render");
    let request = RenderRequest {
        backend: BackendChoice::Cpu,
        width: 48,
        height: 36,
        turntable: Some(2),
        ..RenderRequest::new(Vec::new(), dir.join("spin.png"))
    };
    let mut heard = Heard::default();
    let rendered = render_files(&request, &mut heard).unwrap();
    assert_eq!(rendered.outputs, [dir.join("spin_000.png"), dir.join("spin_001.png")]);
    assert!(rendered.outputs.iter().all(|p| p.is_file()));
    assert!(rendered.device.starts_with("CPU"), "{}", rendered.device);
    assert_eq!(&heard.stages[..4], ["load", "load", "device", "build"]);
    assert!(
        heard.lines[0].starts_with("default scene: 560 base triangles"),
        "{:?}",
        heard.lines
    );
    assert_eq!(
        heard.lines.iter().filter(|l| l.starts_with("rendered 48x36")).count(),
        2
    );

    // Refused before any work: nothing is written.
    let too_deep = RenderRequest {
        lod: Some(Lod::Depth(5)),
        ..request.clone()
    };
    let e = render_files(&too_deep, &mut Silent).unwrap_err();
    assert_eq!(e.kind(), ErrorKind::Options, "{e}");
    assert!(e.to_string().contains("--lod 5 is deeper than --levels 3"), "{e}");
}

#[test]
fn stats_compare_export_and_bench_are_one_call_each() {
    let dir = scratch("request-others");
    let build = BuildRequest {
        levels: 2,
        ..BuildRequest::default()
    };
    let stats = stats_file(None, &build, &mut Silent).unwrap();
    assert_eq!(
        (stats.levels, stats.base_triangles, stats.micro_triangles),
        (2, 560, 560 * 16)
    );
    assert!(stats.compression_gain > 1.0, "{stats:?}");

    let export = |scheme: Scheme, name: &str| {
        let request = ExportRequest {
            mesh: None,
            levels: Some(1),
            scheme,
            crease_angle: None,
            output: dir.join(name),
        };
        export_file(&request, &mut Silent).unwrap()
    };
    assert_eq!(export(Scheme::Flat, "flat.ply").micro_triangles, 560 * 4);
    assert_eq!(export(Scheme::Loop, "loop.ply").micro_triangles, 560 * 4);
    // Loop subdivision rounds the scene's edges; a surface lies on itself.
    let (flat, rounded) = (dir.join("flat.ply"), dir.join("loop.ply"));
    let apart = compare_files(&flat, &rounded, 2000, &mut Silent).unwrap();
    assert!(apart.symmetric.max > 1e-3, "{apart:?}");
    let same = compare_files(&flat, &flat, 2000, &mut Silent).unwrap();
    assert!(same.symmetric.max < 1e-9, "{same:?}");

    let request = BenchRequest {
        build,
        views: 1,
        width: 16,
        height: 12,
        warmup: 0,
        repeats: 1,
        build_repeats: 1,
        ..BenchRequest::new(vec![dir.join("flat.ply")])
    };
    let rows = bench_files(&request, &mut Silent).unwrap();
    assert_eq!(rows.len(), 1);
    assert_eq!(rows[0].stats.micro_triangles, 560 * 4 * 16);
    assert_eq!(rows[0].rays.primary, 16.0 * 12.0);
}
