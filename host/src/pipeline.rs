//! The render pipeline in four calls: open a mesh, build a [`Scene`] from it, frame a camera,
//! render an [`Image`] on a [`Backend`](crate::backend::Backend). The `gridrt` binary is a thin user of it.
//!
//! See the crate documentation for the whole chain, and `host/examples/embed.rs`.

use std::path::Path;

use crate::error::{fail, Result};
use gridrt_shared::glam::Vec3;
use gridrt_shared::layout::{
    Camera, FrameParams, MAX_AO_SAMPLES, SHADE_AMBIENT_OCCLUSION, SHADE_COST, SHADE_DEPTH, SHADE_EYE_LIGHT,
    SHADE_LEVEL, SHADE_LIT, SHADE_NORMAL, SHADE_PRIMITIVE,
};

use crate::grid::{self, GridBuild};
use crate::input::Input;
use crate::mesh::Mesh;
use crate::micromesh::DisplacedMesh;
use crate::rays::AO_RADIUS;
use crate::scene::Scene;
use crate::{image_io, subdiv, triangles};

/// Which structure holds the micro-triangles.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Representation {
    /// Grid primitives: a sphere hierarchy per base triangle, an SAH BVH over the grids.
    #[default]
    Grids,
    /// The baseline: every micro-triangle in an indexed list under an SAH BVH.
    Triangles,
}

impl std::str::FromStr for Representation {
    type Err = crate::error::Error;

    /// The names the CLI's `--mode` takes: grid, triangles.
    fn from_str(name: &str) -> Result<Representation> {
        Ok(match name {
            "grid" => Representation::Grids,
            "triangles" => Representation::Triangles,
            _ => fail!(Options, "no mode is called {name:?}: grid or triangles"),
        })
    }
}

/// What [`Scene::build`] makes of a base mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildOptions {
    pub representation: Representation,
    /// Subdivision depth, scheme and creases, and the grids' own options (the baseline uses
    /// all but the last).
    pub grid: GridBuild,
    /// Depth rendered, at most `grid.levels` (level of detail from the same grids);
    /// `None`: the full depth.
    pub lod: Option<u32>,
}

impl BuildOptions {
    /// Grids of depth `levels`, Loop subdivision, the default grid options.
    pub fn levels(levels: u32) -> Self {
        BuildOptions {
            representation: Representation::Grids,
            grid: GridBuild::new(levels),
            lod: None,
        }
    }

    /// For [`Scene::build_displaced`]: displaced grids at their defaults
    /// ([`crate::grid::GridOptions::for_displaced`]), the micro-mesh's own level.
    pub fn for_displaced() -> Self {
        let mut options = BuildOptions::default();
        options.grid.options = crate::grid::GridOptions::for_displaced();
        options
    }
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions::levels(3)
    }
}

impl Scene {
    /// Builds `mesh` (in its local frame, see [`crate::input::open`]) as `options` say. Grids
    /// are built one base triangle at a time; the baseline subdivides the whole mesh.
    pub fn build(mesh: &Mesh, options: &BuildOptions) -> Result<Scene> {
        Scene::build_reporting(mesh, options, &|_| {})
    }

    /// [`Scene::build`], calling `progress(grids)` as runs of grids are built (grids only).
    pub fn build_reporting(mesh: &Mesh, options: &BuildOptions, progress: &(dyn Fn(usize) + Sync)) -> Result<Scene> {
        let levels = options.grid.levels;
        let lod = rendered_depth(options, levels, "the")?;
        match options.representation {
            Representation::Grids => {
                // The build checks the mesh against the grid layout's limits first.
                let mut grids = grid::build_lean_reporting(mesh, &options.grid, progress)?;
                grids.set_lod(lod)?;
                Ok(Scene::Grids(grids))
            }
            Representation::Triangles => {
                let creases = options.grid.creases(mesh);
                let mut sub = subdiv::subdivide_creased(mesh, levels, options.grid.scheme, &creases);
                if options.grid.quantized {
                    sub.quantize_inner();
                }
                let list = sub.micro_triangles(lod);
                Ok(Scene::Triangles(triangles::build(&sub.positions, &list)))
            }
        }
    }
}

impl Scene {
    /// Builds a displaced micro-mesh (in its local frame) as `options` say: displaced grids,
    /// or the baseline over its decoded micro-triangles. The mesh's own levels are built (of
    /// mixed levels, each grid at its own within the deepest one's lattice), so
    /// `options.grid`'s levels and subdivision are not used; `options.lod` may render the
    /// grids shallower. [`BuildOptions::for_displaced`] gives the defaults the CLI uses.
    pub fn build_displaced(mesh: &DisplacedMesh, options: &BuildOptions) -> Result<Scene> {
        let Some(levels) = mesh.deepest_level() else {
            fail!(Input, "it has no base triangles");
        };
        let lod = rendered_depth(options, levels, "the micro-mesh's")?;
        match options.representation {
            Representation::Grids => {
                let mut grids = grid::displaced::build(mesh, &options.grid.options)?;
                grids.set_lod(lod)?;
                Ok(Scene::Grids(grids))
            }
            Representation::Triangles => {
                if lod != levels {
                    fail!(Options, "the baseline has one depth, the micro-mesh's own ({levels})");
                }
                let decoded = mesh.with_ranges_folded().decoded_welded();
                Ok(Scene::Triangles(triangles::build(
                    &decoded.positions,
                    &decoded.triangles,
                )))
            }
        }
    }
}

impl Scene {
    /// Builds what `input` holds as `options` say: a displaced micro-mesh as displaced grids
    /// ([`crate::grid::GridOptions::for_displaced`], at its own levels) or, for the baseline,
    /// its decoded micro-triangles; any other mesh subdivided as `options.grid` says.
    pub fn from_input(input: &Input, options: &BuildOptions) -> Result<Scene> {
        match input.displaced_grids() {
            Some(micromesh) => {
                let mut displaced = *options;
                displaced.grid.options = grid::GridOptions::for_displaced();
                Scene::build_displaced(micromesh, &displaced)
            }
            _ => Scene::build(&input.mesh, options),
        }
    }

    /// How many micro-triangles of each base triangle the scene [`Scene::from_input`] builds
    /// numbers in its hits: a hit's triangle `t` is micro-triangle `t % n` of base triangle
    /// `t / n`. A displaced micro-mesh built as triangles numbers its decoded triangles one
    /// by one (1).
    pub fn micro_triangles_per_base(input: &Input, options: &BuildOptions) -> u32 {
        // The same test as `from_input`: a micro-mesh with levels is built from them.
        let depth = match input.micromesh.as_ref().and_then(|m| m.deepest_level()) {
            Some(_) if options.representation == Representation::Triangles => 0,
            Some(deepest) => options.lod.unwrap_or(deepest),
            None => options.lod.unwrap_or(options.grid.levels),
        };
        1 << (2 * depth)
    }
}

/// The depth `options` render at: their level of detail, or all `levels` built (`whose`
/// names whose levels they are in the refusal of a deeper one).
fn rendered_depth(options: &BuildOptions, levels: u32, whose: &str) -> Result<u32> {
    let lod = options.lod.unwrap_or(levels);
    if lod > levels {
        fail!(
            Options,
            "level of detail {lod} is deeper than {whose} {levels} levels built"
        );
    }
    Ok(lod)
}

/// How pixels are coloured.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Shading {
    /// A headlight on a plain material.
    #[default]
    EyeLight,
    /// The geometric normal as colour.
    Normal,
    /// One colour per micro-triangle.
    Primitive,
    /// The plain material darkened by ambient occlusion (see [`RenderOptions::ao_samples`]).
    AmbientOcclusion,
    /// Clay under a key light and a sky, both dimmed by ambient occlusion (the same rays as
    /// [`Shading::AmbientOcclusion`]; see `gridrt_shared::shade::ao_pixel`).
    Lit,
    /// Distance from the eye: white at the scene's nearest point, black at its farthest.
    Depth,
    /// The cost heat map: the tests each pixel's ray makes (see [`crate::heat_map`] and
    /// [`RenderOptions::heat_white`]).
    Cost,
    /// Each grid coloured by the depth it is rendered at (see [`RenderOptions::lod_pixels`]);
    /// grids only.
    Level,
}

impl Shading {
    /// The mode number the shared shading code reads.
    pub fn code(self) -> u32 {
        match self {
            Shading::EyeLight => SHADE_EYE_LIGHT,
            Shading::Normal => SHADE_NORMAL,
            Shading::Primitive => SHADE_PRIMITIVE,
            Shading::AmbientOcclusion => SHADE_AMBIENT_OCCLUSION,
            Shading::Lit => SHADE_LIT,
            Shading::Depth => SHADE_DEPTH,
            Shading::Cost => SHADE_COST,
            Shading::Level => SHADE_LEVEL,
        }
    }
}

impl std::str::FromStr for Shading {
    type Err = crate::error::Error;

    /// The names the CLI's `--shading` takes: eye, normal, primitive, ao, lit, depth, cost,
    /// level.
    fn from_str(name: &str) -> Result<Shading> {
        Ok(match name {
            "eye" => Shading::EyeLight,
            "normal" => Shading::Normal,
            "primitive" => Shading::Primitive,
            "ao" => Shading::AmbientOcclusion,
            "lit" => Shading::Lit,
            "depth" => Shading::Depth,
            "cost" => Shading::Cost,
            "level" => Shading::Level,
            _ => fail!(
                Options,
                "no shading is called {name:?}: eye, normal, primitive, ao, lit, depth, cost or level"
            ),
        })
    }
}

/// How a frame is rendered (its size and view are the camera's).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    pub shading: Shading,
    /// Ambient-occlusion rays per pixel.
    pub ao_samples: u32,
    /// How far ambient-occlusion rays look, in the scene's coordinates; `None`: a tenth of
    /// the scene's bounding-box diagonal.
    pub ao_distance: Option<f32>,
    /// Tests per pixel the cost heat map shows white; `None`: the frame's 99th percentile.
    pub heat_white: Option<u32>,
    /// Level of detail per grid: with `Some(p)` each grid is rendered at the shallowest depth
    /// (up to the scene's) whose micro-triangles span at most `p` pixels on screen (see
    /// [`gridrt_shared::lod::grid_level`] and [`crate::lod::LodReport`]); `None`: every grid at
    /// the scene's depth. Grids only.
    pub lod_pixels: Option<f32>,
    /// Light grids with smooth normals, interpolated across micro-triangles from the lattice
    /// around each hit (see [`gridrt_shared::smooth_normal`]), instead of each micro-triangle's
    /// own. Grids only; plain ambient occlusion and depth do not use normals to colour.
    pub smooth_normals: bool,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            shading: Shading::EyeLight,
            ao_samples: 16,
            ao_distance: None,
            heat_white: None,
            lod_pixels: None,
            smooth_normals: false,
        }
    }
}

impl RenderOptions {
    /// Refuses options `scene` cannot be rendered with: those that need grids, on the baseline.
    pub fn check(&self, scene: &Scene) -> Result<()> {
        if let Scene::Triangles(_) = scene {
            if self.lod_pixels.is_some() {
                fail!(
                    Options,
                    "a level of detail per grid needs grids; the baseline has one depth, fixed when it is built"
                );
            }
            if self.shading == Shading::Level {
                fail!(
                    Options,
                    "level colouring shows each grid's depth; the baseline has one depth, fixed when it is built"
                );
            }
            if self.smooth_normals {
                fail!(Options, "smooth normals come from the grids' lattice; the baseline's triangle list has no neighbours to take them from");
            }
        }
        let occlusion = matches!(self.shading, Shading::AmbientOcclusion | Shading::Lit);
        if occlusion && !(1..=MAX_AO_SAMPLES).contains(&self.ao_samples) {
            fail!(
                Options,
                "{} ambient-occlusion rays per pixel: between 1 and {MAX_AO_SAMPLES}",
                self.ao_samples
            );
        }
        if let Some(pixels) = self.lod_pixels {
            if !(pixels.is_finite() && pixels > 0.0) {
                fail!(
                    Options,
                    "the target micro-triangle size must be a number of pixels above zero, not {pixels}"
                );
            }
        }
        Ok(())
    }

    /// The dispatch parameters of `scene` seen by `camera` with these options.
    pub fn frame(&self, scene: &Scene, camera: &Camera) -> FrameParams {
        let bounds = scene.bounds();
        let diagonal = (bounds.max - bounds.min).length();
        // The eye's distances to the box around the scene, and to its farthest corner.
        let eye = Vec3::from(camera.origin);
        let near = (eye - eye.clamp(bounds.min, bounds.max)).length();
        let far = bounds
            .corners()
            .iter()
            .map(|&c| (c - eye).length())
            .fold(near, f32::max);
        let mut frame = FrameParams {
            depth_near: near,
            depth_far: far,
            ao_samples: self.ao_samples,
            ao_distance: self.ao_distance.unwrap_or(diagonal * AO_RADIUS),
            // A hair off the surface, so the rays do not find the triangle they leave.
            ao_offset: diagonal * 1e-5,
            smooth_normals: self.smooth_normals as u32,
            ..scene.frame(*camera, self.shading.code())
        };
        if let (Some(pixels), Scene::Grids(_)) = (self.lod_pixels, scene) {
            frame.grid.lod_auto = 1;
            frame.grid.lod_eye = camera.origin;
            frame.grid.lod_scale = pixels_per_unit(camera) / pixels;
        }
        frame
    }
}

/// Pixels that one unit of length spans one unit in front of `camera`'s eye (the image plane
/// is one unit away, `vertical` its height).
pub fn pixels_per_unit(camera: &Camera) -> f32 {
    camera.height as f32 / Vec3::from(camera.vertical).length()
}

/// A rendered frame: packed RGBA8 (red in the low byte), row-major, top row first.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<u32>,
}

impl Image {
    /// Writes the image as PNG (through a temporary file, so a failure leaves no partial one).
    pub fn write_png(&self, path: &Path) -> Result<()> {
        image_io::write_png(path, &self.pixels, self.width, self.height)
    }
}
