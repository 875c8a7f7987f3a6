//! Four rays through a refitted tree at once: the packet walk of `packet.rs` for the bounded
//! tree's overlapping child boxes. Up to four consecutive rays whose directions share an octant
//! clip each child box lane by lane, the lanes that enter a child go down it together, and the
//! nearer child (by the octant on the node's split axis) comes first. A leaf's triangles are
//! tested against the lanes still walking with the four-lane watertight test.
//!
//! Each lane finds its closest hit, or whether anything blocks it, as its single-ray walk
//! (`RefitTree::walk_boxes`) does: every box the ray enters before its best hit is visited and
//! each triangle sits in exactly one leaf. The order of the leaves can differ from the single
//! walk's (which orders two children by the ray's own entry distances), so of two triangles
//! hit at exactly the same distance another one can win; any-hit answers cannot differ.

use super::aabb::Aabb;
use super::box_node::Child;
use super::lanes::F4;
use super::packet::{LANES, PacketRays};
use super::refit::RefitTree;
use super::tree::MAX_DEPTH;
use super::triangle::{RayPre4, intersect_packet};
use super::{Hit, Ray};

/// Per lane, where the rays enter `b` (before `limit`), and the lanes of `active` that do.
#[inline(always)]
fn enter(rays: &PacketRays<F4, LANES>, b: &Aabb, limit: F4, active: u32) -> (F4, u32) {
    let (t0, t1) = rays.clip(b, limit);
    (t0, active & !t0.gt(t1).bits())
}

impl RefitTree {
    /// The walk of `rays` (2 to `LANES` rays, all in octant `oct`): per lane, the closest hit
    /// before `t_max` (`ANY = false`) or whether anything is hit (`ANY = true`).
    pub(super) fn packet_walk_boxes<const ANY: bool>(
        &self,
        rays: &[Ray],
        t_max: &[f32],
        oct: u8,
    ) -> [Option<Hit>; LANES] {
        let mut hits = [None; LANES];
        let n = rays.len();
        debug_assert!((1..=LANES).contains(&n) && t_max.len() == n);
        let (nodes, refs, triangles) = self.walk_arrays();
        let rays4 = PacketRays::<F4, LANES>::new(rays);
        let mut best = std::array::from_fn::<f32, LANES, _>(|i| t_max[i.min(n - 1)]);
        let mut best_v = F4::new(best);
        let (entry, active) = enter(&rays4, &self.bounds(), best_v, (1 << n) - 1);
        if active == 0 {
            return hits;
        }
        let pre = RayPre4::new(rays4.rays);
        // Both children can be pushed at every level: twice the depth bounds the stack.
        let mut stack = [(Child::Inner(0), 0u32, F4::splat(0.0)); 2 * MAX_DEPTH as usize + 4];
        stack[0] = (self.root(), active, entry);
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let (child, lanes, near) = stack[sp];
            // A lane whose best hit lies before where it enters this box is done with it.
            let lanes = lanes & !near.gt(best_v).bits();
            if lanes == 0 {
                continue;
            }
            let i = match child {
                Child::Inner(i) => i,
                Child::Leaf(start, count) => {
                    for j in Child::leaf_range(start, count) {
                        let (hit, [t, b1, b2]) =
                            intersect_packet(&pre, &triangles[j], best_v, lanes);
                        for k in (0..LANES).filter(|k| hit >> k & 1 == 1) {
                            hits[k] = Some(Hit {
                                t: t[k],
                                prim: refs[j],
                                b1: b1[k],
                                b2: b2[k],
                            });
                            // An any-hit lane is done: no box is entered before minus infinity.
                            best[k] = if ANY { f32::NEG_INFINITY } else { t[k] };
                        }
                        if hit != 0 {
                            best_v = F4::new(best);
                        }
                    }
                    continue;
                }
            };
            let node = &nodes[i as usize];
            let (below_entry, below) = enter(&rays4, &node.boxes[0], best_v, lanes);
            let (above_entry, above) = enter(&rays4, &node.boxes[1], best_v, lanes);
            let below = (node.child(0), below, below_entry);
            let above = (node.child(1), above, above_entry);
            // The nearer child is popped first: the one the octant meets first on the split
            // axis.
            let (first, second) = if oct >> node.axis() & 1 == 1 {
                (below, above)
            } else {
                (above, below)
            };
            for child in [second, first] {
                if child.1 != 0 {
                    stack[sp] = child;
                    sp += 1;
                }
            }
        }
        hits
    }
}
