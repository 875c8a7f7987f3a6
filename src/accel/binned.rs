//! The default SAH kd-tree build: binned where a node is large, exact where it is small, nodes
//! written straight into the final array. The same cost model and termination rule as the exact
//! event sweep of `sah.rs` (kept as `sah-exact`, the oracle this build is measured against).
//!
//! What makes it fast, and where each idea comes from:
//! - **Min-max binning** (Shevtsov et al. 2007; Mitsuba 0.6's `gkdtree.h`): a node's references
//!   are counted into bins on each axis by the bin of their lower and of their upper bound; one
//!   prefix sweep gives, for every bin boundary, the references reaching below and above it. O(N)
//!   per node, no allocation. The three axes' boundaries are costed as three lanes of one sweep.
//!   The best boundary is refined by an exact sweep over the few reference bounds in the two
//!   bins beside it, found by comparing each bound with the two bins' coordinate range.
//! - **Exact search in small nodes** (`small_split.rs`): below `EXACT_MAX` references every
//!   reference bound is a candidate, counted by brute force in four lanes (cheaper than binning
//!   there, and as good as the sweep).
//! - **One-plane straddler split** (Embree's `splitter.h`): a triangle crossing the plane is cut
//!   by that plane only and the two halves' bounds intersected with its current bounds, instead of
//!   re-clipping the triangle against six planes.
//! - **Costs from precomputed constants** (`plane_cost.rs`): one division per node and axis, none
//!   per candidate.
//! - **No allocation per node**: reference lists come from a per-thread pool of spare vectors;
//!   nodes and leaf references are appended to their final arrays in depth-first order.
//! - **Parallel**: the root's binning and partition run on all threads, subtrees on rayon tasks.
//!   Every choice is made by the same sequential rules and bins hold integer counts, so the tree
//!   does not depend on the thread count.

use super::aabb::Aabb;
use super::bins::{BIN_STORE, Bins, Grid, Ref};
use super::flat::Flat;
use super::lanes::{F4, M4};
use super::params::BuildParams;
use super::plane_cost::{AxesCost, AxisCost};
use super::small_split::{EXACT_MAX, exact_split};
use super::spare::{CHUNK_CAPACITY, gather, give, give_chunk, take, take_chunk};
use super::split::{PARALLEL_THRESHOLD, REFERENCE_BUDGET, Split, keep, share};
use super::tree::depth_cap;
use glam::Vec3;
use rayon::prelude::*;
use smallvec::SmallVec;
use std::cell::RefCell;

/// Above this many references a node bins and partitions on all threads, in chunks of this size.
const PARALLEL_NODE: usize = 1 << 16;
const CHUNK: usize = CHUNK_CAPACITY;

/// Bins for a node of `n` references: one per four references, between 8 and 512. Measured on
/// the 1M peer mesh, 1 thread: one per four builds 4% faster than one per two (from 16) at the
/// same SAH cost (148.51 against 148.70) once the best boundary is refined; a cap of 512 instead
/// of 128 (Mitsuba 0.6's count) leaves fewer reference bounds to refine in the large nodes.
fn bin_count(n: usize) -> usize {
    (n / 4).clamp(8, 512)
}

/// The tree's arrays and the box its root covers (that of the triangles with finite vertices).
pub(super) fn build(triangles: &[[Vec3; 3]], params: &BuildParams) -> (Flat, Aabb) {
    // Triangles with a non-finite vertex can never be hit; keep them out of the tree.
    // Six tests written out: an iterator chain here was not inlined (0.8% of a one-thread build's
    // profile).
    let finite = |r: &Ref| {
        let ([a, b, c], [d, e, f]) = (r.lo, r.hi);
        a.is_finite()
            & b.is_finite()
            & c.is_finite()
            & d.is_finite()
            & e.is_finite()
            & f.is_finite()
    };
    // One pass writes every reference straight into a spare vector (the previous build's root
    // list, when there was one) and gathers the bounds of the finite ones: a filtering collect
    // went through one growing vector per task and a copy, and faulted in a tenth of the
    // build's fresh pages; three passes (references, finiteness, bounds) took 6.5 ms of a
    // two-thread build of the 1M peer mesh.
    let n = triangles.len();
    let mut refs = take(n);
    let (bounds, all_finite) = refs.spare_capacity_mut()[..n]
        .par_chunks_mut(CHUNK)
        .zip(triangles.par_chunks(CHUNK))
        .enumerate()
        .map(|(chunk, (room, tris))| {
            let (mut bounds, mut all_finite) = (Aabb::EMPTY, true);
            for (i, (slot, t)) in room.iter_mut().zip(tris).enumerate() {
                let b = Aabb::of_points(t);
                let r = Ref {
                    lo: b.min.to_array(),
                    hi: b.max.to_array(),
                    prim: (chunk * CHUNK + i) as u32,
                };
                if finite(&r) {
                    bounds = bounds.union(&b);
                } else {
                    all_finite = false;
                }
                slot.write(r);
            }
            (bounds, all_finite)
        })
        .reduce(
            || (Aabb::EMPTY, true),
            |(a, x), (b, y)| (a.union(&b), x & y),
        );
    // SAFETY: the chunks above wrote all `n` references.
    unsafe { refs.set_len(n) };
    if !all_finite {
        refs.retain(finite);
    }
    let max_depth = depth_cap(refs.len());
    // A subtree goes to another task only while there are few enough tasks to keep every thread
    // busy with room to balance (16 per thread): finer tasks only add scheduling and parts to
    // splice.
    let parallel_above = PARALLEL_THRESHOLD.max(refs.len() / (16 * rayon::current_num_threads()));
    let ctx = Ctx {
        triangles,
        params,
        max_depth,
        parallel_above,
    };
    // The final arrays, reserved at the sizes the ladder's meshes reach with a traversal cost of
    // 15 (about 6 nodes and 4.3 references per triangle; larger costs make fewer), so they
    // rarely grow by copying.
    let mut out = Flat::with_capacity(6 * refs.len(), 5 * refs.len());
    if !refs.is_empty() {
        let budget = REFERENCE_BUDGET * refs.len() as f64;
        ctx.node(refs, bounds, 0, budget, &mut out);
    } else {
        out.leaf(std::iter::empty());
    }
    (out, bounds)
}

struct Ctx<'a> {
    triangles: &'a [[Vec3; 3]],
    params: &'a BuildParams,
    max_depth: u32,
    parallel_above: usize,
}

/// A child's reference list as the partition appends to it: `extend` with one reference was
/// a call per reference into `SmallVec`'s out-of-line `extend`.
trait RefList {
    fn push_ref(&mut self, r: Ref);
}

impl RefList for Vec<Ref> {
    #[inline(always)]
    fn push_ref(&mut self, r: Ref) {
        self.push(r);
    }
}

impl RefList for SmallVec<[Ref; EXACT_MAX]> {
    #[inline(always)]
    fn push_ref(&mut self, r: Ref) {
        self.push(r);
    }
}

/// Event kinds of the refinement sweep, in the order events at one position are swept (as in
/// `sah.rs`): references ending there are below the plane before those starting there count above.
const END: u8 = 0;
const PLANAR: u8 = 1;
const START: u8 = 2;

thread_local! {
    /// The refinement's events, reused from node to node.
    static WINDOW: RefCell<Vec<(f32, u8)>> = const { RefCell::new(Vec::new()) };
}

impl Ctx<'_> {
    /// A node and its subtree, holding at most `budget` references (see `REFERENCE_BUDGET`).
    fn node(&self, refs: Vec<Ref>, node_box: Aabb, depth: u32, budget: f64, out: &mut Flat) {
        let n = refs.len();
        if n <= EXACT_MAX {
            self.small_node(&refs, node_box, depth, budget, out);
            give(refs);
            return;
        }
        let Some(split) = self.split_or_leaf(&refs, &node_box, depth, out) else {
            give(refs);
            return;
        };
        let (below_box, above_box) = node_box.split(split.axis, split.pos);
        let (below, above) = self.partition(&refs, &split);
        let Some((below_budget, above_budget)) = share(budget, below.len(), above.len()) else {
            out.leaf(refs.iter().map(|r| r.prim));
            give(below);
            give(above);
            give(refs);
            return;
        };
        give(refs);
        out.inner(
            split.axis,
            split.pos,
            (n > self.parallel_above).then_some(above.len()),
            |out| self.node(below, below_box, depth + 1, below_budget, out),
            |out| self.node(above, above_box, depth + 1, above_budget, out),
        );
    }

    /// A node of at most `EXACT_MAX` references and its whole subtree: no child holds more
    /// references than its parent, so the lists live on the stack (measured: 4% faster than
    /// pooled vectors on the 1M peer mesh, 1 thread).
    fn small_node(&self, refs: &[Ref], node_box: Aabb, depth: u32, budget: f64, out: &mut Flat) {
        let Some(split) = self.split_or_leaf(refs, &node_box, depth, out) else {
            return;
        };
        let (below_box, above_box) = node_box.split(split.axis, split.pos);
        let mut below = SmallVec::<[Ref; EXACT_MAX]>::new();
        let mut above = SmallVec::<[Ref; EXACT_MAX]>::new();
        self.partition_into(refs, &split, &mut below, &mut above);
        let Some((below_budget, above_budget)) = share(budget, below.len(), above.len()) else {
            out.leaf(refs.iter().map(|r| r.prim));
            return;
        };
        out.inner(
            split.axis,
            split.pos,
            None,
            |out| self.small_node(&below, below_box, depth + 1, below_budget, out),
            |out| self.small_node(&above, above_box, depth + 1, above_budget, out),
        );
    }

    /// The node's split, or `None` after writing it as a leaf.
    fn split_or_leaf(
        &self,
        refs: &[Ref],
        node_box: &Aabb,
        depth: u32,
        out: &mut Flat,
    ) -> Option<Split> {
        let n = refs.len();
        let split = if depth >= self.max_depth || n <= 1 || node_box.surface_area() <= 0.0 {
            None
        } else {
            self.find_split(refs, node_box)
        };
        if split.is_none() {
            out.leaf(refs.iter().map(|r| r.prim));
        }
        split
    }

    /// The cheapest plane, or `None` when a leaf is cheaper (the SAH termination rule).
    fn find_split(&self, refs: &[Ref], node_box: &Aabb) -> Option<Split> {
        let leaf_cost = self.params.intersection_cost * refs.len() as f32;
        // A plane costs at least K_T (`AxisCost::cost`: its area term is never negative), so
        // where a leaf costs no more than that, no plane beats it and there is nothing to search
        // (nodes of up to 3 references at K_T = 60, 5 at K_T = 100).
        if leaf_cost <= self.params.traversal_cost {
            return None;
        }
        let best = if refs.len() <= EXACT_MAX {
            exact_split(self.params, refs, node_box)
        } else {
            self.binned_split(refs, node_box)
        };
        best.filter(|(cost, _)| *cost < leaf_cost).map(|(_, s)| s)
    }

    /// Min-max binning on each axis; the planes are the bin boundaries. A reference in the plane
    /// of a boundary falls in the bin above it and is counted there, so these splits send planar
    /// references above. The best boundary of each axis is then refined by the exact sweep over
    /// the reference bounds in the two bins beside it: coarse bins at the top of the tree would
    /// otherwise miss the plane that cuts exactly along a cluster's edge, and pay for it with an
    /// extra sliver node over much of the scene (measured: +10% SAH cost on the 1M peer mesh).
    fn binned_split(&self, refs: &[Ref], node_box: &Aabb) -> Option<(f32, Split)> {
        let n = refs.len();
        let grid = Grid::new(node_box, bin_count(n));
        let counts = if n > PARALLEL_NODE {
            refs.par_chunks(CHUNK)
                .map(|c| {
                    let mut b = Bins::with_storage(grid.count, Vec::new());
                    b.add(c, &grid);
                    b
                })
                .reduce(|| Bins::with_storage(grid.count, Vec::new()), Bins::merge)
        } else {
            let mut b = Bins::with_storage(grid.count, BIN_STORE.take());
            b.add(refs, &grid);
            b
        };
        let mut best = None;
        let costs = AxisCost::per_axis(self.params, node_box);
        // Per axis, the boundary index of its cheapest plane (the first of equal ones), kept
        // as the node's best in axis order: the first cheapest boundary in visiting order.
        let axis_best =
            counts.cheapest_boundaries(&grid, node_box, &AxesCost::new(&costs), n as u32);
        for (axis, axis_best) in axis_best.iter().enumerate() {
            if let Some((c, k)) = *axis_best {
                keep(&mut best, c, axis, grid.boundary(axis, k), false);
            }
        }
        // Refining only the axis the bins chose costs a third of refining all three and,
        // measured on the 1M peer mesh, reaches the exact sweep's SAH cost (148.70 against
        // 148.69; refining all three gave 150.10: greedy choices are not monotonic).
        if let Some((_, chosen)) = best {
            let axis = chosen.axis;
            if let Some((_, k)) = axis_best[axis] {
                let (binning, window) = ((&grid, &counts), (axis, k - 1));
                self.refine(refs, node_box, binning, &costs[axis], window, &mut best);
            }
        }
        BIN_STORE.with_borrow_mut(|store| *store = counts.counts);
        best
    }

    /// The exact event sweep over the reference bounds in bins `first` and `first + 1` of `axis`,
    /// starting from the counts (of the node's binning, `grid` and `counts`) of the bins before
    /// them.
    fn refine(
        &self,
        refs: &[Ref],
        node_box: &Aabb,
        (grid, counts): (&Grid, &Bins),
        cost: &AxisCost,
        (axis, first): (usize, usize),
        best: &mut Option<(f32, Split)>,
    ) {
        WINDOW.with_borrow_mut(|ev| {
            // Every reference writes both its events and keeps those inside the window (a
            // planar one once): no branch on where a reference lies, which is unpredictable.
            ev.clear();
            ev.reserve(2 * refs.len());
            let room = &mut ev.spare_capacity_mut()[..2 * refs.len()];
            let (from, to) = grid.pair_range(axis, first);
            let in_window = |x: f32| x >= from && x < to;
            let mut len = 0;
            for r in refs {
                let (lo, hi) = (r.lo[axis], r.hi[axis]);
                let planar = lo == hi;
                room[len].write((lo, if planar { PLANAR } else { START }));
                len += in_window(lo) as usize;
                room[len].write((hi, END));
                len += (in_window(hi) & !planar) as usize;
            }
            // SAFETY: the first `len` entries of the spare room were written above.
            unsafe { ev.set_len(len) };
            ev.sort_unstable_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
            let (started, ended) = counts.before(axis, first);
            sweep(
                ev,
                (started, refs.len() as u32 - ended),
                node_box,
                axis,
                cost,
                best,
            );
        });
    }

    /// The children's reference lists, in the parent's order (so the result is deterministic).
    fn partition(&self, refs: &[Ref], s: &Split) -> (Vec<Ref>, Vec<Ref>) {
        if refs.len() > PARALLEL_NODE {
            // Each chunk into spare vectors of its own thread, then the chunks in order into
            // two spare vectors: no list here is grown or allocated where a spare one fits.
            let parts: Vec<(Vec<Ref>, Vec<Ref>)> = refs
                .par_chunks(CHUNK)
                .map(|c| {
                    let (mut below, mut above) = (take_chunk(), take_chunk());
                    self.partition_into(c, s, &mut below, &mut above);
                    (below, above)
                })
                .collect();
            let (below, above) = rayon::join(
                || gather(parts.iter().map(|p| &p.0[..])),
                || gather(parts.iter().map(|p| &p.1[..])),
            );
            for (b, a) in parts {
                give_chunk(b);
                give_chunk(a);
            }
            (below, above)
        } else {
            let (mut below, mut above) = (take(refs.len()), take(refs.len()));
            self.partition_into(refs, s, &mut below, &mut above);
            (below, above)
        }
    }

    #[inline(never)]
    fn partition_into(
        &self,
        refs: &[Ref],
        s: &Split,
        below: &mut impl RefList,
        above: &mut impl RefList,
    ) {
        let (axis, pos) = (s.axis, s.pos);
        for r in refs {
            let (lo, hi) = (r.lo[axis], r.hi[axis]);
            if lo == pos && hi == pos {
                if s.planar_below {
                    below.push_ref(*r);
                } else {
                    above.push_ref(*r);
                }
            } else if hi <= pos {
                below.push_ref(*r);
            } else if lo >= pos {
                above.push_ref(*r);
            } else {
                let [b, a] = split_straddler(&self.triangles[r.prim as usize], r, axis, pos);
                if let Some(b) = b {
                    below.push_ref(b);
                }
                if let Some(a) = a {
                    above.push_ref(a);
                }
            }
        }
    }
}

/// The exact sweep over sorted events on one axis, starting with `below` references already
/// begun and `above` not yet ended: each distinct position is a candidate, with references lying
/// in it tried on either side (the rule of `sah.rs`).
fn sweep(
    ev: &[(f32, u8)],
    (mut below, mut above): (u32, u32),
    node_box: &Aabb,
    axis: usize,
    cost: &AxisCost,
    best: &mut Option<(f32, Split)>,
) {
    let (min, max) = (node_box.min[axis], node_box.max[axis]);
    let mut i = 0;
    while i < ev.len() {
        let pos = ev[i].0;
        let mut count = [0u32; 3];
        while i < ev.len() && ev[i].0 == pos {
            count[ev[i].1 as usize] += 1;
            i += 1;
        }
        let [ending, planar, starting] = count;
        above -= planar + ending;
        if pos > min && pos < max {
            let l = pos - min;
            keep(best, cost.cost(l, below + planar, above), axis, pos, true);
            keep(best, cost.cost(l, below, above + planar), axis, pos, false);
        }
        below += starting + planar;
    }
}

/// Cuts a triangle crossing the plane `pos` on `axis` by that plane alone: the bounds of the
/// vertices and edge crossings on each side, intersected with the reference's current bounds.
/// A side whose intersection is empty holds no part of the triangle inside the node. Points are
/// four lanes (x, y, z, unused); the three edges' crossing parameters are one division, and
/// which points count on which side are selects, not branches: where a vertex lies and which
/// edges cross are unpredictable (a branch per edge took half of this function's time).
fn split_straddler(tri: &[Vec3; 3], r: &Ref, axis: usize, pos: f32) -> [Option<Ref>; 2] {
    let (inf, neg_inf) = (F4::splat(f32::INFINITY), F4::splat(f32::NEG_INFINITY));
    let (mut lo, mut hi) = ([inf; 2], [neg_inf; 2]);
    // Adds `v` to the below side's bounds where `below`, to the above side's where `above`.
    let mut add = |v: F4, below: M4, above: M4| {
        lo[0] = lo[0].min(F4::select(below, v, inf));
        hi[0] = hi[0].max(F4::select(below, v, neg_inf));
        lo[1] = lo[1].min(F4::select(above, v, inf));
        hi[1] = hi[1].max(F4::select(above, v, neg_inf));
    };
    let on_axis = F4::new([0.0, 1.0, 2.0, 3.0]).eq(F4::splat(axis as f32));
    let pos4 = F4::splat(pos);
    let v = [
        F4::xyz(tri[0].to_array()),
        F4::xyz(tri[1].to_array()),
        F4::xyz(tri[2].to_array()),
    ];
    // Lane i: edge i, from vertex i to vertex i + 1; lane 3 repeats edge 0.
    let (a0, a1, a2) = (tri[0][axis], tri[1][axis], tri[2][axis]);
    let (pa, qa) = (F4::new([a0, a1, a2, a0]), F4::new([a1, a2, a0, a1]));
    let t = pos4.sub(pa).div(qa.sub(pa)).to_array();
    let crosses = (pa.lt(pos4).and(qa.gt(pos4)))
        .or(pa.gt(pos4).and(qa.lt(pos4)))
        .bits();
    let (at_or_below, at_or_above) = (pa.le(pos4).bits(), pa.ge(pos4).bits());
    for i in 0..3 {
        let (p, q) = (v[i], v[(i + 1) % 3]);
        add(
            p,
            M4::all(at_or_below >> i & 1 == 1),
            M4::all(at_or_above >> i & 1 == 1),
        );
        let crossing = M4::all(crosses >> i & 1 == 1);
        let x = F4::select(on_axis, pos4, p.add(q.sub(p).mul(F4::splat(t[i]))));
        add(x, crossing, crossing);
    }
    // Written out: an array `map` here is not always inlined.
    [
        cut_side(r, (lo[0], hi[0]), true, on_axis, pos4),
        cut_side(r, (lo[1], hi[1]), false, on_axis, pos4),
    ]
}

/// One side of a cut reference: the bounds gathered on that side (`lo`, `hi`), intersected
/// with the reference's bounds and the side's half-space of the plane `pos4` on the axis lane
/// `on_axis`; `None` when nothing of the triangle lies there inside the node.
fn cut_side(r: &Ref, (lo, hi): (F4, F4), below: bool, on_axis: M4, pos4: F4) -> Option<Ref> {
    let (mut c_lo, mut c_hi) = (F4::xyz(r.lo).max(lo), F4::xyz(r.hi).min(hi));
    if below {
        c_hi = F4::select(on_axis, c_hi.min(pos4), c_hi);
    } else {
        c_lo = F4::select(on_axis, c_lo.max(pos4), c_lo);
    }
    (c_lo.le(c_hi).bits() & 0b111 == 0b111).then(|| {
        let (l, h) = (c_lo.to_array(), c_hi.to_array());
        Ref {
            lo: [l[0], l[1], l[2]],
            hi: [h[0], h[1], h[2]],
            prim: r.prim,
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::lanes::M4;
    use crate::accel::test_rng::Lcg;

    /// The straddler split as it was, with a branch per edge.
    fn branchy_straddler(tri: &[Vec3; 3], r: &Ref, axis: usize, pos: f32) -> [Option<Ref>; 2] {
        let (inf, neg_inf) = (F4::splat(f32::INFINITY), F4::splat(f32::NEG_INFINITY));
        let (mut lo, mut hi) = ([inf; 2], [neg_inf; 2]);
        // Adds `v` to the below side's bounds if `below`, to the above side's if `above`.
        let mut add = |v: F4, below: bool, above: bool| {
            for (side, on) in [below, above].into_iter().enumerate() {
                let m = M4::all(on);
                lo[side] = lo[side].min(F4::select(m, v, inf));
                hi[side] = hi[side].max(F4::select(m, v, neg_inf));
            }
        };
        let on_axis = F4::new([0.0, 1.0, 2.0, 3.0]).eq(F4::splat(axis as f32));
        let pos4 = F4::splat(pos);
        let v = tri.map(|p| F4::xyz(p.to_array()));
        for i in 0..3 {
            let (p, q) = (v[i], v[(i + 1) % 3]);
            let (pa, qa) = (tri[i][axis], tri[(i + 1) % 3][axis]);
            add(p, pa <= pos, pa >= pos);
            if (pa < pos && qa > pos) || (pa > pos && qa < pos) {
                let t = F4::splat((pos - pa) / (qa - pa));
                add(
                    F4::select(on_axis, pos4, p.add(q.sub(p).mul(t))),
                    true,
                    true,
                );
            }
        }
        [0, 1].map(|side| cut_side(r, (lo[side], hi[side]), side == 0, on_axis, pos4))
    }

    /// The select-based split gives the branchy one's bounds bit for bit, on triangles with
    /// vertices on the plane, edges along it and references already clipped.
    #[test]
    fn straddler_split_matches_the_branchy_one() {
        let mut rng = Lcg(11);
        let mut split = 0;
        for case in 0..20_000 {
            // Coordinates on a coarse grid, so that vertices often lie in the plane.
            let mut coord = |_| (rng.next() * 8.0).floor() / 4.0 - 1.0;
            let tri = [0; 3].map(|_| Vec3::from_array([0; 3].map(&mut coord)));
            let axis = case % 3;
            let pos = coord(0) + 0.125 * (case % 2) as f32;
            let b = Aabb::of_points(&tri);
            // Every fourth reference is already cut down to part of the triangle's box.
            let shrink = if case % 4 == 0 { 0.25 } else { 0.0 };
            let r = Ref {
                lo: (b.min + shrink).min(b.max).to_array(),
                hi: b.max.to_array(),
                prim: case as u32,
            };
            if !(r.lo[axis] < pos && r.hi[axis] > pos) {
                continue;
            }
            split += 1;
            let key = |s: [Option<Ref>; 2]| {
                s.map(|r| r.map(|r| (r.lo.map(f32::to_bits), r.hi.map(f32::to_bits))))
            };
            assert_eq!(
                key(split_straddler(&tri, &r, axis, pos)),
                key(branchy_straddler(&tri, &r, axis, pos)),
                "case {case}: {tri:?} {r:?} {axis} {pos}"
            );
        }
        assert!(split > 5_000, "too few straddlers: {split}");
    }
}
