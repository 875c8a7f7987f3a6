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
use super::lanes::F4;
use super::packet::LANES;
use super::refit::RefitTree;
use super::tree::MAX_DEPTH;
use super::triangle::{RayPre4, intersect4};
use super::{Hit, Ray};

/// Per lane, where the rays enter `b` (before `limit`), and the lanes of `active` that do.
#[inline(always)]
fn enter(b: &Aabb, origin: &[F4; 3], inv_dir: &[F4; 3], limit: F4, active: u32) -> (F4, u32) {
    let (lo, hi) = (b.min.to_array(), b.max.to_array());
    let (mut t0, mut t1) = (F4::splat(0.0), limit);
    for axis in 0..3 {
        let near = F4::splat(lo[axis]).sub(origin[axis]).mul(inv_dir[axis]);
        let far = F4::splat(hi[axis]).sub(origin[axis]).mul(inv_dir[axis]);
        let swap = near.gt(far);
        t0 = t0.max_num(F4::select(swap, far, near));
        t1 = t1.min_num(F4::select(swap, near, far));
    }
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
        let (nodes, refs) = self.topology_arrays();
        if nodes.is_empty() || self.bounds().is_empty() {
            return hits;
        }
        let lane_rays: [Ray; LANES] = std::array::from_fn(|i| rays[i.min(n - 1)]);
        let [ox, oy, oz, _] = F4::columns(lane_rays.map(|r| r.origin.extend(0.0).to_array()));
        let [dx, dy, dz, _] = F4::columns(lane_rays.map(|r| r.dir.extend(1.0).to_array()));
        let origin = [ox, oy, oz];
        let inv_dir = [dx, dy, dz].map(|d| F4::splat(1.0).div(d));
        let mut best = std::array::from_fn::<f32, LANES, _>(|i| t_max[i.min(n - 1)]);
        let mut best_v = F4::new(best);
        let (entry, active) = enter(&self.bounds(), &origin, &inv_dir, best_v, (1 << n) - 1);
        if active == 0 {
            return hits;
        }
        let pre = RayPre4::new(lane_rays);
        let triangles = self.triangles();
        let boxes = self.boxes();
        // Both children can be pushed at every level: twice the depth bounds the stack.
        let mut stack = [(0u32, 0u32, F4::splat(0.0)); 2 * MAX_DEPTH as usize + 4];
        stack[0] = (0, active, entry);
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let (i, lanes, near) = stack[sp];
            // A lane whose best hit lies before where it enters this box is done with it.
            let lanes = lanes & !near.gt(best_v).bits();
            if lanes == 0 {
                continue;
            }
            let node = nodes[i as usize];
            if node.is_leaf() {
                for &p in &refs[node.leaf_range()] {
                    let (hit, [t, b1, b2]) =
                        intersect4(&pre, &triangles[p as usize], best_v, lanes);
                    for k in (0..LANES).filter(|k| hit >> k & 1 == 1) {
                        hits[k] = Some(Hit {
                            t: t[k],
                            prim: p,
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
            let [below_box, above_box] = &boxes[i as usize];
            let (below_entry, below) = enter(below_box, &origin, &inv_dir, best_v, lanes);
            let (above_entry, above) = enter(above_box, &origin, &inv_dir, best_v, lanes);
            let below = (i + 1, below, below_entry);
            let above = (i + node.above_offset() as u32, above, above_entry);
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
