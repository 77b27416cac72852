//! Finding the reference surface along a micro-vertex's line: rays both ways from a point,
//! through gridrt's own BVH and triangle test, keeping the hit nearest the point (the
//! surface the base approximates there rather than another sheet farther along).
//!
//! A point on the surface itself (every base corner is a reference vertex) must be found at
//! distance zero, which a ray starting there skips (hits count from `t > 0`): each ray starts
//! a little behind the point, so a surface just behind or at it is still met. Where neither
//! ray meets the surface within reach (a hole in a scan, a base that strays past the
//! reach), the point on the line nearest the reference's closest point stands in, and is
//! counted. So is a hit much farther along the line than the surface's closest point: the
//! line has passed by the sheet it was meant for, and met another.

use gridrt_shared::glam::Vec3;
use gridrt_shared::ray::Ray;
use gridrt_shared::traverse::trace_triangles;

use crate::mesh::Mesh;
use crate::surface_distance::NearestTriangles;
use crate::triangles::{self, TriangleScene};

/// How far behind its point each ray starts, as a fraction of the reach.
const BACK_OFF: f32 = 1e-3;

/// How many times farther than the surface's closest point a hit may lie along the line.
/// Lines meet a surface at an angle, so a hit on the right sheet can lie a few times farther
/// than the closest point; much farther, and it is on another sheet.
pub const FARTHER_SHEET: f32 = 5.0;

/// The reference surface, ready for line queries.
pub struct Reference {
    scene: TriangleScene,
    nearest: NearestTriangles,
}

/// Where a line met the surface: a multiple of its direction from its origin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Crossing {
    pub t: f32,
    /// False when no ray met the surface and the closest-point fallback gave `t`.
    pub hit: bool,
}

impl Reference {
    pub fn new(mesh: &Mesh) -> Reference {
        Reference {
            scene: triangles::build(&mesh.positions, &mesh.triangles),
            nearest: NearestTriangles::new(mesh),
        }
    }

    /// The crossing of the line `origin + t * direction` with the surface nearest `origin`,
    /// with `|t|` below `reach` (in multiples of `direction`), and no farther along the line
    /// than [`FARTHER_SHEET`] times the distance from `origin` to the surface: a hit that far
    /// is on another sheet (the far side of a thin part, a fold), and the closest point's
    /// projection serves better.
    pub fn crossing_near_surface(&self, origin: Vec3, direction: Vec3, reach: f32) -> Crossing {
        let o = origin.as_dvec3();
        let closest = self.nearest.closest_point(o).map_or(0.0, |q| q.distance(o)) as f32;
        let length = direction.length();
        let sheet = if length > 0.0 {
            FARTHER_SHEET * closest / length
        } else {
            reach
        };
        // A little slack, so a point on the surface still finds it.
        self.crossing(origin, direction, reach.min(sheet + BACK_OFF * reach))
    }

    /// The crossing of the line `origin + t * direction` with the surface nearest `origin`,
    /// with `|t|` below `reach` (in multiples of `direction`).
    pub fn crossing(&self, origin: Vec3, direction: Vec3, reach: f32) -> Crossing {
        let back = BACK_OFF * reach;
        let forward = self.first_hit(origin - direction * back, direction, reach + back);
        let backward = self.first_hit(origin + direction * back, -direction, reach + back);
        // Signed distances along `direction`; the one of least size wins.
        let along = [forward.map(|f| f - back), backward.map(|b| back - b)];
        let nearest = along.into_iter().flatten().min_by(|a, b| a.abs().total_cmp(&b.abs()));
        match nearest {
            Some(t) => Crossing { t, hit: true },
            None => Crossing {
                t: self.closest_on_line(origin, direction),
                hit: false,
            },
        }
    }

    fn first_hit(&self, origin: Vec3, direction: Vec3, t_max: f32) -> Option<f32> {
        let ray = Ray::new(origin, direction);
        let hit = trace_triangles(self.scene.nodes.as_slice(), &self.scene.view(), &ray, t_max);
        hit.is_hit().then_some(hit.t)
    }

    /// The `t` of the line's point nearest the surface's point closest to `origin`.
    fn closest_on_line(&self, origin: Vec3, direction: Vec3) -> f32 {
        let (o, d) = (origin.as_dvec3(), direction.as_dvec3());
        let length2 = d.length_squared();
        match self.nearest.closest_point(o) {
            Some(q) if length2 > 0.0 => ((q - o).dot(d) / length2) as f32,
            _ => 0.0,
        }
    }
}
