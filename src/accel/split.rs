//! The split rules every kd-tree builder shares: the SAH cost of a candidate plane, which side
//! of a plane a reference goes to, how a straddling triangle is clipped into each child ("perfect
//! splits", Havran 2000; Wald & Havran 2006), and the tree shape the builders hand to the layout.

use super::aabb::Aabb;
use super::params::BuildParams;
use glam::Vec3;

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

/// References the whole tree may hold, per triangle. Perfect splits copy a straddling triangle
/// into both children; on ordinary meshes that gives 3-6 references per triangle (the ladder of
/// docs/bench/kdtree.md), but a pile of overlapping triangles (the same sprite placed a
/// thousand times a millimetre apart) is split again and again and grew to 300 MB for 1,000
/// triangles and 8 GB for 5,000. Each node hands its budget to its children in proportion to
/// their references and becomes a leaf when its split would hold more than its budget, so the
/// tree holds at most this many references per triangle whatever the input, and the rule is the
/// same on every thread count. Every clipping builder follows it (`binned.rs`, `sah.rs`, `build.rs`). 64 is over ten times what the ladder's meshes use, so they build as before.
pub(super) const REFERENCE_BUDGET: f64 = 64.0;

/// The children's budgets, in proportion to their references, or `None` when the two children
/// together would hold more references than the node's budget allows (the node stays a leaf).
pub(super) fn share(budget: f64, below: usize, above: usize) -> Option<(f64, f64)> {
    let total = (below + above) as f64;
    (total <= budget).then(|| {
        let per_reference = budget / total;
        (per_reference * below as f64, per_reference * above as f64)
    })
}
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
        keep(best, cost, axis, pos, planar_below);
    }
}

/// Keeps `(cost, split)` if strictly cheaper than the best so far (so ties go to the first
/// candidate in visiting order, a rule that does not depend on threads).
#[inline]
pub(super) fn keep(
    best: &mut Option<(f32, Split)>,
    cost: f32,
    axis: usize,
    pos: f32,
    planar_below: bool,
) {
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

/// Bounds of the part of a triangle inside `b` (Sutherland-Hodgman against the six planes). The
/// result is intersected with `b` again so float error can only shrink it toward the box; when
/// clipping loses the triangle entirely through rounding, the box itself is kept (conservative).
pub(super) fn clip_bounds(tri: &[Vec3; 3], b: &Aabb) -> Aabb {
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
}
