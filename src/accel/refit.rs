//! Refitting a kd-tree topology to deformed triangles. A classic kd-tree cannot be refitted: once
//! the triangles move, its split planes no longer separate them. Bounded kd-trees (B-KD trees,
//! Woop, Marmitt and Slusallek 2006) keep the topology and store, per inner node, bounds of each
//! child recomputed bottom-up in O(n). B-KD trees store two planes on the split axis; this keeps
//! each child's whole box, so a ray is clipped on all three axes at every node, as in a BVH: on
//! BrainStem that traced 1.15-1.3x faster than the two planes (`bench sweep`, 320x240, 1-16 spp:
//! 4.0-5.1 Mrays/s against 3.1-4.4). Children may overlap; traversal visits them nearer first. The compact 8-byte nodes of the static path are untouched:
//! the boxes live beside them.

use super::aabb::Aabb;
use super::packet::{Run, for_each_hit};
use super::params::BuildParams;
use super::traverse::{LeafWalk, NoTally, Visit, WalkRay, any_hit, closest_hit, walk_one};
use super::tree::{KdTree, MAX_DEPTH};
use super::{Hit, Intersect, Ray};
use glam::Vec3;
use std::sync::Arc;

/// A kd-tree topology refitted to the current triangles (same indexing as the topology's).
pub struct RefitTree {
    topology: Arc<KdTree>,
    triangles: Vec<[Vec3; 3]>,
    /// Per inner node: the boxes of its below and above subtrees' current triangles.
    boxes: Vec<[Aabb; 2]>,
    bounds: Aabb,
}

impl RefitTree {
    /// A bounded kd-tree over `triangles`, built for refitting: each triangle in one leaf
    /// (`bounded.rs`), its boxes fitted to the triangles as they are now.
    pub fn build(triangles: Vec<[Vec3; 3]>, params: BuildParams) -> RefitTree {
        let topology = Arc::new(super::bounded::build_topology(triangles.clone(), params));
        RefitTree::refit(topology, triangles)
    }

    /// The topology, for refitting it to a later pose.
    pub fn topology(&self) -> &Arc<KdTree> {
        &self.topology
    }

    /// Refits `topology` (built over an earlier pose of the same triangles) to `triangles`.
    pub fn refit(topology: Arc<KdTree>, triangles: Vec<[Vec3; 3]>) -> RefitTree {
        assert_eq!(
            topology.triangles.len(),
            triangles.len(),
            "refit keeps the topology: the triangle count must not change"
        );
        let mut boxes = vec![[Aabb::EMPTY; 2]; topology.nodes.len()];
        let bounds = if topology.nodes.is_empty() {
            Aabb::EMPTY
        } else {
            subtree_bounds(&topology, &triangles, &mut boxes, 0)
        };
        RefitTree {
            topology,
            triangles,
            boxes,
            bounds,
        }
    }

    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The triangles as they are now, in the topology's indexing.
    pub fn triangles(&self) -> &[[Vec3; 3]] {
        &self.triangles
    }

    /// Per node of the topology (unused at leaves): the boxes of its below and above subtrees,
    /// for a walker elsewhere (the GPU's) to upload.
    pub fn boxes(&self) -> &[[Aabb; 2]] {
        &self.boxes
    }

    /// SAH cost of the refitted tree with the topology's constants: each node weighted by the
    /// surface area of its box over the root's.
    pub fn sah_cost(&self) -> f64 {
        let p = &self.topology.params;
        let root = self.bounds.surface_area().max(f32::MIN_POSITIVE) as f64;
        let mut cost = 0.0;
        let mut stack = vec![(0usize, self.bounds)];
        while let Some((i, b)) = stack.pop() {
            if self.topology.nodes.is_empty() || b.is_empty() {
                continue;
            }
            let n = self.topology.nodes[i];
            let area = b.surface_area() as f64 / root;
            if n.is_leaf() {
                cost += area * p.intersection_cost as f64 * n.leaf_range().len() as f64;
            } else {
                cost += area * p.traversal_cost as f64;
                let [below, above] = self.boxes[i];
                stack.push((i + 1, below));
                stack.push((i + n.above_offset(), above));
            }
        }
        cost
    }

    /// Front-to-back walk over possibly overlapping child boxes, nearer child first; a child is
    /// skipped once the best hit is closer than where the ray enters it.
    fn walk_boxes(&self, ray: &WalkRay, t_max: f32, visit: &mut impl Visit) {
        let nodes = &self.topology.nodes;
        if nodes.is_empty() || self.bounds.is_empty() {
            return;
        }
        let Some((t0, _)) = ray.clip(&self.bounds, t_max) else {
            return;
        };
        // Both children can be pushed at every level: twice the depth bounds the stack.
        let mut stack = [(0u32, 0f32); 2 * MAX_DEPTH as usize + 4];
        stack[0] = (0, t0);
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let (i, near) = stack[sp];
            if near > visit.limit() {
                continue;
            }
            let n = nodes[i as usize];
            if n.is_leaf() {
                if visit.leaf(&self.topology.prim_refs[n.leaf_range()]) {
                    return;
                }
                continue;
            }
            visit.inner();
            let [below_box, above_box] = &self.boxes[i as usize];
            let limit = visit.limit();
            let below = ray.clip(below_box, limit).map(|(a, _)| (i + 1, a));
            let above = ray
                .clip(above_box, limit)
                .map(|(a, _)| (i + n.above_offset() as u32, a));
            // Push the farther child first so the nearer one is popped next (no allocation:
            // this runs at every inner node a ray visits).
            let (first, second) = match (below, above) {
                (Some(x), Some(y)) if y.1 < x.1 => (Some(x), Some(y)),
                (x, y) => (y, x),
            };
            for c in [first, second].into_iter().flatten() {
                stack[sp] = c;
                sp += 1;
            }
        }
    }
}

/// Bounds of a subtree's current triangles; records each inner node's child boxes on the way up.
fn subtree_bounds(t: &KdTree, tris: &[[Vec3; 3]], boxes: &mut [[Aabb; 2]], i: usize) -> Aabb {
    let n = t.nodes[i];
    if n.is_leaf() {
        return t.prim_refs[n.leaf_range()]
            .iter()
            .fold(Aabb::EMPTY, |b, &p| {
                b.union(&Aabb::of_points(&tris[p as usize]))
            });
    }
    let below = subtree_bounds(t, tris, boxes, i + 1);
    let above = subtree_bounds(t, tris, boxes, i + n.above_offset());
    boxes[i] = [below, above];
    below.union(&above)
}

impl LeafWalk for RefitTree {
    fn triangles(&self) -> &[[Vec3; 3]] {
        &self.triangles
    }

    fn walk(&self, ray: &WalkRay, t_max: f32, visit: &mut impl Visit) {
        self.walk_boxes(ray, t_max, visit)
    }
}

impl RefitTree {
    /// The topology's nodes and leaf references, for the packet walk (`refit_packet.rs`).
    pub(super) fn topology_arrays(&self) -> (&[super::Node], &[u32]) {
        (&self.topology.nodes, &self.topology.prim_refs)
    }

    /// Walks `rays` in packets where consecutive rays share an octant, singly elsewhere;
    /// `out(i, hit)`.
    fn batch<const ANY: bool>(
        &self,
        rays: &[Ray],
        t_max: &[f32],
        out: impl FnMut(usize, Option<Hit>),
    ) {
        assert_eq!(rays.len(), t_max.len(), "one limit per ray");
        let walk = |run| match run {
            Run::Single(i) => {
                let hit = walk_one::<ANY>(self, &rays[i], t_max[i], &mut NoTally);
                [hit, None, None, None]
            }
            Run::Packet(a, b, oct) => self.packet_walk_boxes::<ANY>(&rays[a..b], &t_max[a..b], oct),
        };
        for_each_hit(rays, walk, out);
    }
}

impl Intersect for RefitTree {
    fn closest_hit(&self, ray: &Ray, t_max: f32) -> Option<Hit> {
        closest_hit(self, ray, t_max, &mut NoTally)
    }

    fn any_hit(&self, ray: &Ray, t_max: f32) -> bool {
        any_hit(self, ray, t_max, &mut NoTally)
    }

    fn closest_hits(&self, rays: &[Ray], t_max: &[f32], hits: &mut [Option<Hit>]) {
        self.batch::<false>(rays, t_max, |i, h| hits[i] = h);
    }

    fn any_hits(&self, rays: &[Ray], t_max: &[f32], occluded: &mut [bool]) {
        self.batch::<true>(rays, t_max, |i, h| occluded[i] = h.is_some());
    }
}

#[cfg(test)]
mod tests {
    use super::super::{BruteForce, BuildParams};
    use super::*;
    use crate::accel::test_rng::Lcg;

    /// Packets of coherent rays (a pinhole's fan, with rays of mixed octants and ray limits)
    /// find the single walk's hits and occlusion on a refitted, deformed tree.
    #[test]
    fn packets_find_the_single_walk_hits() {
        let mut rng = Lcg(17);
        let rest: Vec<[Vec3; 3]> = (0..3000)
            .map(|_| {
                let c = rng.v(10.0);
                [c, c + rng.v(1.0) - 0.5, c + rng.v(1.0) - 0.5]
            })
            .collect();
        let topology = Arc::new(KdTree::build(rest.clone(), BuildParams::default()));
        let moved: Vec<[Vec3; 3]> = rest
            .iter()
            .map(|t| t.map(|v| v + Vec3::new((v.y * 0.7).sin(), 0.0, (v.x * 0.5).cos())))
            .collect();
        let refit = RefitTree::refit(topology, moved);
        let eye = Vec3::new(5.0, 5.0, -8.0);
        let mut rays = Vec::new();
        for y in 0..48 {
            for x in 0..48 {
                let d = Vec3::new(x as f32 / 48.0 - 0.5, y as f32 / 48.0 - 0.5, 1.0);
                rays.push(Ray::new(eye, d));
            }
        }
        for _ in 0..500 {
            rays.push(Ray::new(rng.v(12.0) - 1.0, rng.v(2.0) - 1.0));
        }
        let t_max: Vec<f32> = (0..rays.len())
            .map(|i| if i % 5 == 0 { 9.0 } else { f32::INFINITY })
            .collect();
        let mut hits = vec![None; rays.len()];
        let mut occluded = vec![false; rays.len()];
        refit.closest_hits(&rays, &t_max, &mut hits);
        refit.any_hits(&rays, &t_max, &mut occluded);
        let mut found = 0;
        for (i, r) in rays.iter().enumerate() {
            let single = refit.closest_hit(r, t_max[i]);
            let bits = |h: Option<Hit>| h.map(|h| (h.t.to_bits(), h.prim, h.b1.to_bits()));
            assert_eq!(bits(hits[i]), bits(single), "ray {i}");
            assert_eq!(occluded[i], refit.any_hit(r, t_max[i]), "ray {i}");
            found += single.is_some() as usize;
        }
        assert!(
            found > rays.len() / 4,
            "the rays must hit something: {found}"
        );
    }

    #[test]
    fn refitted_tree_finds_the_brute_force_hits_after_large_deformations() {
        let mut rng = Lcg(9);
        let rest: Vec<[Vec3; 3]> = (0..1500)
            .map(|_| {
                let c = rng.v(10.0);
                [c, c + rng.v(1.0) - 0.5, c + rng.v(1.0) - 0.5]
            })
            .collect();
        let topology = Arc::new(KdTree::build(rest.clone(), BuildParams::default()));
        for step in 1..5 {
            // A swirl that moves triangles across many of the original split planes.
            let a = step as f32 * 0.4;
            let moved: Vec<[Vec3; 3]> = rest
                .iter()
                .map(|t| {
                    t.map(|v| {
                        Vec3::new(
                            v.x * a.cos() - v.z * a.sin(),
                            v.y + (v.x * 0.5).sin() * step as f32,
                            v.x * a.sin() + v.z * a.cos(),
                        )
                    })
                })
                .collect();
            let refit = RefitTree::refit(topology.clone(), moved.clone());
            let brute = BruteForce { triangles: moved };
            for _ in 0..1500 {
                let r = Ray::new(rng.v(30.0) - 15.0, rng.v(2.0) - 1.0);
                assert_eq!(
                    refit.closest_hit(&r, f32::INFINITY).map(|h| h.t),
                    brute.closest_hit(&r, f32::INFINITY).map(|h| h.t)
                );
                assert_eq!(
                    refit.any_hit(&r, f32::INFINITY),
                    brute.any_hit(&r, f32::INFINITY)
                );
            }
            assert!(refit.sah_cost() > 0.0);
        }
        // Planes bound whole triangles, not the clipped pieces of a perfect-split build, so the
        // cost at the build pose differs from the fresh tree's; it is the baseline drift is
        // measured against, and it must be a finite, positive number.
        let base = RefitTree::refit(topology.clone(), rest).sah_cost();
        assert!(base.is_finite() && base > 0.0);
    }
}
