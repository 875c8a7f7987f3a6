//! kd-tree construction. `sah` (the default) uses the binned build of `binned.rs`, `sah-exact` the
//! O(N log N) event sweep of `sah.rs`; `center` (middle of
//! the node's longest axis) and `median` (object median on that axis) use the simple recursive
//! builder here, which also hosts the quadratic SAH search the literature starts from, kept as
//! the test oracle of the exact sweep. Both share the split rules of `split.rs`.

use super::aabb::Aabb;
use super::params::{BuildParams, SplitMethod};
use super::split::{
    BuildNode, Item, PARALLEL_THRESHOLD, REFERENCE_BUDGET, Side, Split, clip_straddler,
    consider_plane, share, side_of,
};
use super::tree::{KdTree, depth_cap, flatten};
use glam::Vec3;
use std::time::Instant;

impl KdTree {
    pub fn build(triangles: Vec<[Vec3; 3]>, params: BuildParams) -> KdTree {
        Self::build_with(triangles, params, false)
    }

    /// The SAH tree built with the quadratic split search (every candidate plane counted against
    /// every reference). Slow; the oracle the O(N log N) build is tested against.
    pub fn build_quadratic_sah(triangles: Vec<[Vec3; 3]>, params: BuildParams) -> KdTree {
        Self::build_with(
            triangles,
            BuildParams {
                method: SplitMethod::Sah,
                ..params
            },
            true,
        )
    }

    fn build_with(triangles: Vec<[Vec3; 3]>, params: BuildParams, quadratic: bool) -> KdTree {
        let start = Instant::now();
        let params = params.for_triangles(triangles.len());
        if params.method == SplitMethod::Sah && !quadratic {
            let (flat, bounds) = super::binned::build(&triangles, &params);
            let (nodes, refs) = flat.into_arrays();
            return KdTree::assemble(nodes, refs, triangles, bounds, params, start);
        }
        let items: Vec<Item> = triangles
            .iter()
            .enumerate()
            .filter_map(|(i, t)| {
                let b = Aabb::of_points(t);
                // Triangles with a non-finite vertex can never be hit; keep them out of the tree.
                (b.min.is_finite() && b.max.is_finite()).then_some(Item {
                    prim: i as u32,
                    bounds: b,
                })
            })
            .collect();
        let bounds = items
            .iter()
            .fold(Aabb::EMPTY, |acc, it| acc.union(&it.bounds));
        let max_depth = depth_cap(items.len());
        let root = if params.method == SplitMethod::SahExact && !quadratic {
            super::sah::build(&triangles, items, bounds, &params, max_depth)
        } else {
            let builder = Builder {
                params,
                triangles: &triangles,
                max_depth,
            };
            let budget = REFERENCE_BUDGET * items.len() as f64;
            builder.build(items, bounds, 0, budget)
        };
        let (nodes, prim_refs) = flatten(root);
        KdTree::assemble(nodes, prim_refs, triangles, bounds, params, start)
    }
}

struct Builder<'a> {
    params: BuildParams,
    triangles: &'a [[Vec3; 3]],
    max_depth: u32,
}

impl Builder<'_> {
    /// A node and its subtree, holding at most `budget` references (`REFERENCE_BUDGET`).
    fn build(&self, items: Vec<Item>, node_box: Aabb, depth: u32, budget: f64) -> BuildNode {
        let split = if depth >= self.max_depth || items.len() <= 1 {
            None
        } else {
            match self.params.method {
                SplitMethod::Sah | SplitMethod::SahExact => {
                    self.quadratic_sah_split(&items, &node_box)
                }
                SplitMethod::Center => self.spatial_split(&items, &node_box, false),
                SplitMethod::Median => self.spatial_split(&items, &node_box, true),
            }
        };
        let Some(split) = split else {
            return BuildNode::Leaf(items.iter().map(|it| it.prim).collect());
        };
        let (below_box, above_box) = node_box.split(split.axis, split.pos);
        // Children hold at most twice the node's references: only near the budget is the
        // node's own list kept, for the leaf it becomes when the split would pass it.
        let as_leaf: Option<Vec<u32>> =
            (2.0 * items.len() as f64 > budget).then(|| items.iter().map(|it| it.prim).collect());
        let (below, above) = self.partition(items, &split, &below_box, &above_box);
        let Some((below_budget, above_budget)) = share(budget, below.len(), above.len()) else {
            return BuildNode::Leaf(
                as_leaf.expect("a split past the budget holds over half of it"),
            );
        };
        let (lo, hi) = if below.len() + above.len() > PARALLEL_THRESHOLD {
            rayon::join(
                || self.build(below, below_box, depth + 1, below_budget),
                || self.build(above, above_box, depth + 1, above_budget),
            )
        } else {
            (
                self.build(below, below_box, depth + 1, below_budget),
                self.build(above, above_box, depth + 1, above_budget),
            )
        };
        BuildNode::Inner {
            split,
            below: Box::new(lo),
            above: Box::new(hi),
        }
    }

    /// The quadratic SAH search: for every candidate plane (every distinct bound of a reference,
    /// strictly inside the node) count the references on each side by looping over all of them.
    /// Candidates are visited in the order the sweep visits them (axis, then position, then
    /// planar-below before planar-above) and only a strictly cheaper one replaces the best, so
    /// both searches break ties identically.
    fn quadratic_sah_split(&self, items: &[Item], node_box: &Aabb) -> Option<Split> {
        let area = node_box.surface_area();
        if area <= 0.0 {
            return None;
        }
        let leaf_cost = self.params.intersection_cost * items.len() as f32;
        let mut best: Option<(f32, Split)> = None;
        for axis in 0..3 {
            let mut candidates: Vec<f32> = items
                .iter()
                .flat_map(|it| [it.bounds.min[axis], it.bounds.max[axis]])
                .collect();
            candidates.sort_unstable_by(f32::total_cmp);
            candidates.dedup();
            for pos in candidates {
                if !(pos > node_box.min[axis] && pos < node_box.max[axis]) {
                    continue;
                }
                let below = items.iter().filter(|it| it.bounds.min[axis] < pos).count();
                let above = items.iter().filter(|it| it.bounds.max[axis] > pos).count();
                let planar = items
                    .iter()
                    .filter(|it| it.bounds.min[axis] == pos && it.bounds.max[axis] == pos)
                    .count();
                consider_plane(
                    &mut best,
                    &self.params,
                    node_box,
                    area,
                    axis,
                    pos,
                    (below, above, planar),
                );
            }
        }
        best.filter(|(cost, _)| *cost < leaf_cost).map(|(_, s)| s)
    }

    /// Center or median split on the longest axis; `None` when the node is small enough, or when
    /// the split would not separate anything (coincident triangles).
    fn spatial_split(&self, items: &[Item], node_box: &Aabb, median: bool) -> Option<Split> {
        if items.len() <= self.params.leaf_size {
            return None;
        }
        let axis = node_box.longest_axis();
        let pos = if median {
            let mut c: Vec<f32> = items
                .iter()
                .map(|it| 0.5 * (it.bounds.min[axis] + it.bounds.max[axis]))
                .collect();
            let mid = c.len() / 2;
            let (_, m, _) = c.select_nth_unstable_by(mid, f32::total_cmp);
            *m
        } else {
            0.5 * (node_box.min[axis] + node_box.max[axis])
        };
        if !(pos > node_box.min[axis] && pos < node_box.max[axis]) {
            return None;
        }
        let below = items.iter().filter(|it| it.bounds.min[axis] < pos).count();
        let above = items.iter().filter(|it| it.bounds.max[axis] > pos).count();
        if below == items.len() && above == items.len() {
            return None;
        }
        Some(Split {
            axis,
            pos,
            planar_below: true,
        })
    }

    fn partition(
        &self,
        items: Vec<Item>,
        s: &Split,
        below_box: &Aabb,
        above_box: &Aabb,
    ) -> (Vec<Item>, Vec<Item>) {
        let mut below = Vec::new();
        let mut above = Vec::new();
        for it in items {
            match side_of(it.bounds.min[s.axis], it.bounds.max[s.axis], s) {
                Side::Below => below.push(it),
                Side::Above => above.push(it),
                Side::Both => {
                    let tri = &self.triangles[it.prim as usize];
                    let [b, a] = clip_straddler(tri, it.prim, &it.bounds, below_box, above_box);
                    below.extend(b);
                    above.extend(a);
                }
            }
        }
        (below, above)
    }
}
