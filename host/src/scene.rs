//! A scene ready to trace, in either representation.

use gridrt_shared::glam::Vec3;
use gridrt_shared::layout::{Camera, FrameParams, GridParams, Hit};
use gridrt_shared::ray::{Ray, T_FAR};
use gridrt_shared::traverse::{trace, trace_triangles};
use gridrt_shared::triangle::{intersect_triangle, triangle_normal};

use crate::bvh::Aabb;
use crate::grid::format::{read_as_format, GridFormat};
use crate::grid::GridScene;
use crate::triangles::TriangleScene;

pub enum Scene {
    Triangles(TriangleScene),
    Grids(GridScene),
}

impl Scene {
    /// Closest hit, by the same `gridrt_shared` code the kernels run.
    pub fn trace(&self, ray: &Ray, t_max: f32) -> Hit {
        match self {
            Scene::Triangles(s) => trace_triangles(s.nodes.as_slice(), &s.view(), ray, t_max),
            Scene::Grids(s) => read_as_format!(s, s.params, |view| trace(s.top(), &view, ray, t_max)),
        }
    }

    /// The dispatch parameters for this scene under `camera`.
    pub fn frame(&self, camera: Camera, shading: u32) -> FrameParams {
        FrameParams {
            camera,
            grid: match self {
                Scene::Triangles(_) => GridParams::default(),
                Scene::Grids(s) => s.params,
            },
            shading,
            tile_width: camera.width,
            tile_height: camera.height,
            ..Default::default()
        }
    }

    /// Whether the scene is of grids of compressed values, which only kernels of their own
    /// decode on the GPU.
    pub fn has_compressed_values(&self) -> bool {
        matches!(self, Scene::Grids(g) if g.format() == GridFormat::Compressed)
    }

    /// Whether the scene is of grids in a format made for displaced grids (their values, tight
    /// headers, relative radii, a wide top level), which only kernels of their own read on the
    /// GPU: plain grids' kernels leave those formats out.
    pub fn uses_displaced_formats(&self) -> bool {
        matches!(self, Scene::Grids(g) if g.format() != GridFormat::Plain)
    }

    /// Whether the scene holds what displaced grids alone do (their values, a wide top level,
    /// leaf radius pairs), which the GPU reads from whole bindings only: split into chunks, a
    /// scene is read by plain grids' kernels, which leave those out. Tight headers and relative
    /// radii without leaf pairs they read.
    pub fn needs_whole_bindings(&self) -> bool {
        matches!(self, Scene::Grids(g) if g.params.displaced != 0 || g.has_wide_top() || g.params.leaf_pairs())
    }

    /// Bytes of everything the traversal reads.
    pub fn memory(&self) -> usize {
        let parts = match self {
            Scene::Triangles(s) => s.memory(),
            Scene::Grids(s) => s.memory(),
        };
        parts.iter().map(|(_, bytes)| bytes).sum()
    }

    /// The box around every micro-triangle: the root of the scene's BVH.
    pub fn bounds(&self) -> Aabb {
        match self {
            Scene::Triangles(s) => Aabb {
                min: s.nodes[0].min.into(),
                max: s.nodes[0].max.into(),
            },
            Scene::Grids(s) => s.bounds(),
        }
    }

    /// Maps a hit's primitive to the micro-triangle numbering of
    /// `Subdivided::micro_triangles` (or the input numbering for a plain triangle mesh).
    pub fn original_triangle(&self, prim: u32) -> u32 {
        match self {
            Scene::Triangles(s) => s.original[prim as usize],
            Scene::Grids(s) => s.micro_triangle_id(prim),
        }
    }

    /// Corners of a hit's triangle, by its primitive id (a grid hit at the scene's depth, or
    /// at its grid's own level where that is shallower, see [`gridrt_shared::layout::Hit`];
    /// not for automatic levels of detail, whose depths [`Self::hit_triangle`] takes from the
    /// hit).
    pub fn triangle(&self, prim: u32) -> [Vec3; 3] {
        match self {
            Scene::Triangles(s) => s.view().corners(prim),
            Scene::Grids(s) => {
                let view = s.view();
                let grid = prim / gridrt_shared::grid_index::triangle_count(s.params.lod);
                let depth = s.params.lod.min(view.own_level(&view.open(grid)));
                view.micro_triangle(prim, depth)
            }
        }
    }

    /// Corners of the triangle `hit` is on, at the depth it was rendered at (grids of mixed
    /// levels or automatic levels of detail render some grids shallower than the scene's).
    pub fn hit_triangle(&self, hit: &Hit) -> [Vec3; 3] {
        match self {
            Scene::Triangles(s) => s.view().corners(hit.prim),
            Scene::Grids(s) => s.view().micro_triangle(hit.prim, hit.level),
        }
    }

    /// Unnormalised geometric normal of a hit's triangle, by its primitive id.
    pub fn normal(&self, prim: u32) -> Vec3 {
        let [a, b, c] = self.triangle(prim);
        gridrt_shared::triangle::triangle_normal(a, b, c)
    }
}

/// How far apart two correct closest hits of `ray` may lie (as `t`), given the triangles
/// they are on: what two traversals of the same triangles (the grids and the baseline, or
/// either and a brute-force loop) can disagree by. The property tests and the fuzz targets
/// judge the traversals with it.
///
/// The triangle test is watertight and every box, sphere and footprint test conservative,
/// but of triangles within the triangle test's rounding of each other along the ray (slivers
/// at a grazing angle), a traversal may keep another than the one a brute-force loop keeps:
/// a triangle's computed `t` can fall before its box's or sphere's entry, and whatever is
/// entered beyond the closest hit so far is skipped. So the slack is the sum of both
/// triangles' [`hit_uncertainty`].
pub fn closest_hit_slack(ray: &Ray, triangles: [[Vec3; 3]; 2]) -> f32 {
    hit_uncertainty(ray, triangles[0]) + hit_uncertainty(ray, triangles[1])
}

/// Whether `ray` meets triangle `[a, b, c]` only through the triangle test's rounding: in
/// double precision its line passes outside the triangle. The watertight test shears the
/// vertices into the ray's frame after moving them to its origin, so its inside/outside
/// decision is as accurate as the largest of those coordinates allows: a sliver a thousandth
/// of its length thick, seen from close by, can be hit a few units in the last place of its
/// length outside it. Box and sphere tests are conservative for the exact triangle, not for
/// the rounded test, so one traversal may cull such a triangle that another, or a brute-force
/// loop, hits. Either is correct to the test's precision.
pub fn hits_only_by_rounding(ray: &Ray, [a, b, c]: [Vec3; 3]) -> bool {
    let (o, d) = (ray.origin.as_dvec3(), ray.dir.as_dvec3());
    let (a, b, c) = (a.as_dvec3() - o, b.as_dvec3() - o, c.as_dvec3() - o);
    // The signed volumes the test's edge functions compute in the sheared frame.
    let (u, v, w) = (d.dot(b.cross(c)), d.dot(c.cross(a)), d.dot(a.cross(b)));
    (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0)
}

/// How far the triangle test's `t` for this ray and triangle may be from the truth: its own
/// error here (against a double-precision reference) plus `1e-5 / |cos|`, `cos` between the
/// ray and the normal: a vertex off by 1e-5 (a hundred units in the last place of the
/// unit-sized local frame) moves a hit that far, without bound for a ray in the triangle's
/// plane. A hit no nearer the ray's origin than this is certain to be in front of it: one
/// closer may be found by one traversal and culled by another, whose box or sphere lies behind.
pub fn hit_uncertainty(ray: &Ray, [a, b, c]: [Vec3; 3]) -> f32 {
    let cos = triangle_normal(a, b, c).normalize_or_zero().dot(ray.dir).abs();
    let rounding = match (intersect_triangle(a, b, c, ray, T_FAR), reference_t(ray, [a, b, c])) {
        (Some((t, _, _)), Some(exact)) => (t as f64 - exact).abs() as f32,
        _ => 0.0,
    };
    rounding + 1e-5 / cos
}

/// The ray's distance to the plane of a triangle it crosses, in `f64` (Moller and Trumbore),
/// or `None`.
fn reference_t(ray: &Ray, [a, b, c]: [Vec3; 3]) -> Option<f64> {
    let (o, d) = (ray.origin.as_dvec3(), ray.dir.as_dvec3());
    let (e1, e2) = (b.as_dvec3() - a.as_dvec3(), c.as_dvec3() - a.as_dvec3());
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 {
        return None;
    }
    let s = o - a.as_dvec3();
    let q = s.cross(e1);
    Some(e2.dot(q) / det)
}
