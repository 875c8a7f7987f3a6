//! The O(N log N) SAH kd-tree build of Wald and Havran ("On building fast kd-trees for ray tracing,
//! and on doing that in O(N log N)", RT'06). Split candidates are events (a reference starts, ends,
//! or lies planar at a position on an axis), sorted once for the whole scene. Each node sweeps its
//! events to find the cheapest plane, then splits its event list in one linear pass: references
//! entirely on one side keep their events in order; only the straddlers, clipped to each child, get
//! new events, which are sorted (there are few: O(sqrt N) on typical scenes) and merged in.
//! Subtrees are built in parallel, and at the top of the tree, where one node holds everything, the
//! three axes are swept in parallel, so two cores are busy from the root down. The result does not
//! depend on the thread count: every choice is made by the same sequential rules.

use super::aabb::Aabb;
use super::params::BuildParams;
use super::split::{
    BuildNode, Item, PARALLEL_THRESHOLD, REFERENCE_BUDGET, Side, Split, clip_straddler,
    consider_plane, share, side_of,
};
use glam::Vec3;
use rayon::prelude::*;
use rustc_hash::FxHashMap;
use std::cmp::Ordering;

/// Event kinds, in the order events at one position are swept: references ending there are
/// below the plane before those starting there are counted above it.
const END: u8 = 0;
const PLANAR: u8 = 1;
const START: u8 = 2;

/// Above this many events a node sweeps its three axes on separate rayon tasks.
const PARALLEL_SWEEP: usize = 1 << 16;

/// Side codes in the per-thread classification array; zero means "straddles" (or unvisited).
const MARK_BELOW: u8 = 1;
const MARK_ABOVE: u8 = 2;

thread_local! {
    /// One byte per triangle of the scene: which side of the current split a reference lies on.
    /// A node classifies and splits its events on one thread without yielding to rayon, and
    /// clears what it marked before returning, so each thread can keep one array for every node.
    static SIDES: std::cell::RefCell<Vec<u8>> = const { std::cell::RefCell::new(Vec::new()) };
}

#[derive(Clone, Copy, Debug)]
struct Event {
    pos: f32,
    prim: u32,
    axis: u8,
    kind: u8,
}

/// Total order: axis, position, kind, then primitive (so equal inputs always sort the same way).
fn order(a: &Event, b: &Event) -> Ordering {
    a.axis
        .cmp(&b.axis)
        .then(a.pos.total_cmp(&b.pos))
        .then(a.kind.cmp(&b.kind))
        .then(a.prim.cmp(&b.prim))
}

fn push_events(out: &mut Vec<Event>, it: &Item) {
    for axis in 0..3u8 {
        let (lo, hi) = (it.bounds.min[axis as usize], it.bounds.max[axis as usize]);
        let e = |pos, kind| Event {
            pos,
            prim: it.prim,
            axis,
            kind,
        };
        if lo == hi {
            out.push(e(lo, PLANAR));
        } else {
            out.push(e(lo, START));
            out.push(e(hi, END));
        }
    }
}

pub(super) fn build(
    triangles: &[[Vec3; 3]],
    items: Vec<Item>,
    bounds: Aabb,
    params: &BuildParams,
    max_depth: u32,
) -> BuildNode {
    let mut events = Vec::with_capacity(items.len() * 6);
    for it in &items {
        push_events(&mut events, it);
    }
    events.par_sort_unstable_by(order);
    let ctx = Ctx {
        triangles,
        params,
        max_depth,
    };
    let budget = REFERENCE_BUDGET * items.len() as f64;
    ctx.node(events, items.len(), bounds, 0, budget)
}

struct Ctx<'a> {
    triangles: &'a [[Vec3; 3]],
    params: &'a BuildParams,
    max_depth: u32,
}

impl Ctx<'_> {
    /// A node and its subtree, holding at most `budget` references (`REFERENCE_BUDGET`).
    fn node(
        &self,
        events: Vec<Event>,
        n: usize,
        node_box: Aabb,
        depth: u32,
        budget: f64,
    ) -> BuildNode {
        let split = if depth >= self.max_depth || n <= 1 {
            None
        } else {
            self.find_split(&events, n, &node_box)
        };
        let Some(split) = split else {
            return BuildNode::Leaf(leaf_prims(&events));
        };
        let (below_box, above_box) = node_box.split(split.axis, split.pos);
        // Children hold at most twice the node's references: only near the budget is the
        // node's own list kept, for the leaf it becomes when the split would pass it.
        let as_leaf = (2.0 * n as f64 > budget).then(|| leaf_prims(&events));
        let ((eb, nb), (ea, na)) = self.split_events(events, n, &split, &below_box, &above_box);
        let Some((below_budget, above_budget)) = share(budget, nb, na) else {
            return BuildNode::Leaf(
                as_leaf.expect("a split past the budget holds over half of it"),
            );
        };
        let (lo, hi) = if nb + na > PARALLEL_THRESHOLD {
            rayon::join(
                || self.node(eb, nb, below_box, depth + 1, below_budget),
                || self.node(ea, na, above_box, depth + 1, above_budget),
            )
        } else {
            (
                self.node(eb, nb, below_box, depth + 1, below_budget),
                self.node(ea, na, above_box, depth + 1, above_budget),
            )
        };
        BuildNode::Inner {
            split,
            below: Box::new(lo),
            above: Box::new(hi),
        }
    }

    /// The cheapest plane over the three axes, or `None` when a leaf is cheaper. Ties go to the
    /// lower axis, then the lower position (the order of the sequential sweep).
    fn find_split(&self, events: &[Event], n: usize, node_box: &Aabb) -> Option<Split> {
        let area = node_box.surface_area();
        if area <= 0.0 {
            return None;
        }
        let bounds: Vec<usize> = (0..=3u8)
            .map(|a| events.partition_point(|e| e.axis < a))
            .collect();
        let sweep = |axis: usize| {
            self.sweep(
                &events[bounds[axis]..bounds[axis + 1]],
                axis,
                n,
                node_box,
                area,
            )
        };
        let per_axis: Vec<Option<(f32, Split)>> = if events.len() > PARALLEL_SWEEP {
            (0..3).into_par_iter().map(sweep).collect()
        } else {
            (0..3).map(sweep).collect()
        };
        let mut best: Option<(f32, Split)> = None;
        for (cost, s) in per_axis.into_iter().flatten() {
            if best.is_none_or(|(c, _)| cost < c) {
                best = Some((cost, s));
            }
        }
        let leaf_cost = self.params.intersection_cost * n as f32;
        best.filter(|(cost, _)| *cost < leaf_cost).map(|(_, s)| s)
    }

    /// One axis: visit each distinct position once, with the counts of references entirely below
    /// (`n_below`), entirely above (`n_above`) and lying in the plane.
    fn sweep(
        &self,
        ev: &[Event],
        axis: usize,
        n: usize,
        node_box: &Aabb,
        area: f32,
    ) -> Option<(f32, Split)> {
        let mut best: Option<(f32, Split)> = None;
        let (mut n_below, mut n_above) = (0usize, n);
        let mut i = 0;
        while i < ev.len() {
            let pos = ev[i].pos;
            let mut count = [0usize; 3];
            while i < ev.len() && ev[i].pos == pos {
                count[ev[i].kind as usize] += 1;
                i += 1;
            }
            let [ending, planar, starting] = count;
            n_above -= planar + ending;
            if pos > node_box.min[axis] && pos < node_box.max[axis] {
                consider_plane(
                    &mut best,
                    self.params,
                    node_box,
                    area,
                    axis,
                    pos,
                    (n_below, n_above, planar),
                );
            }
            n_below += starting + planar;
        }
        best
    }

    /// Splits a node's sorted events into the children's sorted events (and reference counts).
    fn split_events(
        &self,
        events: Vec<Event>,
        n: usize,
        s: &Split,
        below_box: &Aabb,
        above_box: &Aabb,
    ) -> ((Vec<Event>, usize), (Vec<Event>, usize)) {
        // Classify from the split axis alone: a reference ending at or before the plane is below,
        // one starting at or after it is above, planar ones follow the split; the rest straddle.
        let lo = events.partition_point(|e| (e.axis as usize) < s.axis);
        let hi = events.partition_point(|e| (e.axis as usize) <= s.axis);
        let axis_events = &events[lo..hi];
        let mark = |e: &Event| match e.kind {
            END if e.pos <= s.pos => MARK_BELOW,
            START if e.pos >= s.pos => MARK_ABOVE,
            PLANAR => match side_of(e.pos, e.pos, s) {
                Side::Below => MARK_BELOW,
                _ => MARK_ABOVE,
            },
            _ => 0,
        };
        let mut below = Vec::new();
        let mut above = Vec::new();
        let mut straddlers: FxHashMap<u32, Aabb> = FxHashMap::default();
        let (mut below_only, mut above_only) = (0, 0);
        SIDES.with_borrow_mut(|sides| {
            if sides.len() < self.triangles.len() {
                sides.resize(self.triangles.len(), 0);
            }
            for e in axis_events {
                let m = mark(e);
                if m != 0 {
                    sides[e.prim as usize] = m;
                    below_only += (m == MARK_BELOW) as usize;
                    above_only += (m == MARK_ABOVE) as usize;
                }
            }
            // A reference has at most six events (two per axis).
            below.reserve_exact((6 * below_only).min(events.len()));
            above.reserve_exact((6 * above_only).min(events.len()));
            for e in &events {
                match sides[e.prim as usize] {
                    MARK_BELOW => below.push(*e),
                    MARK_ABOVE => above.push(*e),
                    _ => {
                        let b = straddlers.entry(e.prim).or_insert(Aabb::EMPTY);
                        let axis = e.axis as usize;
                        if e.kind != END {
                            b.min[axis] = e.pos;
                        }
                        if e.kind != START {
                            b.max[axis] = e.pos;
                        }
                    }
                }
            }
            for e in axis_events {
                sides[e.prim as usize] = 0;
            }
        });
        let _ = n;
        let mut new_below = Vec::new();
        let mut new_above = Vec::new();
        for (&prim, bounds) in &straddlers {
            let tri = &self.triangles[prim as usize];
            let [b, a] = clip_straddler(tri, prim, bounds, below_box, above_box);
            if let Some(it) = b {
                push_events(&mut new_below, &it);
            }
            if let Some(it) = a {
                push_events(&mut new_above, &it);
            }
        }
        let nb = below_only + count_refs(&new_below);
        let na = above_only + count_refs(&new_above);
        new_below.sort_unstable_by(order);
        new_above.sort_unstable_by(order);
        ((merge(below, new_below), nb), (merge(above, new_above), na))
    }
}

/// References described by a list of events: one START or PLANAR event each on axis 0.
/// A node's references as a leaf: each has exactly one START or PLANAR event on axis 0.
fn leaf_prims(events: &[Event]) -> Vec<u32> {
    let axis0 = events.partition_point(|e| e.axis == 0);
    events[..axis0]
        .iter()
        .filter(|e| e.kind != END)
        .map(|e| e.prim)
        .collect()
}

fn count_refs(events: &[Event]) -> usize {
    events
        .iter()
        .filter(|e| e.axis == 0 && e.kind != END)
        .count()
}

fn merge(a: Vec<Event>, b: Vec<Event>) -> Vec<Event> {
    if b.is_empty() {
        return a;
    }
    let mut out = Vec::with_capacity(a.len() + b.len());
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        if order(&a[i], &b[j]) != Ordering::Greater {
            out.push(a[i]);
            i += 1;
        } else {
            out.push(b[j]);
            j += 1;
        }
    }
    out.extend_from_slice(&a[i..]);
    out.extend_from_slice(&b[j..]);
    out
}

#[cfg(test)]
mod tests {
    use super::super::test_rng::Lcg;
    use super::super::{BuildParams, KdTree};
    use glam::Vec3;

    fn same_tree(tris: Vec<[Vec3; 3]>, what: &str) {
        let fast = KdTree::build(
            tris.clone(),
            BuildParams::with_method(super::super::SplitMethod::SahExact),
        );
        let slow = KdTree::build_quadratic_sah(tris, BuildParams::default());
        assert_eq!(fast.shape(), slow.shape(), "{what}: trees differ");
        assert_eq!(fast.stats().sah_cost, slow.stats().sah_cost, "{what}");
        assert!(
            fast.stats().nodes > 1,
            "{what}: the test needs a tree that splits"
        );
    }

    #[test]
    fn event_sweep_builds_the_same_tree_as_the_quadratic_search_on_random_soups() {
        for seed in 1..6 {
            let mut rng = Lcg(seed);
            let tris: Vec<[Vec3; 3]> = (0..300)
                .map(|_| {
                    let c = rng.v(10.0);
                    let s = if rng.next() < 0.2 { 6.0 } else { 1.0 };
                    [c, c + (rng.v(1.0) - 0.5) * s, c + (rng.v(1.0) - 0.5) * s]
                })
                .collect();
            same_tree(tris, &format!("soup {seed}"));
        }
    }

    #[test]
    fn event_sweep_matches_on_planar_grids_coincident_and_thin_triangles() {
        let mut grid = Vec::new();
        for i in 0..10 {
            for j in 0..10 {
                let (x, y) = (i as f32, j as f32);
                grid.push([
                    Vec3::new(x, y, 0.0),
                    Vec3::new(x + 1.0, y, 0.0),
                    Vec3::new(x, y + 1.0, 0.0),
                ]);
                grid.push([
                    Vec3::new(x, 0.0, y),
                    Vec3::new(x, 1.0, y),
                    Vec3::new(x, 0.0, y + 1.0),
                ]);
            }
        }
        same_tree(grid, "axis-aligned planes on candidate splits");

        let mut coincident = vec![[Vec3::ZERO, Vec3::X, Vec3::Y]; 200];
        coincident.push([
            Vec3::splat(5.0),
            Vec3::splat(5.0) + Vec3::X,
            Vec3::splat(5.0) + Vec3::Z,
        ]);
        same_tree(coincident, "coincident triangles");

        let mut rng = Lcg(99);
        let thin: Vec<[Vec3; 3]> = (0..200)
            .map(|_| {
                let a = rng.v(10.0);
                let b = rng.v(10.0);
                [a, b, b + Vec3::splat(1e-4)]
            })
            .collect();
        same_tree(thin, "long thin triangles");
    }
}
