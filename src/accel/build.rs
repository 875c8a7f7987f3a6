//! kd-tree construction. Three split strategies share one recursive builder: `center` (middle of the
//! node's longest axis), `median` (object median on that axis) and `sah` (the surface area
//! heuristic with an exact sweep over the split candidates). Triangles that straddle a split are
//! clipped to each child's box before their bounds are used further down ("perfect splits",
//! Havran 2000; Wald & Havran 2006), which keeps deep nodes tight around long triangles.

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
    fn leaf(first: u32, count: u32) -> Node {
        Node {
            a: first,
            b: (count << 2) | 3,
        }
    }

    fn inner(axis: usize, split: f32, above_offset: u32) -> Node {
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
#[derive(Clone, Copy)]
struct Item {
    prim: u32,
    bounds: Aabb,
}

struct Subtree {
    nodes: Vec<Node>,
    refs: Vec<u32>,
}

/// Subtrees with more references than this are built on another rayon task.
const PARALLEL_THRESHOLD: usize = 4096;
/// Hard cap so the traversal stack (one entry per level) has a fixed size.
pub const MAX_DEPTH: u32 = 60;

impl KdTree {
    pub fn build(triangles: Vec<[Vec3; 3]>, params: BuildParams) -> KdTree {
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
        let builder = Builder {
            params,
            triangles: &triangles,
            max_depth,
        };
        let sub = builder.build(items, bounds, 0);
        KdTree {
            nodes: sub.nodes,
            prim_refs: sub.refs,
            triangles,
            bounds,
            params,
            build_seconds: start.elapsed().as_secs_f64(),
        }
    }

    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }
}

struct Builder<'a> {
    params: BuildParams,
    triangles: &'a [[Vec3; 3]],
    max_depth: u32,
}

/// A chosen split: axis, position, and which side triangles lying in the plane go to.
#[derive(Clone, Copy, Debug)]
struct Split {
    axis: usize,
    pos: f32,
    planar_below: bool,
}

impl Builder<'_> {
    fn build(&self, items: Vec<Item>, node_box: Aabb, depth: u32) -> Subtree {
        let split = if depth >= self.max_depth || items.len() <= 1 {
            None
        } else {
            match self.params.method {
                SplitMethod::Sah => self.sah_split(&items, &node_box),
                SplitMethod::Center => self.spatial_split(&items, &node_box, false),
                SplitMethod::Median => self.spatial_split(&items, &node_box, true),
            }
        };
        let Some(split) = split else {
            return leaf(items);
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
        let mut nodes = Vec::with_capacity(1 + lo.nodes.len() + hi.nodes.len());
        nodes.push(Node::inner(
            split.axis,
            split.pos,
            1 + lo.nodes.len() as u32,
        ));
        nodes.extend_from_slice(&lo.nodes);
        let shift = lo.refs.len() as u32;
        nodes.extend(hi.nodes.iter().map(|n| {
            if n.is_leaf() {
                Node {
                    a: n.a + shift,
                    b: n.b,
                }
            } else {
                *n
            }
        }));
        let mut refs = lo.refs;
        refs.extend_from_slice(&hi.refs);
        Subtree { nodes, refs }
    }

    /// The cheapest SAH split over all three axes, or `None` when a leaf is cheaper.
    fn sah_split(&self, items: &[Item], node_box: &Aabb) -> Option<Split> {
        let area = node_box.surface_area();
        if area <= 0.0 {
            return None;
        }
        let n = items.len();
        let leaf_cost = self.params.intersection_cost * n as f32;
        let mut best: Option<(f32, Split)> = None;
        // Event kinds sort as end < planar < start at equal positions (Wald & Havran's order), so
        // a sweep sees the triangles ending at a plane before those starting there.
        let mut events: Vec<(f32, u8)> = Vec::with_capacity(2 * n);
        for axis in 0..3 {
            events.clear();
            for it in items {
                let (lo, hi) = (it.bounds.min[axis], it.bounds.max[axis]);
                if lo == hi {
                    events.push((lo, 1));
                } else {
                    events.push((lo, 2));
                    events.push((hi, 0));
                }
            }
            events.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            let (mut n_below, mut n_above) = (0usize, n);
            let mut i = 0;
            while i < events.len() {
                let pos = events[i].0;
                let count = |kind: u8, i: &mut usize| {
                    let mut c = 0;
                    while *i < events.len() && events[*i].0 == pos && events[*i].1 == kind {
                        c += 1;
                        *i += 1;
                    }
                    c
                };
                let ending = count(0, &mut i);
                let planar = count(1, &mut i);
                let starting = count(2, &mut i);
                n_above -= planar + ending;
                if pos > node_box.min[axis] && pos < node_box.max[axis] {
                    for planar_below in [true, false] {
                        let (nb, na) = if planar_below {
                            (n_below + planar, n_above)
                        } else {
                            (n_below, n_above + planar)
                        };
                        let cost = self.sah_cost(node_box, area, axis, pos, nb, na);
                        if best.is_none_or(|(c, _)| cost < c) {
                            best = Some((
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
                n_below += starting + planar;
            }
        }
        best.filter(|(cost, _)| *cost < leaf_cost).map(|(_, s)| s)
    }

    fn sah_cost(&self, b: &Aabb, area: f32, axis: usize, pos: f32, nb: usize, na: usize) -> f32 {
        let (below, above) = b.split(axis, pos);
        let pb = below.surface_area() / area;
        let pa = above.surface_area() / area;
        let bonus = if nb == 0 || na == 0 {
            1.0 - self.params.empty_bonus
        } else {
            1.0
        };
        self.params.traversal_cost
            + bonus * self.params.intersection_cost * (pb * nb as f32 + pa * na as f32)
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
            let (lo, hi) = (it.bounds.min[s.axis], it.bounds.max[s.axis]);
            if lo == hi && lo == s.pos {
                if s.planar_below {
                    below.push(it);
                } else {
                    above.push(it);
                }
            } else if hi <= s.pos {
                below.push(it);
            } else if lo >= s.pos {
                above.push(it);
            } else {
                let tri = &self.triangles[it.prim as usize];
                for (child_box, out) in [(below_box, &mut below), (above_box, &mut above)] {
                    let clipped = clip_bounds(tri, &it.bounds.intersection(child_box));
                    if !clipped.is_empty() {
                        out.push(Item {
                            prim: it.prim,
                            bounds: clipped,
                        });
                    }
                }
            }
        }
        (below, above)
    }
}

fn leaf(items: Vec<Item>) -> Subtree {
    Subtree {
        nodes: vec![Node::leaf(0, items.len() as u32)],
        refs: items.iter().map(|it| it.prim).collect(),
    }
}

/// Bounds of the part of a triangle inside `b` (Sutherland-Hodgman against the six planes). The
/// result is intersected with `b` again so float error can only shrink it toward the box; when
/// clipping loses the triangle entirely through rounding, the box itself is kept (conservative).
fn clip_bounds(tri: &[Vec3; 3], b: &Aabb) -> Aabb {
    if b.is_empty() {
        return Aabb::EMPTY;
    }
    let mut poly: Vec<Vec3> = tri.to_vec();
    let mut next = Vec::with_capacity(9);
    for axis in 0..3 {
        for (plane, keep_above) in [(b.min[axis], true), (b.max[axis], false)] {
            next.clear();
            for i in 0..poly.len() {
                let p = poly[i];
                let q = poly[(i + 1) % poly.len()];
                let inside = |v: Vec3| {
                    if keep_above {
                        v[axis] >= plane
                    } else {
                        v[axis] <= plane
                    }
                };
                if inside(p) {
                    next.push(p);
                }
                if inside(p) != inside(q) {
                    let t = (plane - p[axis]) / (q[axis] - p[axis]);
                    let mut v = p + (q - p) * t;
                    v[axis] = plane;
                    next.push(v);
                }
            }
            std::mem::swap(&mut poly, &mut next);
            if poly.is_empty() {
                return *b;
            }
        }
    }
    Aabb::of_points(&poly).intersection(b)
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
