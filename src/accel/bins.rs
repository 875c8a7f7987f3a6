//! Min-max binning for the kd-tree build of `binned.rs`: the references a node holds, the grid of
//! equal bins over the node's box, and per-axis counts of the bins the references' lower and upper
//! bounds fall in (Shevtsov et al. 2007; Mitsuba 0.6's `gkdtree.h` calls it min-max binning).

use super::aabb::Aabb;
use super::lanes::F4;
use super::plane_cost::AxesCost;
use std::cell::RefCell;

/// The part of one triangle inside the current node, by its bounds (arrays, not `Vec3`, so the
/// per-axis loops index without glam's checked `match`).
#[derive(Clone, Copy, Debug)]
pub(super) struct Ref {
    pub lo: [f32; 3],
    pub hi: [f32; 3],
    pub prim: u32,
}

/// The bins of one node: `count` equal slices of the node box on each axis.
pub(super) struct Grid {
    pub count: usize,
    pub origin: [f32; 3],
    pub extent: [f32; 3],
    inv_width: [f32; 3],
    /// `origin`, `inv_width` and the last bin as lanes (the fourth lane bins a zero to bin 0).
    pub origin4: F4,
    inv_width4: F4,
    last4: F4,
}

impl Grid {
    pub fn new(node_box: &Aabb, count: usize) -> Grid {
        let extent = (node_box.max - node_box.min).to_array();
        let origin = node_box.min.to_array();
        let inv_width = extent.map(|e| if e > 0.0 { count as f32 / e } else { 0.0 });
        Grid {
            count,
            origin,
            extent,
            inv_width,
            origin4: F4::xyz(origin),
            inv_width4: F4::xyz(inv_width),
            last4: F4::splat((count - 1) as f32),
        }
    }

    /// The bin rule, before the conversion to an index: coordinate `x` on `axis` in bin widths
    /// from the node's lower face, clamped to the bins (below the lower face and NaN to the
    /// first, the upper face and beyond to the last). A coordinate's bin is this value rounded
    /// down. Counting (`bins3`, the same operations three axes at a time) and refinement
    /// (`in_pair`) both bin by it.
    #[inline]
    fn position(&self, x: f32, axis: usize) -> f32 {
        let b = ((x - self.origin[axis]) * self.inv_width[axis]).max(0.0);
        b.min((self.count - 1) as f32)
    }

    /// Whether `x` falls in bin `first` or `first + 1` of `axis`, by comparing its position
    /// (cheaper than converting it to an index); the rule `pair_range` is held to.
    #[cfg(test)]
    pub fn in_pair(&self, x: f32, axis: usize, first: usize) -> bool {
        let b = self.position(x, axis);
        b >= first as f32 && b < (first + 2) as f32
    }

    /// The coordinates of `axis` in bins `first` and `first + 1`, as a half-open range
    /// `[from, to)`: a finite `x` is in it exactly when `in_pair(x, axis, first)`. Two
    /// comparisons a coordinate instead of the bin rule's four operations and two comparisons
    /// (the refinement tests both bounds of every reference of a node).
    pub fn pair_range(&self, axis: usize, first: usize) -> (f32, f32) {
        let from = if first == 0 {
            f32::NEG_INFINITY
        } else {
            self.bin_start(axis, first)
        };
        let to = if first + 2 >= self.count {
            f32::INFINITY
        } else {
            self.bin_start(axis, first + 2)
        };
        (from, to)
    }

    /// Where boundary `k` of `axis` lies before rounding: the plane the binned search names
    /// (the boundary sweep's lanes compute the same expression).
    pub fn boundary(&self, axis: usize, k: usize) -> f32 {
        self.origin[axis] + k as f32 * (self.extent[axis] / self.count as f32)
    }

    /// The smallest coordinate of `axis` in bin `k` or above, for `k` in `1..count`. The bin
    /// rule is monotone in `x` (a subtraction and a multiplication by a positive constant, each
    /// rounded, then a clamp), so the boundary is searched for among the floats in their order:
    /// from the unrounded boundary, steps doubling until they pass it, then halving. Near zero
    /// the floats are so dense that the rounding's few bin widths are billions of floats: one
    /// float a step took seconds a node there (MetalRoughSpheres' 1M triangles: 23 s a build).
    fn bin_start(&self, axis: usize, k: usize) -> f32 {
        if self.inv_width[axis] == 0.0 {
            // A flat axis bins everything to 0.
            return f32::INFINITY;
        }
        let guess = self.boundary(axis, k);
        let k = k as f32;
        let reaches = |key: u32| self.position(from_order(key), axis) >= k;
        from_order(first_reaching(reaches, to_order(guess)))
    }

    /// The bins of a point's three coordinates (lane 3 is unused), each in `0..count` whatever
    /// the point (a NaN coordinate in bin 0): `Bins::add` indexes by them unchecked.
    #[inline(always)]
    fn bins3(&self, p: &[f32; 3]) -> [i32; 4] {
        let b = F4::xyz(*p).sub(self.origin4).mul(self.inv_width4);
        b.clamp(F4::splat(0.0), self.last4).trunc_i32()
    }
}

/// A float's place in the order of all floats but NaN, as an integer (minus zero just below
/// plus zero).
fn to_order(x: f32) -> u32 {
    let bits = x.to_bits();
    if bits >> 31 == 1 {
        !bits
    } else {
        bits | 1 << 31
    }
}

/// The float at a place of `to_order`.
fn from_order(key: u32) -> f32 {
    f32::from_bits(if key >> 31 == 1 {
        key & !(1 << 31)
    } else {
        !key
    })
}

/// The first place in the order of floats (`to_order`) where the monotone `reaches` holds,
/// searched from `guess`: steps doubling until they pass it, then halving, so at most about 64
/// tests whatever the distance. Minus infinity must not reach and plus infinity must.
fn first_reaching(reaches: impl Fn(u32) -> bool, guess: u32) -> u32 {
    let (first, last) = (to_order(f32::NEG_INFINITY), to_order(f32::INFINITY));
    // A NaN guess lies past either end of the order.
    let guess = guess.clamp(first, last);
    // `below` never reaches and `above` does.
    let (mut below, mut above);
    let mut step = 1u32;
    if reaches(guess) {
        above = guess;
        loop {
            below = above.saturating_sub(step).max(first);
            if !reaches(below) {
                break;
            }
            above = below;
            step = step.saturating_mul(2);
        }
    } else {
        below = guess;
        loop {
            above = below.saturating_add(step).min(last);
            if reaches(above) {
                break;
            }
            below = above;
            step = step.saturating_mul(2);
        }
    }
    while above - below > 1 {
        let middle = below + (above - below) / 2;
        if reaches(middle) {
            above = middle;
        } else {
            below = middle;
        }
    }
    above
}

/// Per-axis counts of references by the bin of their lower bound and of their upper bound.
pub(super) struct Bins {
    pub count: usize,
    /// `[axis][lower, upper][bin]`, flattened.
    pub counts: Vec<u32>,
}

thread_local! {
    /// The bin counts' storage, reused from node to node on each thread.
    pub(super) static BIN_STORE: RefCell<Vec<u32>> = const { RefCell::new(Vec::new()) };
}

impl Bins {
    pub fn with_storage(count: usize, mut counts: Vec<u32>) -> Bins {
        counts.clear();
        counts.resize(6 * count, 0);
        Bins { count, counts }
    }

    /// References of `axis` whose lower bound lies in a bin before `first`, and whose upper
    /// bound does.
    pub fn before(&self, axis: usize, first: usize) -> (u32, u32) {
        (
            self.lo(axis)[..first].iter().sum(),
            self.hi(axis)[..first].iter().sum(),
        )
    }

    fn lo(&self, axis: usize) -> &[u32] {
        &self.counts[2 * axis * self.count..][..self.count]
    }

    fn hi(&self, axis: usize) -> &[u32] {
        &self.counts[(2 * axis + 1) * self.count..][..self.count]
    }

    pub fn add(&mut self, refs: &[Ref], grid: &Grid) {
        let c = self.count;
        let counts = &mut self.counts[..6 * c];
        for r in refs {
            // The three axes' bins of both bounds in two vector conversions: the scalar
            // float-to-index conversion, six times a reference, was most of the count.
            let (lo, hi) = (grid.bins3(&r.lo), grid.bins3(&r.hi));
            for a in 0..3 {
                // SAFETY: `bins3` clamps every lane into `0..count` (a NaN to 0), so both
                // indices lie in this axis's `count` bins of `counts`' `6 * count`. Without
                // the six bounds checks a reference the whole build is 4% faster (1M peer mesh,
                // 1 thread, 0.84-0.87 s -> 0.81-0.83 s).
                unsafe {
                    *counts.get_unchecked_mut(2 * a * c + lo[a] as usize) += 1;
                    *counts.get_unchecked_mut((2 * a + 1) * c + hi[a] as usize) += 1;
                }
            }
        }
    }

    /// Per axis, the cheapest bin boundary strictly inside the node, as (cost, boundary index
    /// `k` in `1..count`), the first of equally cheap ones; `n` references counted. The three
    /// axes are three lanes of one sweep over the boundaries, each lane computing what
    /// `AxisCost::cost` computes for its axis (four boundaries of one axis a step, with scalar
    /// running counts and a reduction across lanes per axis, took an eighth of the build).
    pub fn cheapest_boundaries(
        &self,
        grid: &Grid,
        node_box: &Aabb,
        cost: &AxesCost,
        n: u32,
    ) -> [Option<(f32, usize)>; 3] {
        let c = self.count;
        let (lo, hi) = (
            [self.lo(0), self.lo(1), self.lo(2)],
            [self.hi(0), self.hi(1), self.hi(2)],
        );
        let width = F4::xyz(grid.extent).div(F4::splat(c as f32));
        let (min, max) = (
            F4::xyz(node_box.min.to_array()),
            F4::xyz(node_box.max.to_array()),
        );
        let axes = F4::new([0.0, 1.0, 2.0, 3.0]).lt(F4::splat(3.0));
        let (mut best, mut best_k) = (F4::splat(f32::INFINITY), F4::splat(0.0));
        let (mut started, mut ended) = ([0u32; 3], [0u32; 3]);
        for k in 1..c {
            for a in 0..3 {
                started[a] += lo[a][k - 1];
                ended[a] += hi[a][k - 1];
            }
            let below = F4::new([started[0] as f32, started[1] as f32, started[2] as f32, 1.0]);
            let above = F4::new([
                (n - ended[0]) as f32,
                (n - ended[1]) as f32,
                (n - ended[2]) as f32,
                1.0,
            ]);
            let kf = F4::splat(k as f32);
            let l = kf.mul(width);
            let pos = grid.origin4.add(l);
            let inside = pos.gt(min).and(pos.lt(max)).and(axes);
            let cost = cost.cost(l, below, above);
            let better = inside.and(cost.lt(best));
            best = F4::select(better, cost, best);
            best_k = F4::select(better, kf, best_k);
        }
        let (best, best_k) = (best.to_array(), best_k.to_array());
        let axis = |a: usize| (best[a] < f32::INFINITY).then(|| (best[a], best_k[a] as usize));
        [axis(0), axis(1), axis(2)]
    }

    pub fn merge(mut self, o: Bins) -> Bins {
        for (x, y) in self.counts.iter_mut().zip(&o.counts) {
            *x += y;
        }
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::plane_cost::AxisCost;
    use glam::Vec3;

    /// The three-axis boundary search picks what a scalar sweep over each axis's boundaries
    /// picks: the first of the cheapest, with ties made likely by counts on a few values and
    /// flat boxes.
    #[test]
    fn lanes_pick_the_scalar_sweeps_boundary() {
        let params = crate::accel::BuildParams::default();
        let mut rng = crate::accel::test_rng::Lcg(3);
        for case in 0..3000 {
            let count = 8 + case % 37;
            let node = Aabb {
                min: Vec3::ZERO,
                max: Vec3::new(
                    1.0 + (case % 3) as f32,
                    2.0,
                    if case % 5 == 0 { 0.0 } else { 1.0 },
                ),
            };
            let grid = Grid::new(&node, count);
            let mut bins = Bins::with_storage(count, Vec::new());
            // Lower bounds counted no later than upper ones, as references would be, and every
            // reference on every axis.
            let n = (rng.next() * 40.0) as u32;
            for axis in 0..3 {
                for _ in 0..n {
                    let a = (rng.next() * count as f32) as usize % count;
                    let b = a + (rng.next() * (count - a) as f32) as usize % (count - a);
                    bins.counts[2 * axis * count + a] += 1;
                    bins.counts[(2 * axis + 1) * count + b] += 1;
                }
            }
            let costs = AxisCost::per_axis(&params, &node);
            let got = bins.cheapest_boundaries(&grid, &node, &AxesCost::new(&costs), n);
            for (axis, cost) in costs.iter().enumerate() {
                let width = grid.extent[axis] / count as f32;
                let (mut started, mut ended, mut want) = (0, 0, None::<(f32, usize)>);
                for k in 1..count {
                    started += bins.lo(axis)[k - 1];
                    ended += bins.hi(axis)[k - 1];
                    let l = k as f32 * width;
                    let pos = grid.origin[axis] + l;
                    if pos > node.min[axis] && pos < node.max[axis] {
                        let c = cost.cost(l, started, n - ended);
                        if want.is_none_or(|(b, _)| c < b) {
                            want = Some((c, k));
                        }
                    }
                }
                assert_eq!(
                    want.map(|(c, k)| (c.to_bits(), k)),
                    got[axis].map(|(c, k)| (c.to_bits(), k)),
                    "case {case}, axis {axis}"
                );
            }
        }
    }

    /// The boundary search finds the first float at or past a threshold in a few dozen tests
    /// wherever the guess lies, across zero and the subnormals too.
    #[test]
    fn the_boundary_is_found_in_a_few_dozen_tests() {
        let thresholds = [0.0, -0.0, 1e-45, -1e-40, 1e-30, 3.5, -7e20, f32::MAX];
        let guesses = [
            0.0,
            1e-3,
            -1e-3,
            1e-38,
            2.0,
            -5e30,
            f32::MIN,
            f32::MAX,
            f32::NAN,
        ];
        for t in thresholds {
            for g in guesses {
                let tests = std::cell::Cell::new(0);
                let reaches = |key: u32| {
                    tests.set(tests.get() + 1);
                    from_order(key) >= t
                };
                let found = from_order(first_reaching(reaches, to_order(g)));
                assert!(found >= t && found.next_down() < t, "{t} from {g}: {found}");
                assert!(tests.get() <= 66, "{t} from {g}: {} tests", tests.get());
            }
        }
    }

    /// Counting and refinement must put every coordinate in the same bin, or the refined sweep
    /// would start from counts that disagree with its window.
    #[test]
    fn counting_and_refinement_bin_alike() {
        // An ordinary node, and one around zero (where floats are densest and bin boundaries
        // lie billions of floats from their unrounded place) with a subnormal-wide axis.
        let nodes = [
            (Vec3::new(-1.0, 0.25, 3.0), Vec3::new(2.0, 0.25, 7.5)),
            (
                Vec3::new(-1e-3, -3e-7, -1e-40),
                Vec3::new(2e-3, 5e-7, 1e-40),
            ),
        ];
        for (min, max) in nodes {
            let node = Aabb { min, max };
            let grid = Grid::new(&node, 37);
            let mut xs = vec![-5.0, -1.0, 0.25, 2.0, 3.0, 7.5, 9.0, f32::NAN];
            xs.extend([
                0.0, -0.0, 1e-45, -1e-45, 1e-38, -1e-38, 1e-20, -1e-20, 1e-40,
            ]);
            for axis in 0..3 {
                let (lo, hi) = (min[axis], max[axis]);
                xs.extend((0..700).map(|i| lo + (hi - lo) * (i as f32 / 600.0 - 0.1)));
            }
            xs.extend((0..2000).map(|i| -1.5 + i as f32 * 0.0047));
            for &x in &xs {
                let bins = grid.bins3(&[x, x, x]);
                for (axis, &bin) in bins[..3].iter().enumerate() {
                    assert!((0..37).contains(&bin), "{x} on {axis}: bin {bin}");
                    for first in 0..36 {
                        let expected = bin as usize == first || bin as usize == first + 1;
                        assert_eq!(
                            grid.in_pair(x, axis, first),
                            expected,
                            "{x}, {axis}, {first}"
                        );
                        let (from, to) = grid.pair_range(axis, first);
                        if x.is_finite() {
                            assert_eq!(x >= from && x < to, expected, "{x}, {axis}, {first}");
                        }
                    }
                }
            }
        }
    }
}
