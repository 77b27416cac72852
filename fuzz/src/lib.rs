//! What the fuzz targets check, as plain functions: the targets are one-line wrappers, and the
//! same checks can run over the committed corpus without libFuzzer.

use gridrt::error::{Error, ErrorKind, Result};
use gridrt::grid::{self, GridOptions, RadiusFormat, TopFormat};
use gridrt::mesh::{Mesh, WorldMesh};
use gridrt::scene::{closest_hit_slack, hit_uncertainty, hits_only_by_rounding, Scene};
use gridrt::subdiv::{subdivide_creased, Scheme};
use gridrt::triangles;
use gridrt_shared::glam::Vec3;
use gridrt_shared::ray::{Ray, T_FAR};

pub mod gltf_mutation;

/// Every error gridrt prints is one line, and a loader's is about the input.
fn assert_one_line(e: &Error) {
    assert_eq!(e.kind(), ErrorKind::Input, "{e}");
    let text = e.to_string();
    assert!(
        !text.contains('\n') && !text.contains('\r'),
        "error on several lines: {text:?}"
    );
}

/// A loader's result: an error on one line, or a mesh that validation accepts or refuses on
/// one line.
pub fn check_loaded(result: Result<WorldMesh>) {
    match result {
        Err(e) => assert_one_line(&e),
        Ok(mesh) => match mesh.validate("fuzz") {
            Err(e) => assert_one_line(&e),
            Ok((mesh, _)) => {
                let n = mesh.positions.len();
                assert!(mesh.positions.iter().all(|p| p.is_finite()));
                assert!(mesh.triangles.iter().flatten().all(|&i| (i as usize) < n));
                let (local, _) = mesh.into_local();
                assert!(local.positions.iter().all(|p| p.is_finite()));
            }
        },
    }
}

/// A glTF or GLB file's bytes through the glTF loader, external buffers looked for in an
/// empty folder of their own: the same checks as [`check_loaded`].
pub fn check_gltf(data: &[u8]) {
    static FOLDER: std::sync::OnceLock<std::path::PathBuf> = std::sync::OnceLock::new();
    let folder = FOLDER.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("gridrt-fuzz-gltf-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("a scratch folder");
        dir
    });
    check_loaded(gridrt::mesh::gltf::parse_gltf(data, Some(folder)));
    // The same bytes as a displaced micro-mesh: refused on one line, or decoded to finite
    // micro-vertices whenever its counts and levels check out.
    match gridrt::micromesh::gltf_micromap::parse_displaced(data, Some(folder)) {
        Err(e) => assert_one_line(&e),
        Ok(None) => {}
        Ok(Some(displaced)) => {
            let (mesh, _) = displaced.into_local();
            if mesh.check().is_ok() {
                let decoded = mesh.decoded();
                let n = decoded.positions.len();
                assert!(decoded.triangles.iter().flatten().all(|&i| (i as usize) < n));
                // Compressed values lay out as grids without loss.
                if mesh.uniform_level().is_some() && decoded.triangles.len() <= 1 << 14 {
                    let options = gridrt::grid::compressed::ValueCompression::bounded(1e-2);
                    let compressed = gridrt::grid::compressed::compress(&mesh, &options).expect("compressed");
                    let grid_options = gridrt::grid::GridOptions::for_displaced();
                    if let Err(e) = gridrt::grid::displaced::layout(&compressed.mesh, &grid_options) {
                        assert!(!e.to_string().contains("compressed code"), "{e}");
                    }
                }
            }
        }
    }
}

/// A `.bary` file's bytes through the reader: an error on one line, or a micromap whose
/// triangles each hold their level's values, no more values than the file's bytes could hold,
/// and which writes back to a file that reads as the same micromap.
pub fn check_bary(data: &[u8]) {
    use gridrt::micromesh::bary;
    match bary::read(data) {
        Err(e) => assert_one_line(&e),
        Ok(map) => {
            for t in 0..map.triangles.len() {
                assert!(map.triangle_values(t).iter().all(|&v| v <= bary::UNORM11_MAX));
            }
            assert!(map.values.len() <= 8 * data.len() / 11 + 3 * map.triangles.len());
            assert_eq!(bary::read(&bary::write(&map)).expect("a written file reads"), map);
            check_written_set(&map);
        }
    }
}

/// A micromap written as a micro-mesh's files (glTF, buffer, `.bary`) over an earlier set of
/// another micromap in the same place: the glTF reads back with this micromap, and the folder
/// holds this set alone, whole.
fn check_written_set(map: &gridrt::micromesh::bary::Micromap) {
    use gridrt::mesh::frame::LocalFrame;
    use gridrt::micromesh::DisplacedMesh;
    // A primitive reads one group: a micromap of one group of all its triangles reads back
    // whole.
    let count = map.triangles.len() as u32;
    let whole = |g: &gridrt::micromesh::bary::MicromapGroup| g.triangle_first == 0 && g.triangle_count == count;
    if count == 0 || map.groups.len() != 1 || !whole(&map.groups[0]) {
        return;
    }
    // One triangle of its own for each of the micromap's, side by side.
    let corner = |t: u32, k: u32| Vec3::new((t + (k == 1) as u32) as f32, (k == 2) as u32 as f32, 0.0);
    let mesh = |micromap: gridrt::micromesh::bary::Micromap| DisplacedMesh {
        positions: (0..count).flat_map(|t| (0..3).map(move |k| corner(t, k))).collect(),
        directions: vec![Vec3::Z; 3 * count as usize],
        triangles: (0..count).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect(),
        micromap,
        decimated_edges: Vec::new(),
    };
    let folder = std::env::temp_dir().join(format!("gridrt-fuzz-set-{}", std::process::id()));
    std::fs::create_dir_all(&folder).expect("a scratch folder");
    let gltf = folder.join("set.gltf");
    let mut earlier = map.clone();
    earlier.values.iter_mut().for_each(|v| *v ^= 1);
    gridrt::micromesh::gltf::write(&gltf, &mesh(earlier), &LocalFrame::IDENTITY).expect("the earlier set is written");
    let written =
        gridrt::micromesh::gltf::write(&gltf, &mesh(map.clone()), &LocalFrame::IDENTITY).expect("the set is written");
    let mut names: Vec<_> = (std::fs::read_dir(&folder).expect("the folder lists"))
        .map(|e| e.expect("an entry").path())
        .collect();
    names.sort();
    let mut expected = written.clone();
    expected.sort();
    assert_eq!(names, expected, "the folder holds the new set alone");
    let bytes = std::fs::read(&gltf).expect("the glTF reads");
    let read = gridrt::micromesh::gltf_micromap::parse_displaced(&bytes, Some(&folder))
        .expect("the written set reads")
        .expect("it is displaced");
    let levels = |m: &gridrt::micromesh::bary::Micromap| m.triangles.iter().map(|t| t.level).collect::<Vec<_>>();
    assert_eq!(levels(&read.micromap), levels(map));
    for t in 0..map.triangles.len() {
        assert_eq!(read.micromap.triangle_values(t), map.triangle_values(t), "triangle {t}");
    }
}

/// Reads bytes front to back; zeros once they run out.
struct Bytes<'a>(&'a [u8]);

impl Bytes<'_> {
    fn u8(&mut self) -> u8 {
        match self.0.split_first() {
            Some((&b, rest)) => {
                self.0 = rest;
                b
            }
            None => 0,
        }
    }

    fn i16(&mut self) -> i16 {
        i16::from_le_bytes([self.u8(), self.u8()])
    }

    /// A coordinate: 16 bits at a scale from 2^-20 to 2^19, so one mesh mixes huge, tiny,
    /// sliver and degenerate triangles.
    fn coordinate(&mut self, exponent: u8) -> f32 {
        self.i16() as f32 * ((exponent % 40) as f32 - 20.0).exp2()
    }
}

/// What a run builds, decoded from the input's first bytes.
struct Plan {
    levels: u32,
    lod: u32,
    scheme: Scheme,
    /// Creases chosen beyond this dihedral angle, in degrees.
    crease_angle: Option<f32>,
    quantized: bool,
    options: GridOptions,
}

impl Plan {
    fn grid_build(&self) -> grid::GridBuild {
        grid::GridBuild {
            levels: self.levels,
            scheme: self.scheme,
            crease_angle: self.crease_angle,
            options: self.options,
            quantized: self.quantized,
        }
    }
}

fn decode(data: &[u8]) -> (Plan, Mesh, Bytes<'_>) {
    let mut b = Bytes(data);
    let flags = b.u8();
    let levels = (flags & 3) as u32;
    // The second byte: the depth rendered (low three bits), a binary compact or wide top level
    // (the fourth, with the fifth saying which), the crease angle (high half, 0: none).
    let detail = b.u8();
    let plan = Plan {
        levels,
        lod: (detail & 7) as u32 % (levels + 1),
        scheme: if flags & 4 != 0 { Scheme::Flat } else { Scheme::Loop },
        crease_angle: (detail >> 4 != 0).then_some((detail >> 4) as f32 * 12.0 - 6.0),
        quantized: flags & 8 != 0,
        options: GridOptions {
            radii: if flags & 16 != 0 {
                RadiusFormat::Relative
            } else {
                RadiusFormat::Half
            },
            leaf_footprint: flags & 32 == 0,
            excluded_levels: 1 + (flags >> 6) as u32 % 3,
            top: match (detail & 8 != 0, detail & 16 != 0) {
                (false, _) => TopFormat::Full,
                (true, false) => TopFormat::Compact,
                (true, true) => TopFormat::Wide,
            },
            // Displaced grids' storage: relative radii and tight headers together.
            tight_headers: flags & 16 != 0,
            own_rooms: true,
        },
    };
    let vertices = 3 + b.u8() as usize % 13;
    let positions = (0..vertices)
        .map(|_| {
            let e = b.u8();
            Vec3::new(b.coordinate(e), b.coordinate(e), b.coordinate(e))
        })
        .collect();
    let count = 1 + b.u8() as usize % 24;
    let triangles = (0..count)
        .map(|_| [b.u8(), b.u8(), b.u8()].map(|i| i as u32 % vertices as u32))
        .collect();
    (plan, Mesh { positions, triangles }, b)
}

/// Decodes a mesh and options, builds both representations as a render does and traces rays
/// through both: no panic, errors on one line, the lean grid build equal to the whole-mesh
/// one, and the same closest hits.
pub fn run_pipeline(data: &[u8]) {
    let (plan, mesh, mut rest) = decode(data);
    let mut mesh = match mesh.validate("fuzz") {
        Ok((mesh, _)) => mesh,
        Err(e) => return assert_one_line(&e),
    };
    mesh.into_local_frame();
    let creases = plan.grid_build().creases(&mesh);
    let mut sub = subdivide_creased(&mesh, plan.levels, plan.scheme, &creases);
    assert!(
        sub.positions.iter().all(|p| p.is_finite()),
        "subdivision made a non-finite vertex"
    );
    if plan.quantized {
        sub.quantize_inner();
    }
    let mut grids = match grid::build(&mesh, &sub, &plan.options) {
        Ok(g) => g,
        Err(e) => return assert_one_line(&e),
    };
    // The lean build, as `render` runs it, gives the same scene bit for bit.
    let lean =
        grid::build_lean(&mesh, &plan.grid_build()).expect("the lean build refuses what the whole-mesh build takes");
    assert!(lean == grids, "the lean build differs from the whole-mesh build");
    grids.set_lod(plan.lod).expect("lod within levels");
    let grids = Scene::Grids(grids);
    let tris = Scene::Triangles(triangles::build(&sub.positions, &sub.micro_triangles(plan.lod)));
    // Rays from points around the unit-sized local frame towards points inside it.
    for _ in 0..32 {
        let point =
            |b: &mut Bytes, reach: f32| Vec3::new(b.i16() as f32, b.i16() as f32, b.i16() as f32) * (reach / 32768.0);
        let origin = point(&mut rest, 3.0);
        let dir = point(&mut rest, 1.0) - origin;
        if dir.length_squared() == 0.0 {
            continue;
        }
        let ray = Ray::new(origin, dir.normalize());
        let (g, t) = (grids.trace(&ray, T_FAR), tris.trace(&ray, T_FAR));
        if g.is_hit() != t.is_hit() {
            // Only a hit within rounding of the ray's origin, or one the triangle test finds only
            // by its rounding, may be found by one alone.
            let (scene, hit) = if g.is_hit() { (&grids, g) } else { (&tris, t) };
            let triangle = scene.triangle(hit.prim);
            let near = hit.t <= hit_uncertainty(&ray, triangle);
            assert!(
                near || hits_only_by_rounding(&ray, triangle),
                "grid hit {g:?}, baseline hit {t:?} for {ray:?}"
            );
        } else if g.is_hit() {
            let slack = closest_hit_slack(&ray, [grids.triangle(g.prim), tris.triangle(t.prim)]);
            let close = (g.t - t.t).abs() <= 1e-5 * g.t.abs().max(t.t.abs()) + slack;
            assert!(
                close,
                "grid t {} but baseline t {} (allowed {slack}) for {ray:?}",
                g.t, t.t
            );
        }
    }
}
