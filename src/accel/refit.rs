//! Refitting a kd-tree topology to deformed triangles. A classic kd-tree cannot be refitted: once
//! the triangles move, its split planes no longer separate them. Bounded kd-trees (B-KD trees,
//! Woop, Marmitt and Slusallek 2006) keep the topology and store, per inner node, bounds of each
//! child recomputed bottom-up in O(n). B-KD trees store two planes on the split axis; this keeps
//! each child's whole box, so a ray is clipped on all three axes at every node, as in a BVH: on
//! BrainStem that traced 1.15-1.3x faster than the two planes (`bench sweep`, 320x240, 1-16 spp:
//! 4.0-5.1 Mrays/s against 3.1-4.4). Children may overlap; traversal visits them nearer first.
//!
//! The walks read their own layout, rewritten at every refit (`box_node.rs`): one 64-byte node
//! per inner node with both children's boxes, and the triangles copied into leaf order. Against
//! the topology's nodes with a box array beside them and the triangles in mesh order, BrainStem's
//! refitted frames traced 5-7% faster at 16 spp (0.160-0.168 s -> 0.151-0.155, three alternating
//! runs, 2 threads), for the same refit time.

use super::aabb::Aabb;
use super::box_node::{self, BoxNode, Child};
use super::lanes::{F4, Lanes};
#[cfg(target_arch = "x86_64")]
use super::lanes8::F8;
use super::packet::{LANES, Run, WIDE_LANES, group};
use super::params::BuildParams;
use super::traverse::{LeafWalk, NoTally, Visit, WalkRay, any_hit, closest_hit, walk_one};
use super::tree::{KdTree, MAX_DEPTH};
use super::{Hit, Intersect, Ray};
use glam::Vec3;
use std::sync::Arc;

/// A kd-tree topology refitted to the current triangles (same indexing as the topology's).
pub struct RefitTree {
    topology: Arc<KdTree>,
    mesh_order: Vec<[Vec3; 3]>,
    /// The inner nodes with their children's current boxes, as the walks read them.
    nodes: Vec<BoxNode>,
    /// The triangles in leaf-reference order (`box_node::Fitted`), and the walks' references
    /// into them: slot `j` holds the triangle of the topology's reference `j`.
    leaf_order: Vec<[Vec3; 3]>,
    slots: Vec<u32>,
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
        let fitted = box_node::fit(&topology, &triangles);
        RefitTree {
            slots: (0..topology.prim_refs.len() as u32).collect(),
            topology,
            mesh_order: triangles,
            nodes: fitted.nodes,
            leaf_order: fitted.leaf_triangles,
            bounds: fitted.bounds,
        }
    }

    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The triangles as they are now, in the topology's indexing.
    pub fn triangles(&self) -> &[[Vec3; 3]] {
        &self.mesh_order
    }

    /// Per node of the topology (unused at leaves): the boxes of its below and above subtrees,
    /// for a walker elsewhere (the GPU's) to upload.
    pub fn boxes(&self) -> Vec<[Aabb; 2]> {
        box_node::boxes_by_topology(&self.topology, &self.nodes)
    }

    /// Where a walk starts: the root node, or the one leaf of a topology that has no inner node.
    pub(super) fn root(&self) -> Child {
        match self.topology.nodes.first() {
            Some(n) if n.is_leaf() => {
                let r = n.leaf_range();
                Child::Leaf(r.start as u32, r.len() as u32)
            }
            _ => Child::Inner(0),
        }
    }

    /// SAH cost of the refitted tree with the topology's constants: each node weighted by the
    /// surface area of its box over the root's.
    pub fn sah_cost(&self) -> f64 {
        let p = &self.topology.params;
        // An empty box has no area (`Aabb::surface_area`).
        let area = |b: &Aabb| b.surface_area() as f64;
        let weigh = |child: Child, b: &Aabb| match child {
            Child::Inner(_) => area(b) * p.traversal_cost as f64,
            Child::Leaf(_, count) => area(b) * p.intersection_cost as f64 * count as f64,
        };
        let root = area(&self.bounds).max(f32::MIN_POSITIVE as f64);
        let mut cost = weigh(self.root(), &self.bounds);
        for n in &self.nodes {
            cost += weigh(n.child(0), &n.boxes[0]) + weigh(n.child(1), &n.boxes[1]);
        }
        cost / root
    }

    /// Front-to-back walk over possibly overlapping child boxes, nearer child first; a child is
    /// skipped once the best hit is closer than where the ray enters it.
    fn walk_boxes(&self, ray: &WalkRay, t_max: f32, visit: &mut impl Visit) {
        let Some((t0, _)) = ray.clip(&self.bounds, t_max) else {
            return;
        };
        // Both children can be pushed at every level: twice the depth bounds the stack.
        let mut stack = [(Child::Inner(0), 0f32); 2 * MAX_DEPTH as usize + 4];
        stack[0] = (self.root(), t0);
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let (child, near) = stack[sp];
            if near > visit.limit() {
                continue;
            }
            let i = match child {
                Child::Leaf(start, count) => {
                    if visit.leaf(&self.slots[Child::leaf_range(start, count)]) {
                        return;
                    }
                    continue;
                }
                Child::Inner(i) => i,
            };
            visit.inner();
            let n = &self.nodes[i as usize];
            let limit = visit.limit();
            let below = ray.clip(&n.boxes[0], limit).map(|(a, _)| (n.child(0), a));
            let above = ray.clip(&n.boxes[1], limit).map(|(a, _)| (n.child(1), a));
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

/// The single-ray walk's leaves list slots of `leaf_order`; `prim` turns a hit's slot back
/// into the triangle's index.
impl LeafWalk for RefitTree {
    fn triangles(&self) -> &[[Vec3; 3]] {
        &self.leaf_order
    }

    fn walk(&self, ray: &WalkRay, t_max: f32, visit: &mut impl Visit) {
        self.walk_boxes(ray, t_max, visit)
    }
}

impl RefitTree {
    /// The inner nodes, the leaf references and the triangles in their order, for the packet
    /// walk (`refit_packet.rs`).
    pub(super) fn walk_arrays(&self) -> (&[BoxNode], &[u32], &[[Vec3; 3]]) {
        (&self.nodes, &self.topology.prim_refs, &self.leaf_order)
    }

    /// A single walk's hit, its slot turned back into the triangle's index.
    fn prim(&self, hit: Option<Hit>) -> Option<Hit> {
        hit.map(|h| Hit {
            prim: self.topology.prim_refs[h.prim as usize],
            ..h
        })
    }

    /// Walks `rays` in packets where consecutive rays share an octant, singly elsewhere;
    /// `out(i, hit)`. Packets are eight rays wide where the CPU has AVX, four otherwise, as the
    /// kd-tree's are (`KdTree::packet_lanes`).
    fn batch<const ANY: bool>(
        &self,
        rays: &[Ray],
        t_max: &[f32],
        out: impl FnMut(usize, Option<Hit>),
    ) {
        assert_eq!(rays.len(), t_max.len(), "one limit per ray");
        #[cfg(target_arch = "x86_64")]
        if self.topology.packet_lanes() == WIDE_LANES {
            // SAFETY: `packet_lanes` gives `WIDE_LANES` only where the CPU has AVX.
            return unsafe { self.batch_avx::<ANY>(rays, t_max, out) };
        }
        self.batch_in::<F4, LANES, ANY>(rays, t_max, out);
    }

    /// `batch` in eight AVX lanes: the walk and its lane operations inline into this function,
    /// which alone is compiled for AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    fn batch_avx<const ANY: bool>(
        &self,
        rays: &[Ray],
        t_max: &[f32],
        out: impl FnMut(usize, Option<Hit>),
    ) {
        self.batch_in::<F8, WIDE_LANES, ANY>(rays, t_max, out);
    }

    /// `batch` in packets of `N` lanes `L`, without closures around the walk (see
    /// `KdTree::batch_in`).
    #[inline(always)]
    fn batch_in<L: Lanes<N>, const N: usize, const ANY: bool>(
        &self,
        rays: &[Ray],
        t_max: &[f32],
        mut out: impl FnMut(usize, Option<Hit>),
    ) {
        for run in group(rays, N) {
            match run {
                Run::Single(i) => {
                    let hit = walk_one::<ANY>(self, &rays[i], t_max[i], &mut NoTally);
                    out(i, self.prim(hit));
                }
                Run::Packet(a, b, oct) => {
                    let hits = self.packet_walk_boxes::<L, N, ANY>(&rays[a..b], &t_max[a..b], oct);
                    for (k, h) in hits.into_iter().take(b - a).enumerate() {
                        out(a + k, h);
                    }
                }
            }
        }
    }
}

impl Intersect for RefitTree {
    fn closest_hit(&self, ray: &Ray, t_max: f32) -> Option<Hit> {
        self.prim(closest_hit(self, ray, t_max, &mut NoTally))
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

    /// Packets of coherent rays (a pinhole's fan, with rays of mixed octants and ray limits),
    /// four and eight lanes wide, find the single walk's hits and occlusion on a refitted,
    /// deformed tree.
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
        // The packets this CPU walks (eight lanes where it has AVX), and four lanes.
        let mut hits = vec![None; rays.len()];
        let mut occluded = vec![false; rays.len()];
        refit.closest_hits(&rays, &t_max, &mut hits);
        refit.any_hits(&rays, &t_max, &mut occluded);
        let mut hits4 = vec![None; rays.len()];
        let mut occluded4 = vec![false; rays.len()];
        refit.batch_in::<F4, LANES, false>(&rays, &t_max, |i, h| hits4[i] = h);
        refit.batch_in::<F4, LANES, true>(&rays, &t_max, |i, h| occluded4[i] = h.is_some());
        let mut found = 0;
        for (i, r) in rays.iter().enumerate() {
            let single = refit.closest_hit(r, t_max[i]);
            let bits = |h: Option<Hit>| h.map(|h| (h.t.to_bits(), h.prim, h.b1.to_bits()));
            assert_eq!(bits(hits[i]), bits(single), "ray {i}");
            assert_eq!(bits(hits4[i]), bits(single), "ray {i}, four lanes");
            let blocked = refit.any_hit(r, t_max[i]);
            assert_eq!((occluded[i], occluded4[i]), (blocked, blocked), "ray {i}");
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
