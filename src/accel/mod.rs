//! `accel/` answers two questions about a set of world-space triangles: the closest hit along a ray
//! and whether anything blocks a segment. Behind that small interface sits a kd-tree; `render/`
//! never sees its layout. This module never sees a material, a light or a camera; its per-frame
//! update (`update.rs`) reads only the posed triangles and node matrices of a frame.
//!
//! Files: `aabb` (the box), `params` (build constants), `split` (the split rules every builder
//! shares), `build`, `binned` (the default, with `bins`, `plane_cost`, `small_split` for its
//! small nodes and `spare`, its pools of reference vectors), `sah` (the exact sweep) and
//! `bounded` (the refit-friendly topology) are the builders, and `flat` is what `binned` and
//! `bounded` write,
//! `tree` (the compact layout), `traverse` and `refit` (the two walks; `refit_packet` walks
//! refitted trees in packets, and `box_node` is the layout both refit walks read), `instances` (the
//! two-level top), `update` (the per-frame policy), `stats`, `triangle` (the watertight ray-
//! triangle test), `packet` (up to four or eight rays walking together) with `lanes` and
//! `lanes8` (its four- and eight-lane arithmetic), and `query` (the tree's `Intersect`). Only
//! what this file re-exports is visible outside.

mod aabb;
mod binned;
mod bins;
mod bounded;
mod box_node;
mod build;
mod flat;
mod instances;
mod lanes;
#[cfg(target_arch = "x86_64")]
mod lanes8;
mod packet;
mod params;
mod plane_cost;
mod query;
mod refit;
mod refit_packet;
mod sah;
mod small_split;
mod spare;
mod split;
mod stats;
mod traverse;
mod tree;
pub mod triangle;
mod triangle4;
mod update;

use glam::Vec3;

/// A small deterministic generator for the module's tests (no extra crate needed).
#[cfg(test)]
pub(crate) mod test_rng {
    use glam::Vec3;

    pub struct Lcg(pub u64);

    impl Lcg {
        pub fn next(&mut self) -> f32 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((self.0 >> 40) as f32) / (1u64 << 24) as f32
        }

        pub fn v(&mut self, s: f32) -> Vec3 {
            Vec3::new(self.next(), self.next(), self.next()) * s
        }
    }
}

pub use aabb::Aabb;
pub use instances::{Part, PartTree, PrimMap, TwoLevel};
pub(crate) use lanes::F4;
pub use packet::{LANES, WIDE_LANES};
pub use params::{BuildParams, SplitMethod};
pub use query::force_narrow_packets;
pub use refit::RefitTree;
pub use stats::TreeStats;
pub use traverse::{WalkCounts, prefetch};
pub use tree::{KdTree, MAX_DEPTH, Node, TreeArrays};
pub use update::{Action, LogRow, REBUILD_SAMPLES_PER_TRIANGLE, Reason, UpdateMode, Updater};

#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub origin: Vec3,
    /// Need not be unit length; hit distances are in units of its length.
    pub dir: Vec3,
}

impl Ray {
    pub fn new(origin: Vec3, dir: Vec3) -> Ray {
        Ray { origin, dir }
    }

    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }
}

/// A ray-triangle intersection: distance along the ray, the triangle, and barycentric weights of its
/// second and third vertex (the first weighs `1 - b1 - b2`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub prim: u32,
    pub b1: f32,
    pub b2: f32,
}

/// The query interface the renderer uses.
pub trait Intersect: Sync {
    /// Closest hit with `0 < t < t_max`.
    fn closest_hit(&self, ray: &Ray, t_max: f32) -> Option<Hit>;
    /// Whether any triangle is hit with `0 < t < t_max` (shadow rays).
    fn any_hit(&self, ray: &Ray, t_max: f32) -> bool;
    /// `hits[i] = closest_hit(&rays[i], t_max[i])`, bit for bit; a kd-tree walks coherent rays
    /// together.
    fn closest_hits(&self, rays: &[Ray], t_max: &[f32], hits: &mut [Option<Hit>]) {
        for ((r, &t), h) in rays.iter().zip(t_max).zip(hits) {
            *h = self.closest_hit(r, t);
        }
    }
    /// `occluded[i] = any_hit(&rays[i], t_max[i])`.
    fn any_hits(&self, rays: &[Ray], t_max: &[f32], occluded: &mut [bool]) {
        for ((r, &t), o) in rays.iter().zip(t_max).zip(occluded) {
            *o = self.any_hit(r, t);
        }
    }
}

/// The brute-force oracle: tests every triangle. Used by tests and as the slowest baseline.
pub struct BruteForce {
    pub triangles: Vec<[Vec3; 3]>,
}

impl Intersect for BruteForce {
    fn closest_hit(&self, ray: &Ray, t_max: f32) -> Option<Hit> {
        let pre = triangle::RayPre::new(ray);
        let mut best: Option<Hit> = None;
        let mut t_best = t_max;
        for (i, tri) in self.triangles.iter().enumerate() {
            if let Some((t, b1, b2)) = triangle::intersect(&pre, tri, t_best) {
                t_best = t;
                best = Some(Hit {
                    t,
                    prim: i as u32,
                    b1,
                    b2,
                });
            }
        }
        best
    }

    fn any_hit(&self, ray: &Ray, t_max: f32) -> bool {
        let pre = triangle::RayPre::new(ray);
        self.triangles
            .iter()
            .any(|tri| triangle::intersect(&pre, tri, t_max).is_some())
    }
}
