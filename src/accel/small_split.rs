//! The exact split search of the binned build's small nodes: every reference bound strictly
//! inside the node is a candidate plane, with the counts of the exact event sweep (references
//! reaching below, above, and lying in the plane), counted by brute force.
//!
//! Four candidates share each instruction: a node's lower bounds on an axis are one to three
//! groups of four lanes, its upper bounds as many, and each reference is compared against a
//! whole group at once, counting in floats (exact for at most `EXACT_MAX`) since the cost wants
//! floats. The costs use the operations of `AxisCost::cost` in its order, and the cheapest is
//! then kept by scanning the candidates in the order the one-at-a-time search visited them, so
//! the chosen plane is bit for bit the same (the test below holds both searches to it).

use super::aabb::Aabb;
use super::bins::Ref;
use super::lanes::F4;
use super::params::BuildParams;
use super::plane_cost::AxisCost;
use super::split::{Split, keep};

/// At or below this many references a node tries every reference bound as a plane; above, it
/// bins. Measured with the four-lane search on the 1M peer mesh, 1 thread, alternating runs:
/// 4, 6 and 8 built in 0.84-0.85 s (SAH cost 409.81, 1.157-1.158M nodes), 12 in 0.89-0.91 s
/// (409.82, 1.168M), 16 in 0.97-0.98 s and 20 in 1.02 s; traversal the same with 8 and 12.
pub(super) const EXACT_MAX: usize = 8;

/// The cheapest plane of a node of at most `EXACT_MAX` references and its cost, if any
/// candidate lies strictly inside the node.
pub(super) fn exact_split(
    params: &BuildParams,
    refs: &[Ref],
    node_box: &Aabb,
) -> Option<(f32, Split)> {
    // One group of four lanes up to four references (most small nodes hold two to five).
    const _: () = assert!(EXACT_MAX <= 8);
    if refs.len() <= 4 {
        search::<1>(params, refs, node_box)
    } else {
        search::<2>(params, refs, node_box)
    }
}

/// `search` over `GROUPS` groups of four lanes per bound kind (lower, upper).
// Kept out of line: inlined into the build's node loop it made the build slower (measured, 1
// thread, 1M peer mesh).
#[inline(never)]
fn search<const GROUPS: usize>(
    params: &BuildParams,
    refs: &[Ref],
    node_box: &Aabb,
) -> Option<(f32, Split)> {
    let (zero, one) = (F4::splat(0.0), F4::splat(1.0));
    let mut best = None;
    let costs = AxisCost::per_axis(params, node_box);
    for (axis, cost) in costs.iter().enumerate() {
        let (min, max) = (node_box.min[axis], node_box.max[axis]);
        if max <= min {
            continue;
        }
        // Padding is never a candidate: infinities lie strictly inside no node.
        let mut bounds = [
            [[f32::INFINITY; 4]; GROUPS],
            [[f32::NEG_INFINITY; 4]; GROUPS],
        ];
        for (i, r) in refs.iter().enumerate() {
            bounds[0][i / 4][i % 4] = r.lo[axis];
            bounds[1][i / 4][i % 4] = r.hi[axis];
        }
        for kind in &bounds {
            for group in kind {
                let pos = F4::new(*group);
                let (mut below, mut above, mut planar) = (zero, zero, zero);
                for r in refs {
                    let (lo, hi) = (F4::splat(r.lo[axis]), F4::splat(r.hi[axis]));
                    below = below.add(F4::select(lo.lt(pos), one, zero));
                    above = above.add(F4::select(hi.gt(pos), one, zero));
                    let in_plane = lo.eq(pos).and(hi.eq(pos));
                    planar = planar.add(F4::select(in_plane, one, zero));
                }
                let inside = pos.gt(F4::splat(min)).and(pos.lt(F4::splat(max))).bits();
                if inside == 0 {
                    continue;
                }
                let l = pos.sub(F4::splat(min));
                let planar_below = cost.cost4(l, below.add(planar), above).to_array();
                let planar_above = cost.cost4(l, below, above.add(planar)).to_array();
                let has_planar = planar.gt(zero).bits();
                for k in 0..4 {
                    if inside >> k & 1 == 1 {
                        keep(&mut best, planar_below[k], axis, group[k], true);
                        if has_planar >> k & 1 == 1 {
                            keep(&mut best, planar_above[k], axis, group[k], false);
                        }
                    }
                }
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::test_rng::Lcg;

    /// The one-candidate-at-a-time search the lanes replace, as it was.
    fn scalar_search(p: &BuildParams, refs: &[Ref], node_box: &Aabb) -> Option<(f32, Split)> {
        let mut best = None;
        for axis in 0..3 {
            let (min, max) = (node_box.min[axis], node_box.max[axis]);
            if max <= min {
                continue;
            }
            let cost = AxisCost::per_axis(p, node_box)[axis];
            let candidates = refs.iter().map(|r| r.lo[axis]);
            for pos in candidates.chain(refs.iter().map(|r| r.hi[axis])) {
                if !(pos > min && pos < max) {
                    continue;
                }
                let below = refs.iter().filter(|r| r.lo[axis] < pos).count() as u32;
                let above = refs.iter().filter(|r| r.hi[axis] > pos).count() as u32;
                let planar = refs
                    .iter()
                    .filter(|r| r.lo[axis] == pos && r.hi[axis] == pos)
                    .count() as u32;
                let l = pos - min;
                keep(
                    &mut best,
                    cost.cost(l, below + planar, above),
                    axis,
                    pos,
                    true,
                );
                if planar > 0 {
                    keep(
                        &mut best,
                        cost.cost(l, below, above + planar),
                        axis,
                        pos,
                        false,
                    );
                }
            }
        }
        best
    }

    #[test]
    fn lanes_choose_the_plane_the_scalar_search_chooses() {
        let p = BuildParams::default();
        let mut rng = Lcg(7);
        let mut splits = 0;
        for case in 0..20_000 {
            let n = 1 + case % EXACT_MAX;
            // Coordinates on a coarse grid, so that bounds coincide, references lie in planes
            // and candidates tie in cost.
            let mut grid = |_| (rng.next() * 8.0).floor() / 4.0;
            let refs: Vec<Ref> = (0..n)
                .map(|i| {
                    let (a, b) = ([0; 3].map(&mut grid), [0; 3].map(&mut grid));
                    Ref {
                        lo: std::array::from_fn(|k| a[k].min(b[k])),
                        hi: std::array::from_fn(|k| a[k].max(b[k])),
                        prim: i as u32,
                    }
                })
                .collect();
            let corners: Vec<glam::Vec3> = refs
                .iter()
                .flat_map(|r| [r.lo.into(), r.hi.into()])
                .collect();
            let node_box = Aabb::of_points(&corners);
            let (want, got) = (
                scalar_search(&p, &refs, &node_box),
                exact_split(&p, &refs, &node_box),
            );
            assert_eq!(
                want.map(|(c, s)| (c.to_bits(), s)),
                got.map(|(c, s)| (c.to_bits(), s)),
                "case {case}: {refs:?}"
            );
            splits += got.is_some() as usize;
        }
        assert!(splits > 15_000, "too few nodes had a candidate: {splits}");
    }
}
