//! The SAH cost of candidate planes on one axis of one node, from constants computed once per
//! node and axis. Shared by the binned build's binned sweep,
//! its refinement and its exact search of small nodes (`binned.rs`, `small_split.rs`), so their
//! costs agree bit for bit with each other.

use super::aabb::Aabb;
use super::lanes::F4;
use super::params::BuildParams;

/// A plane at offset `l` from the node's lower face gives a below child of area
/// 2 (e1 e2 + l (e1 + e2)) for the other two extents e1, e2, so each candidate costs two
/// multiply-adds (no division, no box).
#[derive(Clone, Copy)]
pub(super) struct AxisCost {
    pub e1e2: f32,
    pub e1_plus_e2: f32,
    pub extent: f32,
    /// 2 K_I / node area.
    pub scale: f32,
    pub traversal: f32,
    pub empty_factor: f32,
}

impl AxisCost {
    /// The three axes' constants of one node, its area and the division computed once (a
    /// node's search asks for all three, its refinement for one again).
    pub fn per_axis(p: &BuildParams, b: &Aabb) -> [AxisCost; 3] {
        let d = (b.max - b.min).to_array();
        let scale = 2.0 * p.intersection_cost / b.surface_area();
        let axis_cost = |axis: usize| {
            let (e1, e2) = (d[(axis + 1) % 3], d[(axis + 2) % 3]);
            AxisCost {
                e1e2: e1 * e2,
                e1_plus_e2: e1 + e2,
                extent: d[axis],
                scale,
                traversal: p.traversal_cost,
                empty_factor: 1.0 - p.empty_bonus,
            }
        };
        [axis_cost(0), axis_cost(1), axis_cost(2)]
    }

    /// Counts as `u32`: one instruction each to convert (a `usize` takes a sign test too).
    #[inline]
    pub fn cost(&self, l: f32, nb: u32, na: u32) -> f32 {
        let below = self.e1e2 + self.e1_plus_e2 * l;
        let above = self.e1e2 + self.e1_plus_e2 * (self.extent - l);
        let bonus = if nb == 0 || na == 0 {
            self.empty_factor
        } else {
            1.0
        };
        self.traversal + bonus * self.scale * (below * nb as f32 + above * na as f32)
    }

    /// `cost` for four planes at once, with the counts as floats (exact below 2^24), by the
    /// same operations in the same order, so each lane is bit for bit `cost`'s result.
    #[inline(always)]
    pub fn cost4(&self, l: F4, nb: F4, na: F4) -> F4 {
        let e1e2 = F4::splat(self.e1e2);
        let e1_plus_e2 = F4::splat(self.e1_plus_e2);
        let below = e1e2.add(e1_plus_e2.mul(l));
        let above = e1e2.add(e1_plus_e2.mul(F4::splat(self.extent).sub(l)));
        let zero = F4::splat(0.0);
        let empty = nb.eq(zero).or(na.eq(zero));
        let bonus = F4::select(empty, F4::splat(self.empty_factor), F4::splat(1.0));
        let scaled = bonus.mul(F4::splat(self.scale));
        F4::splat(self.traversal).add(scaled.mul(below.mul(nb).add(above.mul(na))))
    }
}

/// The three axes' `AxisCost` as lanes 0-2 of one `F4` each (lane 3 is zero and ignored by
/// its users): the bin boundaries of all three axes costed at once.
pub(super) struct AxesCost {
    e1e2: F4,
    e1_plus_e2: F4,
    extent: F4,
    scale: F4,
    traversal: F4,
    empty_factor: F4,
}

impl AxesCost {
    pub fn new(axes: &[AxisCost; 3]) -> AxesCost {
        // Written out: an array `map` here was a call per field (3% of a one-thread build).
        let lanes = |f: fn(&AxisCost) -> f32| F4::new([f(&axes[0]), f(&axes[1]), f(&axes[2]), 0.0]);
        AxesCost {
            e1e2: lanes(|c| c.e1e2),
            e1_plus_e2: lanes(|c| c.e1_plus_e2),
            extent: lanes(|c| c.extent),
            scale: lanes(|c| c.scale),
            traversal: lanes(|c| c.traversal),
            empty_factor: lanes(|c| c.empty_factor),
        }
    }

    /// Lane `a` is `AxisCost::cost4` of axis `a`: the same operations in the same order.
    #[inline(always)]
    pub fn cost(&self, l: F4, nb: F4, na: F4) -> F4 {
        let below = self.e1e2.add(self.e1_plus_e2.mul(l));
        let above = self.e1e2.add(self.e1_plus_e2.mul(self.extent.sub(l)));
        let zero = F4::splat(0.0);
        let empty = nb.eq(zero).or(na.eq(zero));
        let bonus = F4::select(empty, self.empty_factor, F4::splat(1.0));
        let scaled = bonus.mul(self.scale);
        self.traversal
            .add(scaled.mul(below.mul(nb).add(above.mul(na))))
    }
}
