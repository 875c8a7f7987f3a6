//! Two-level acceleration: a handful of parts, each a kd-tree with a mapping from its own
//! triangle indices to the frame's global ones and, for rigid instances, the world-to-object
//! transform. Static geometry is one part built once; a rigidly moving object is an instance (its
//! object-space tree is built once and only its transform changes); a deforming object is a part
//! rebuilt when it moves. The top level is the list of parts with their world bounds: a frame has
//! few parts, so testing each box beats building a tree over them.
//!
//! Rays enter an instance through the inverse transform without renormalizing the direction, so
//! hit distances are the same in both spaces and hits from all parts compare directly.

use super::aabb::Aabb;
use super::refit::RefitTree;
use super::tree::KdTree;
use super::{Hit, Intersect, Ray};
use glam::Mat4;
use smallvec::{SmallVec, smallvec};
use std::sync::Arc;

/// How a part's triangle indices map to the frame's global triangle indices.
#[derive(Clone, Debug)]
pub enum PrimMap {
    /// Global index = local index + offset (one object's contiguous range).
    Offset(u32),
    /// Global index = table[local index].
    Table(Arc<Vec<u32>>),
}

impl PrimMap {
    #[inline]
    pub fn global(&self, local: u32) -> u32 {
        match self {
            PrimMap::Offset(o) => local + o,
            PrimMap::Table(t) => t[local as usize],
        }
    }
}

/// A part's tree: a kd-tree (static geometry, instances, rebuilt deforming meshes) or a bounded
/// kd-tree refitted to a deforming mesh. Kept as its kind, not as any `Intersect`, so that a
/// walker elsewhere (the GPU's) can tell what it uploads.
#[derive(Clone)]
pub enum PartTree {
    Kd(Arc<KdTree>),
    Refit(Arc<RefitTree>),
}

impl PartTree {
    fn accel(&self) -> &(dyn Intersect + Send + Sync) {
        match self {
            PartTree::Kd(t) => t.as_ref(),
            PartTree::Refit(t) => t.as_ref(),
        }
    }
}

#[derive(Clone)]
pub struct Part {
    pub tree: PartTree,
    pub map: PrimMap,
    /// World-to-object transform of an instance; `None`: the tree is in world space.
    pub world_to_object: Option<Mat4>,
    /// World-space bounds of the part at this frame.
    pub bounds: Aabb,
}

impl Part {
    /// A world-space tree.
    pub fn world(tree: Arc<KdTree>, map: PrimMap) -> Part {
        let bounds = tree.bounds;
        Part {
            tree: PartTree::Kd(tree),
            map,
            world_to_object: None,
            bounds,
        }
    }

    /// A world-space tree refitted to deformed triangles.
    pub fn refitted(tree: Arc<RefitTree>, map: PrimMap) -> Part {
        let bounds = tree.bounds();
        Part {
            tree: PartTree::Refit(tree),
            map,
            world_to_object: None,
            bounds,
        }
    }

    /// An instance of an object-space tree placed by `object_to_world`.
    pub fn instance(tree: Arc<KdTree>, map: PrimMap, object_to_world: Mat4) -> Part {
        let bounds = tree.bounds.transformed(&object_to_world);
        Part {
            tree: PartTree::Kd(tree),
            map,
            world_to_object: Some(object_to_world.inverse()),
            bounds,
        }
    }

    fn local_ray(&self, ray: &Ray) -> Ray {
        match &self.world_to_object {
            Some(m) => Ray::new(m.transform_point3(ray.origin), m.transform_vector3(ray.dir)),
            None => *ray,
        }
    }
}

/// The frame's acceleration structure: its parts.
#[derive(Clone, Default)]
pub struct TwoLevel {
    pub(super) parts: Vec<Part>,
}

impl TwoLevel {
    /// A structure of `parts`, tested in that order.
    pub fn new(parts: Vec<Part>) -> TwoLevel {
        TwoLevel { parts }
    }

    /// The parts, in the order rays test them.
    pub fn parts(&self) -> &[Part] {
        &self.parts
    }
}

impl Intersect for TwoLevel {
    fn closest_hit(&self, ray: &Ray, t_max: f32) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        for part in &self.parts {
            let limit = best.map_or(t_max, |h| h.t);
            // Instances are tested against their world box before the ray is transformed (the box
            // is conservative: it encloses the transformed object box); a world-space tree clips
            // the ray to the same box itself, so it is not tested twice.
            if part.world_to_object.is_some() && part.bounds.clip_ray(ray, limit).is_none() {
                continue;
            }
            if let Some(h) = part.tree.accel().closest_hit(&part.local_ray(ray), limit) {
                best = Some(Hit {
                    prim: part.map.global(h.prim),
                    ..h
                });
            }
        }
        best
    }

    fn any_hit(&self, ray: &Ray, t_max: f32) -> bool {
        self.parts.iter().any(|p| {
            (p.world_to_object.is_none() || p.bounds.clip_ray(ray, t_max).is_some())
                && p.tree.accel().any_hit(&p.local_ray(ray), t_max)
        })
    }

    /// Part by part as `closest_hit` does, each part taking the rays still in the running
    /// (with their best hit so far as the limit) as one batch.
    fn closest_hits(&self, rays: &[Ray], t_max: &[f32], hits: &mut [Option<Hit>]) {
        if let [part] = &self.parts[..]
            && part.world_to_object.is_none()
        {
            // One world-space part (a static scene) takes every ray as it comes.
            part.tree.accel().closest_hits(rays, t_max, hits);
            for h in hits.iter_mut().flatten() {
                h.prim = part.map.global(h.prim);
            }
            return;
        }
        hits.fill(None);
        let mut batch = Batch::default();
        for part in &self.parts {
            batch.clear();
            for (i, ray) in rays.iter().enumerate() {
                let limit = hits[i].map_or(t_max[i], |h| h.t);
                if part.world_to_object.is_none() || part.bounds.clip_ray(ray, limit).is_some() {
                    batch.push(i, part.local_ray(ray), limit);
                }
            }
            let mut found: SmallVec<[Option<Hit>; 8]> = smallvec![None; batch.len()];
            part.tree
                .accel()
                .closest_hits(&batch.rays, &batch.limits, &mut found);
            for (&i, h) in batch.lanes.iter().zip(found) {
                if let Some(h) = h {
                    hits[i] = Some(Hit {
                        prim: part.map.global(h.prim),
                        ..h
                    });
                }
            }
        }
    }

    fn any_hits(&self, rays: &[Ray], t_max: &[f32], occluded: &mut [bool]) {
        if let [part] = &self.parts[..]
            && part.world_to_object.is_none()
        {
            return part.tree.accel().any_hits(rays, t_max, occluded);
        }
        occluded.fill(false);
        let mut batch = Batch::default();
        for part in &self.parts {
            batch.clear();
            for (i, ray) in rays.iter().enumerate() {
                if !occluded[i]
                    && (part.world_to_object.is_none()
                        || part.bounds.clip_ray(ray, t_max[i]).is_some())
                {
                    batch.push(i, part.local_ray(ray), t_max[i]);
                }
            }
            let mut found: SmallVec<[bool; 8]> = smallvec![false; batch.len()];
            part.tree
                .accel()
                .any_hits(&batch.rays, &batch.limits, &mut found);
            for (&i, o) in batch.lanes.iter().zip(found) {
                occluded[i] |= o;
            }
        }
    }
}

/// The rays a part takes from a batch: their indices in the batch, in the part's space.
#[derive(Default)]
struct Batch {
    lanes: SmallVec<[usize; 8]>,
    rays: SmallVec<[Ray; 8]>,
    limits: SmallVec<[f32; 8]>,
}

impl Batch {
    fn clear(&mut self) {
        self.lanes.clear();
        self.rays.clear();
        self.limits.clear();
    }

    fn push(&mut self, lane: usize, ray: Ray, limit: f32) {
        self.lanes.push(lane);
        self.rays.push(ray);
        self.limits.push(limit);
    }

    fn len(&self) -> usize {
        self.lanes.len()
    }
}

#[cfg(test)]
mod tests {
    use super::super::{BruteForce, BuildParams};
    use super::*;
    use crate::accel::test_rng::Lcg;
    use glam::{Quat, Vec3};

    #[test]
    fn instances_and_world_parts_give_the_brute_force_hits() {
        let mut rng = Lcg(5);
        let soup = |rng: &mut Lcg, n: usize| -> Vec<[Vec3; 3]> {
            (0..n)
                .map(|_| {
                    let c = rng.v(4.0);
                    [c, c + rng.v(1.0) - 0.5, c + rng.v(1.0) - 0.5]
                })
                .collect()
        };
        let world_part = soup(&mut rng, 300);
        let object = soup(&mut rng, 200);
        let place = Mat4::from_scale_rotation_translation(
            Vec3::splat(1.5),
            Quat::from_rotation_y(0.7),
            Vec3::new(3.0, 1.0, -2.0),
        );
        let placed: Vec<[Vec3; 3]> = object
            .iter()
            .map(|t| t.map(|v| place.transform_point3(v)))
            .collect();
        let mut all = world_part.clone();
        all.extend(&placed);
        let accel = TwoLevel {
            parts: vec![
                Part::world(
                    Arc::new(KdTree::build(world_part, BuildParams::default())),
                    PrimMap::Offset(0),
                ),
                Part::instance(
                    Arc::new(KdTree::build(object, BuildParams::default())),
                    PrimMap::Offset(300),
                    place,
                ),
            ],
        };
        let brute = BruteForce { triangles: all };
        for _ in 0..3000 {
            let r = Ray::new(rng.v(12.0) - 4.0, rng.v(2.0) - 1.0);
            let (a, b) = (
                accel.closest_hit(&r, f32::INFINITY),
                brute.closest_hit(&r, f32::INFINITY),
            );
            match (a, b) {
                (Some(a), Some(b)) => {
                    assert!((a.t - b.t).abs() <= 1e-4 * b.t.max(1.0), "{a:?} vs {b:?}");
                    assert!(a.prim == b.prim || (a.t - b.t).abs() < 1e-4);
                }
                (None, None) => {}
                (a, b) => panic!("{a:?} vs {b:?} for {r:?}"),
            }
            assert_eq!(accel.any_hit(&r, f32::INFINITY), b.is_some());
        }
    }
}
