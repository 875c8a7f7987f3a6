//! Rays through a refitted tree in packets: the packet walk of `packet.rs` for the bounded
//! tree's overlapping child boxes, in four lanes or (where the CPU has AVX) eight, as the
//! kd-tree's packets are (`query.rs`). Consecutive rays whose directions share an octant
//! clip each child box lane by lane, the lanes that enter a child go down it together, and the
//! nearer child (by the octant on the node's split axis) comes first. A leaf's triangles are
//! tested against the lanes still walking with the packet watertight test.
//!
//! Each lane finds its closest hit, or whether anything blocks it, as its single-ray walk
//! (`RefitTree::walk_boxes`) does: every box the ray enters before its best hit is visited and
//! each triangle sits in exactly one leaf. The order of the leaves can differ from the single
//! walk's (which orders two children by the ray's own entry distances), so of two triangles
//! hit at exactly the same distance another one can win; any-hit answers cannot differ.

use super::aabb::Aabb;
use super::box_node::Child;
use super::lanes::{LaneMask, Lanes};
use super::packet::PacketRays;
use super::refit::RefitTree;
use super::tree::MAX_DEPTH;
use super::triangle::{RayPack, intersect_packet};
use super::{Hit, Ray};

/// Per lane, where the rays enter `b` (before `limit`), and the lanes of `active` that do.
#[inline(always)]
fn enter<L: Lanes<N>, const N: usize>(
    rays: &PacketRays<L, N>,
    b: &Aabb,
    limit: L,
    active: u32,
) -> (L, u32) {
    let (t0, t1) = rays.clip(b, limit);
    (t0, active & !t0.gt(t1).bits())
}

impl RefitTree {
    /// The walk of `rays` (2 to `N` rays, all in octant `oct`) in lanes `L`: per lane, the
    /// closest hit before `t_max` (`ANY = false`) or whether anything is hit (`ANY = true`).
    #[inline(always)]
    pub(super) fn packet_walk_boxes<L: Lanes<N>, const N: usize, const ANY: bool>(
        &self,
        rays: &[Ray],
        t_max: &[f32],
        oct: u8,
    ) -> [Option<Hit>; N] {
        let mut hits = [None; N];
        let n = rays.len();
        debug_assert!((1..=N).contains(&n) && t_max.len() == n);
        let (nodes, refs, triangles) = self.walk_arrays();
        let packet = PacketRays::<L, N>::new(rays);
        // Written out, no closures: the eight-lane walk needs every lane operation inlined.
        let mut best = [0.0; N];
        for (i, b) in best.iter_mut().enumerate() {
            *b = t_max[i.min(n - 1)];
        }
        let mut best_v = L::new(best);
        let (entry, active) = enter(&packet, &self.bounds(), best_v, (1 << n) - 1);
        if active == 0 {
            return hits;
        }
        let pre = RayPack::<L, N>::new(packet.rays);
        // Both children can be pushed at every level: twice the depth bounds the stack.
        let mut stack = [(Child::Inner(0), 0u32, L::splat(0.0)); 2 * MAX_DEPTH as usize + 4];
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
                        for k in (0..N).filter(|k| hit >> k & 1 == 1) {
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
                            best_v = L::new(best);
                        }
                    }
                    continue;
                }
            };
            let node = &nodes[i as usize];
            let (below_entry, below) = enter(&packet, &node.boxes[0], best_v, lanes);
            let (above_entry, above) = enter(&packet, &node.boxes[1], best_v, lanes);
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
