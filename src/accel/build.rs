//! kd-tree construction: parameters, the node layout, and the builders. `sah` uses the
//! O(N log N) event sweep of `sah.rs`; `center` (middle of the node's longest axis) and `median`
//! (object median on that axis) use the simple recursive builder here, which also hosts the
//! quadratic SAH search the literature starts from, kept as the test oracle of the fast build.
//! Triangles that straddle a split are clipped to each child's box before their bounds are used
//! further down ("perfect splits", Havran 2000; Wald & Havran 2006).

use glam::Vec3;
use serde::{Deserialize, Serialize};
use std::time::Instant;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum SplitMethod {
    Center,
    Median,
    #[default]
    Sah,
}

/// Build constants. Defaults: K_T = 15, K_I = 20 and an empty-space factor of 0.8 (a cost
/// bonus of 0.2) as Wald & Havran (RT'06) give them and Mitsuba uses; the depth cap is pbrt-v3's
/// `8 + 1.3 log2 N`, only a safety net since the SAH termination criterion ends the recursion.
#[derive(Clone, Copy, Debug)]
pub struct BuildParams {
    pub method: SplitMethod,
    pub traversal_cost: f32,
    pub intersection_cost: f32,
    pub empty_bonus: f32,
    /// Center and median stop at this many triangles (they have no cost model).
    pub leaf_size: usize,
}

/// The SAH cost of splitting `b` at `pos` on `axis` with `nb` and `na` references on each side:
/// K_T + lambda * K_I * (P_below * nb + P_above * na), lambda = 1 - empty_bonus when a side is
/// empty. Both SAH builders call exactly this, so their costs agree bit for bit.
pub(super) fn sah_cost(
    p: &BuildParams,
    b: &Aabb,
    area: f32,
    axis: usize,
    pos: f32,
    nb: usize,
    na: usize,
) -> f32 {
    let (below, above) = b.split(axis, pos);
    let pb = below.surface_area() / area;
    let pa = above.surface_area() / area;
    let bonus = if nb == 0 || na == 0 {
        1.0 - p.empty_bonus
    } else {
        1.0
    };
    p.traversal_cost + bonus * p.intersection_cost * (pb * nb as f32 + pa * na as f32)
}

impl Default for BuildParams {
    fn default() -> Self {
        BuildParams {
            method: SplitMethod::Sah,
            traversal_cost: 15.0,
            intersection_cost: 20.0,
            empty_bonus: 0.2,
            leaf_size: 4,
        }
    }
}

impl BuildParams {
    pub fn with_method(method: SplitMethod) -> Self {
        BuildParams {
            method,
            ..Default::default()
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    pub fn of_points(points: &[Vec3]) -> Aabb {
        points.iter().fold(Aabb::EMPTY, |b, &p| Aabb {
            min: b.min.min(p),
            max: b.max.max(p),
        })
    }

    pub fn is_empty(&self) -> bool {
        !(self.min.x <= self.max.x && self.min.y <= self.max.y && self.min.z <= self.max.z)
    }

    pub fn intersection(&self, o: &Aabb) -> Aabb {
        Aabb {
            min: self.min.max(o.min),
            max: self.max.min(o.max),
        }
    }

    pub fn surface_area(&self) -> f32 {
        if self.is_empty() {
            return 0.0;
        }
        let d = self.max - self.min;
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    }

    pub fn longest_axis(&self) -> usize {
        let d = self.max - self.min;
        if d.x >= d.y && d.x >= d.z {
            0
        } else if d.y >= d.z {
            1
        } else {
            2
        }
    }

    /// Parametric interval `(t0, t1)` of a ray inside the box, clipped to `(0, t_max)`; `None`
    /// when it misses. Zero direction components are tested explicitly rather than through
    /// inf/NaN arithmetic.
    pub fn clip_ray(&self, ray: &super::Ray, t_max: f32) -> Option<(f32, f32)> {
        let (mut t0, mut t1) = (0.0f32, t_max);
        for axis in 0..3 {
            let (o, d) = (ray.origin[axis], ray.dir[axis]);
            let (lo, hi) = (self.min[axis], self.max[axis]);
            if d == 0.0 {
                if o < lo || o > hi {
                    return None;
                }
                continue;
            }
            let inv = 1.0 / d;
            let (mut near, mut far) = ((lo - o) * inv, (hi - o) * inv);
            if near > far {
                std::mem::swap(&mut near, &mut far);
            }
            t0 = t0.max(near);
            t1 = t1.min(far);
            if t0 > t1 {
                return None;
            }
        }
        Some((t0, t1))
    }

    /// The two halves of the box cut at `pos` on `axis`.
    pub fn split(&self, axis: usize, pos: f32) -> (Aabb, Aabb) {
        let mut below = *self;
        let mut above = *self;
        below.max[axis] = pos;
        above.min[axis] = pos;
        (below, above)
    }
}

/// A kd-tree node in 8 bytes: two nodes per 16 bytes, four per cache line, which is what
/// traversal spends its time loading (pbrt-v3's KdAccelNode makes the same choice).
/// Inner: `a` = split position (f32 bits), `b` = (offset of the above child from this node) << 2 | axis.
/// The below child always follows its parent directly.
/// Leaf: `a` = first index into the primitive-reference array, `b` = count << 2 | 3.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C)]
pub struct Node {
    a: u32,
    b: u32,
}

const _: () = assert!(std::mem::size_of::<Node>() == 8);

impl Node {
    pub(super) fn leaf(first: u32, count: u32) -> Node {
        Node {
            a: first,
            b: (count << 2) | 3,
        }
    }

    pub(super) fn inner(axis: usize, split: f32, above_offset: u32) -> Node {
        Node {
            a: split.to_bits(),
            b: (above_offset << 2) | axis as u32,
        }
    }

    #[inline]
    pub fn is_leaf(&self) -> bool {
        self.b & 3 == 3
    }

    #[inline]
    pub fn axis(&self) -> usize {
        (self.b & 3) as usize
    }

    #[inline]
    pub fn split(&self) -> f32 {
        f32::from_bits(self.a)
    }

    #[inline]
    pub fn above_offset(&self) -> usize {
        (self.b >> 2) as usize
    }

    #[inline]
    pub fn leaf_range(&self) -> std::ops::Range<usize> {
        let first = self.a as usize;
        first..first + (self.b >> 2) as usize
    }
}

pub struct KdTree {
    pub(super) nodes: Vec<Node>,
    pub(super) prim_refs: Vec<u32>,
    pub(super) triangles: Vec<[Vec3; 3]>,
    pub(super) bounds: Aabb,
    pub params: BuildParams,
    pub build_seconds: f64,
}

/// A triangle reference during the build with its bounds clipped to the current node.
#[derive(Clone, Copy, Debug)]
pub(super) struct Item {
    pub prim: u32,
    pub bounds: Aabb,
}

/// The tree as the builders make it; flattened once into the compact layout.
pub(super) enum BuildNode {
    Leaf(Vec<u32>),
    Inner {
        split: Split,
        below: Box<BuildNode>,
        above: Box<BuildNode>,
    },
}

/// A chosen split: axis, position, and which side triangles lying in the plane go to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Split {
    pub axis: usize,
    pub pos: f32,
    pub planar_below: bool,
}

/// Subtrees with more references than this are built on another rayon task.
pub(super) const PARALLEL_THRESHOLD: usize = 4096;
/// Hard cap so the traversal stack (one entry per level) has a fixed size.
pub const MAX_DEPTH: u32 = 60;

/// Which side of a split a reference goes to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Side {
    Below,
    Above,
    Both,
}

/// The side of a reference with bounds `[lo, hi]` on the split axis (the same rule for every builder).
#[inline]
pub(super) fn side_of(lo: f32, hi: f32, s: &Split) -> Side {
    if lo == hi && lo == s.pos {
        if s.planar_below {
            Side::Below
        } else {
            Side::Above
        }
    } else if hi <= s.pos {
        Side::Below
    } else if lo >= s.pos {
        Side::Above
    } else {
        Side::Both
    }
}

/// The two clipped references of a triangle straddling a split (either may vanish).
pub(super) fn clip_straddler(
    tri: &[Vec3; 3],
    prim: u32,
    bounds: &Aabb,
    below_box: &Aabb,
    above_box: &Aabb,
) -> [Option<Item>; 2] {
    [below_box, above_box].map(|child| {
        let b = clip_bounds(tri, &bounds.intersection(child));
        (!b.is_empty()).then_some(Item { prim, bounds: b })
    })
}

/// Evaluates a candidate plane with `below`/`above` references strictly on each side and
/// `planar` lying in it, planar ones on either side, and keeps it if strictly cheaper than
/// `best`. Both SAH searches call this in the same candidate order, so ties break identically.
#[allow(clippy::too_many_arguments)]
pub(super) fn consider_plane(
    best: &mut Option<(f32, Split)>,
    p: &BuildParams,
    node_box: &Aabb,
    area: f32,
    axis: usize,
    pos: f32,
    (below, above, planar): (usize, usize, usize),
) {
    for planar_below in [true, false] {
        let (nb, na) = if planar_below {
            (below + planar, above)
        } else {
            (below, above + planar)
        };
        let cost = sah_cost(p, node_box, area, axis, pos, nb, na);
        if best.is_none_or(|(c, _)| cost < c) {
            *best = Some((
                cost,
                Split {
                    axis,
                    pos,
                    planar_below,
                },
            ));
        }
    }
}

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
        let bounds = items.iter().fold(Aabb::EMPTY, |acc, it| Aabb {
            min: acc.min.min(it.bounds.min),
            max: acc.max.max(it.bounds.max),
        });
        let n = items.len().max(1) as f32;
        let max_depth = ((8.0 + 1.3 * n.log2()).round() as u32).min(MAX_DEPTH);
        let root = if params.method == SplitMethod::Sah && !quadratic {
            super::sah::build(&triangles, items, bounds, &params, max_depth)
        } else {
            let builder = Builder {
                params,
                triangles: &triangles,
                max_depth,
            };
            builder.build(items, bounds, 0)
        };
        let (nodes, prim_refs) = flatten(root);
        KdTree {
            nodes,
            prim_refs,
            triangles,
            bounds,
            params,
            build_seconds: start.elapsed().as_secs_f64(),
        }
    }

    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// The tree's inner nodes and leaves in layout order, for comparing trees in tests: inner
    /// nodes as (axis, split, above offset), leaves as their sorted primitive lists.
    pub fn shape(&self) -> Vec<(usize, f32, usize, Vec<u32>)> {
        self.nodes
            .iter()
            .map(|n| {
                if n.is_leaf() {
                    let mut prims = self.prim_refs[n.leaf_range()].to_vec();
                    prims.sort_unstable();
                    (3, 0.0, 0, prims)
                } else {
                    (n.axis(), n.split(), n.above_offset(), Vec::new())
                }
            })
            .collect()
    }
}

/// Depth-first layout: the below child follows its parent, the above child's offset is stored.
fn flatten(root: BuildNode) -> (Vec<Node>, Vec<u32>) {
    let mut nodes = Vec::new();
    let mut refs = Vec::new();
    // (node, index of the parent whose above-offset waits for this node)
    let mut stack: Vec<(BuildNode, Option<usize>)> = vec![(root, None)];
    while let Some((node, parent)) = stack.pop() {
        let here = nodes.len();
        if let Some(p) = parent {
            let Node { a, .. } = nodes[p];
            let axis = nodes[p].axis();
            nodes[p] = Node::inner(axis, f32::from_bits(a), (here - p) as u32);
        }
        match node {
            BuildNode::Leaf(prims) => {
                nodes.push(Node::leaf(refs.len() as u32, prims.len() as u32));
                refs.extend(prims);
            }
            BuildNode::Inner {
                split,
                below,
                above,
            } => {
                nodes.push(Node::inner(split.axis, split.pos, 0));
                stack.push((*above, Some(here)));
                stack.push((*below, None));
            }
        }
    }
    (nodes, refs)
}

struct Builder<'a> {
    params: BuildParams,
    triangles: &'a [[Vec3; 3]],
    max_depth: u32,
}

impl Builder<'_> {
    fn build(&self, items: Vec<Item>, node_box: Aabb, depth: u32) -> BuildNode {
        let split = if depth >= self.max_depth || items.len() <= 1 {
            None
        } else {
            match self.params.method {
                SplitMethod::Sah => self.quadratic_sah_split(&items, &node_box),
                SplitMethod::Center => self.spatial_split(&items, &node_box, false),
                SplitMethod::Median => self.spatial_split(&items, &node_box, true),
            }
        };
        let Some(split) = split else {
            return BuildNode::Leaf(items.iter().map(|it| it.prim).collect());
        };
        let (below_box, above_box) = node_box.split(split.axis, split.pos);
        let (below, above) = self.partition(items, &split, &below_box, &above_box);
        let (lo, hi) = if below.len() + above.len() > PARALLEL_THRESHOLD {
            rayon::join(
                || self.build(below, below_box, depth + 1),
                || self.build(above, above_box, depth + 1),
            )
        } else {
            (
                self.build(below, below_box, depth + 1),
                self.build(above, above_box, depth + 1),
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

/// Bounds of the part of a triangle inside `b` (Sutherland-Hodgman against the six planes). The
/// result is intersected with `b` again so float error can only shrink it toward the box; when
/// clipping loses the triangle entirely through rounding, the box itself is kept (conservative).
fn clip_bounds(tri: &[Vec3; 3], b: &Aabb) -> Aabb {
    if b.is_empty() {
        return Aabb::EMPTY;
    }
    // A triangle clipped by six planes has at most nine vertices: fixed arrays, no allocation.
    let mut poly = [Vec3::ZERO; 9];
    let mut next = [Vec3::ZERO; 9];
    poly[..3].copy_from_slice(tri);
    let mut len = 3;
    for axis in 0..3 {
        for (plane, keep_above) in [(b.min[axis], true), (b.max[axis], false)] {
            let inside = |v: Vec3| {
                if keep_above {
                    v[axis] >= plane
                } else {
                    v[axis] <= plane
                }
            };
            let mut out = 0;
            for i in 0..len {
                let p = poly[i];
                let q = poly[(i + 1) % len];
                if inside(p) {
                    next[out] = p;
                    out += 1;
                }
                if inside(p) != inside(q) && out < 9 {
                    let t = (plane - p[axis]) / (q[axis] - p[axis]);
                    let mut v = p + (q - p) * t;
                    v[axis] = plane;
                    next[out] = v;
                    out += 1;
                }
            }
            std::mem::swap(&mut poly, &mut next);
            len = out;
            if len == 0 {
                return *b;
            }
        }
    }
    Aabb::of_points(&poly[..len]).intersection(b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clipping_a_triangle_to_a_box_shrinks_its_bounds() {
        let tri = [
            Vec3::ZERO,
            Vec3::new(4.0, 0.0, 0.0),
            Vec3::new(0.0, 4.0, 0.0),
        ];
        let b = Aabb {
            min: Vec3::new(3.0, -1.0, -1.0),
            max: Vec3::new(5.0, 5.0, 1.0),
        };
        let c = clip_bounds(&tri, &b);
        assert_eq!(c.min.x, 3.0);
        assert!((c.max.y - 1.0).abs() < 1e-6, "{c:?}");
    }

    #[test]
    fn node_packs_leaf_and_inner_fields() {
        let l = Node::leaf(7, 3);
        assert!(l.is_leaf());
        assert_eq!(l.leaf_range(), 7..10);
        let i = Node::inner(2, 1.5, 42);
        assert!(!i.is_leaf());
        assert_eq!((i.axis(), i.split(), i.above_offset()), (2, 1.5, 42));
    }
}
