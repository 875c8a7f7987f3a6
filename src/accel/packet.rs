//! Packet traversal: up to four rays (eight where the CPU has AVX, `query.rs`) whose directions
//! have the same sign on every axis walk the kd-tree together, so a node is fetched, and its branch taken, once for all of them (Wald et
//! al., "Interactive Rendering with Coherent Ray Tracing", 2001). Coherent rays (neighbouring
//! camera rays, their shadow rays to one light, the two eyes' rays of one pixel) visit nearly
//! the same nodes. The walk is written once over `lanes::Lanes`, for four SSE lanes and for the
//! eight AVX lanes of `lanes8.rs`.
//!
//! Exactness: each lane visits exactly the nodes the single-ray walk (`traverse.rs`) visits for
//! its ray, in the same order, with the same parametric intervals (the same IEEE operations, lane
//! by lane), and runs the same triangle tests against the same limits with its own mailbox. So
//! every hit is bit for bit the single-ray hit, and images cannot change. The shared sign makes
//! the front-to-back order of the two children the same for every lane that visits both; a lane
//! visiting one child keeps the interval the single walk would give it.

use super::aabb::Aabb;
use super::lanes::{LaneMask, Lanes};
use super::traverse::{STACK, Tally, prefetch};
use super::tree::KdTree;
use super::triangle::{RayPack, intersect_packet};
use super::{Hit, Ray};
use std::mem::MaybeUninit;

/// Rays per packet on every CPU: one SSE register of f32. Where the CPU has AVX, `query.rs`
/// walks packets of `WIDE_LANES` instead.
pub const LANES: usize = 4;

/// Rays per packet where the CPU has AVX: one 256-bit register of f32. Measured on the 1M peer
/// mesh (2 threads, the peer camera rays in rows): 4.60 inner steps and 1.41 leaves a camera
/// ray against four-ray packets' 7.71 and 2.19, and 17.3-17.7 against 12.5-13.0 Mrays/s.
pub const WIDE_LANES: usize = 8;

/// Bit `axis` set where the direction is positive; `None` with a zero or NaN component, whose
/// single-ray handling (a ray inside a split plane may visit both sides) the packet does not share.
fn octant(r: &Ray) -> Option<u8> {
    let mut bits = 0;
    for (axis, d) in r.dir.to_array().into_iter().enumerate() {
        if d > 0.0 {
            bits |= 1 << axis;
        } else if d.is_nan() || d == 0.0 {
            return None;
        }
    }
    Some(bits)
}

/// A run of rays `group` hands out: one ray to walk alone, or a packet of consecutive rays
/// `start..end` in one octant.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Run {
    Single(usize),
    Packet(usize, usize, u8),
}

/// Splits `rays` into runs of up to `width` consecutive rays of one octant, and rays no packet
/// can take or that would travel alone.
pub(super) fn group(rays: &[Ray], width: usize) -> impl Iterator<Item = Run> + '_ {
    let mut start = 0;
    std::iter::from_fn(move || {
        let s = start;
        let first = rays.get(s)?;
        let Some(oct) = octant(first) else {
            start += 1;
            return Some(Run::Single(s));
        };
        let mut end = s + 1;
        while end < rays.len() && end - s < width && octant(&rays[end]) == Some(oct) {
            end += 1;
        }
        start = end;
        Some(if end - s == 1 {
            Run::Single(s)
        } else {
            Run::Packet(s, end, oct)
        })
    })
}

/// Up to `N` rays laid out lane by lane for a packet walk; lanes past the rays given copy the
/// last one (the walks start them inactive).
pub(super) struct PacketRays<L, const N: usize> {
    pub rays: [Ray; N],
    pub origin: [L; 3],
    /// `WalkRay`'s reciprocal direction, lane by lane (no component is zero in a packet).
    pub inv_dir: [L; 3],
}

impl<L: Lanes<N>, const N: usize> PacketRays<L, N> {
    #[inline(always)]
    pub(super) fn new(rays: &[Ray]) -> Self {
        let n = rays.len();
        let rays: [Ray; N] = std::array::from_fn(|i| rays[i.min(n - 1)]);
        // Written out, no closures: the eight-lane walk needs every lane operation inlined
        // (see `KdTree::batch_in`).
        let (mut o, mut d) = ([[0.0; N]; 3], [[0.0; N]; 3]);
        for (i, r) in rays.iter().enumerate() {
            for axis in 0..3 {
                o[axis][i] = r.origin[axis];
                d[axis][i] = r.dir[axis];
            }
        }
        let one = L::splat(1.0);
        PacketRays {
            rays,
            origin: [L::new(o[0]), L::new(o[1]), L::new(o[2])],
            inv_dir: [
                one.div(L::new(d[0])),
                one.div(L::new(d[1])),
                one.div(L::new(d[2])),
            ],
        }
    }

    /// Per lane, where the ray enters and leaves box `b` within `[0, limit]` (`Aabb::clip` lane
    /// by lane): empty where entry > exit.
    #[inline(always)]
    pub(super) fn clip(&self, b: &Aabb, limit: L) -> (L, L) {
        let (lo, hi) = (b.min.to_array(), b.max.to_array());
        let (mut entry, mut exit) = (L::splat(0.0), limit);
        for axis in 0..3 {
            let near = L::splat(lo[axis])
                .sub(self.origin[axis])
                .mul(self.inv_dir[axis]);
            let far = L::splat(hi[axis])
                .sub(self.origin[axis])
                .mul(self.inv_dir[axis]);
            let swap = near.gt(far);
            entry = entry.max_num(L::select(swap, far, near));
            exit = exit.min_num(L::select(swap, near, far));
        }
        (entry, exit)
    }
}

/// The packet's mailbox: the last triangles tested, hashed by index as the single-ray mailbox
/// is, each with the lanes that tested it. A lane skips a triangle it tested already; testing
/// one again could not change its result anyway (a miss within a limit misses within any
/// smaller one, and a hit is the best hit already), so collisions cost time, never exactness.
struct PacketMailbox([(u32, u32); 8]);

impl PacketMailbox {
    fn new() -> PacketMailbox {
        PacketMailbox([(u32::MAX, 0); 8])
    }

    /// The lanes of `active` that have not tested `prim`; records them as having tested it.
    #[inline]
    fn untested(&mut self, prim: u32, active: u32) -> u32 {
        let slot = &mut self.0[prim as usize & 7];
        if slot.0 == prim {
            let fresh = active & !slot.1;
            slot.1 |= active;
            fresh
        } else {
            *slot = (prim, active);
            active
        }
    }
}

/// One lane's bit per set lane of `m`, lowest first.
fn lanes_of(mut m: u32) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (m != 0).then(|| {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            i
        })
    })
}

impl KdTree {
    /// The walk of `rays` (2 to `N` rays, all in octant `oct`) in lanes `L`: per lane, the
    /// closest hit before `t_max` (`ANY = false`) or the first hit found (`ANY = true`).
    #[inline(always)]
    pub(super) fn packet_walk<L: Lanes<N>, const N: usize, T: Tally, const ANY: bool>(
        &self,
        rays: &[Ray],
        t_max: &[f32],
        oct: u8,
        tally: &mut T,
    ) -> [Option<Hit>; N] {
        let mut hits = [None; N];
        let n = rays.len();
        debug_assert!((1..=N).contains(&n) && t_max.len() == n);
        if self.nodes.is_empty() || self.bounds.is_empty() {
            return hits;
        }
        let lanes = PacketRays::<L, N>::new(rays);
        let (lane_rays, origin, inv_dir) = (lanes.rays, lanes.origin, lanes.inv_dir);
        let limits = L::new(std::array::from_fn(|i| t_max[i.min(n - 1)]));
        let (entry, exit) = lanes.clip(&self.bounds, limits);
        let mut active = !entry.gt(exit).bits() & ((1 << n) - 1);
        if active == 0 {
            return hits;
        }
        let pre = RayPack::<L, N>::new(lane_rays);
        let mut mailbox = PacketMailbox::new();
        let mut best = limits.to_array();
        let mut best_v = limits;
        // Lanes of an any-hit walk that have not hit yet.
        let mut open = active;
        let (mut t_min, mut t_far) = (entry, exit);
        let mut stack = [const { MaybeUninit::<(u32, u32, L, L)>::uninit() }; STACK];
        let mut sp = 0;
        let mut node = 0usize;
        let zero = L::splat(0.0);
        loop {
            // A lane whose best hit lies before this node's entry is done with it (and, front to
            // back, with every node on the stack): the single walk's stopping rule.
            active &= !best_v.lt(t_min).bits();
            if active != 0 {
                let nd = self.nodes[node];
                if !nd.is_leaf() {
                    tally.inner();
                    let axis = nd.axis();
                    let split = L::splat(nd.split());
                    let below = node + 1;
                    let above = node + nd.above_offset();
                    prefetch(&self.nodes[above]);
                    let positive = oct >> axis & 1 == 1;
                    let o = origin[axis];
                    let t_plane = split.sub(o).mul(inv_dir[axis]);
                    // The single walk's cases per lane: `first` is the child on the origin's side;
                    // `a`: only `first`; `b`: only the other; neither: both, split at the plane.
                    let on_plane = if positive { 0 } else { o.eq(split).bits() };
                    let first_below = o.lt(split).bits() | on_plane;
                    let a_m = t_plane.gt(t_far).or(t_plane.le(zero));
                    let b_m = t_plane.lt(t_min);
                    let (a, b) = (a_m.bits(), b_m.bits());
                    let first_near = if positive { first_below } else { !first_below };
                    let (visit_first, visit_second) = (a | !b, !a);
                    let near_lanes =
                        active & ((first_near & visit_first) | (!first_near & visit_second));
                    let far_lanes =
                        active & ((first_near & visit_second) | (!first_near & visit_first));
                    let both = L::Mask::all(true).and_not(a_m.or(b_m));
                    let (near, far) = if positive {
                        (below, above)
                    } else {
                        (above, below)
                    };
                    if near_lanes == 0 {
                        node = far;
                        t_min = L::select(both, t_plane, t_min);
                        active = far_lanes;
                        continue;
                    }
                    if far_lanes != 0 {
                        stack[sp].write((
                            far as u32,
                            far_lanes,
                            L::select(both, t_plane, t_min),
                            t_far,
                        ));
                        sp += 1;
                    }
                    node = near;
                    t_far = L::select(both, t_plane, t_far);
                    active = near_lanes;
                    continue;
                }
                tally.leaf();
                // As in the single walk: the node the walk resumes at and the leaf's triangles
                // come in together, while the leaf is tested.
                if sp > 0 {
                    // SAFETY: every entry below `sp` was written by a push above.
                    let next = unsafe { stack[sp - 1].assume_init_ref() }.0;
                    prefetch(&self.nodes[next as usize]);
                }
                let refs = &self.prim_refs[nd.leaf_range()];
                for &p in refs {
                    prefetch(&self.triangles[p as usize]);
                }
                for &p in refs {
                    let tri = &self.triangles[p as usize];
                    // An any-hit walk tests again what it tested (a lane that missed a
                    // triangle misses it again, one that hit is done): on the 1M peer mesh its
                    // rays took 14.77 tests each instead of 14.23 and ran 3-4% faster without
                    // the mailbox's bookkeeping; closest-hit rays lost 1-2% without it.
                    let lanes = if ANY {
                        active
                    } else {
                        mailbox.untested(p, active)
                    };
                    if lanes == 0 {
                        continue;
                    }
                    for _ in 0..lanes.count_ones() {
                        tally.test();
                    }
                    let (hit, [t, b1, b2]) = intersect_packet(&pre, tri, best_v, lanes);
                    if hit == 0 {
                        continue;
                    }
                    for i in lanes_of(hit) {
                        hits[i] = Some(Hit {
                            t: t[i],
                            prim: p,
                            b1: b1[i],
                            b2: b2[i],
                        });
                        if ANY {
                            // Done: no later node's entry lies past minus infinity.
                            best[i] = f32::NEG_INFINITY;
                            active &= !(1 << i);
                            open &= !(1 << i);
                        } else {
                            best[i] = t[i];
                        }
                    }
                    best_v = L::new(best);
                }
                if ANY && open == 0 {
                    break;
                }
            }
            if sp == 0 {
                break;
            }
            sp -= 1;
            // SAFETY: every entry below `sp` was written by a push above.
            let (next, lanes, a, b) = unsafe { stack[sp].assume_init() };
            node = next as usize;
            active = lanes;
            t_min = a;
            t_far = b;
        }
        hits
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_rng::Lcg;
    use super::super::{BuildParams, Intersect, SplitMethod};
    use super::*;
    use glam::Vec3;

    fn same(a: Option<Hit>, b: Option<Hit>) -> bool {
        let bits =
            |h: Option<Hit>| h.map(|h| (h.t.to_bits(), h.prim, h.b1.to_bits(), h.b2.to_bits()));
        bits(a) == bits(b)
    }

    /// Packets of neighbouring rays (a pinhole's fan over a soup, and rays on split planes)
    /// give exactly the single-ray hits and occlusion.
    #[test]
    fn packets_find_bit_identical_hits() {
        let mut rng = Lcg(11);
        let mut tris: Vec<[Vec3; 3]> = (0..3000)
            .map(|_| {
                let c = rng.v(10.0);
                [c, c + rng.v(1.0) - 0.5, c + rng.v(1.0) - 0.5]
            })
            .collect();
        // An axis-aligned grid that puts split planes where rays run.
        for i in 0..6 {
            let x = i as f32;
            tris.push([
                Vec3::new(x, 0.0, 0.0),
                Vec3::new(x, 5.0, 0.0),
                Vec3::new(x, 0.0, 5.0),
            ]);
        }
        let mut rays = Vec::new();
        let eye = Vec3::new(5.0, 5.0, -8.0);
        for y in 0..40 {
            for x in 0..40 {
                let d = Vec3::new(x as f32 / 40.0 - 0.5, y as f32 / 40.0 - 0.5, 1.0);
                rays.push(Ray::new(eye, d));
            }
        }
        for _ in 0..2000 {
            rays.push(Ray::new(rng.v(12.0) - 1.0, rng.v(2.0) - 1.0));
        }
        // Origins on grid planes, directions with one zero component mixed in.
        for i in 0..400 {
            let f = i as f32 * 0.0125;
            rays.push(Ray::new(
                Vec3::new(2.0, f, -1.0),
                Vec3::new(0.3, 0.01 * f, 1.0),
            ));
            rays.push(Ray::new(Vec3::new(3.0, f, 9.0), Vec3::new(-0.2, 0.0, -1.0)));
        }
        let t_max: Vec<f32> = (0..rays.len())
            .map(|i| if i % 3 == 0 { 9.0 } else { f32::INFINITY })
            .collect();
        for (method, width) in [SplitMethod::Sah, SplitMethod::Median]
            .into_iter()
            .flat_map(|m| [(m, LANES), (m, WIDE_LANES)])
        {
            let tree = KdTree::build(tris.clone(), BuildParams::with_method(method));
            let (hits, occluded) = packet_answers(&tree, &rays, &t_max, width);
            let mut found = 0;
            for (i, r) in rays.iter().enumerate() {
                let single = tree.closest_hit(r, t_max[i]);
                assert!(
                    same(hits[i], single),
                    "{method:?}, {width} lanes, ray {i}: {:?} vs {single:?}",
                    hits[i]
                );
                let blocked = tree.any_hit(r, t_max[i]);
                assert_eq!(occluded[i], blocked, "{method:?}, {width} lanes, ray {i}");
                found += single.is_some() as usize;
            }
            assert!(
                found > rays.len() / 4,
                "the rays must hit something: {found}"
            );
        }
    }

    /// Closest hits and occlusion of `rays` in packets of `width` lanes. Eight lanes need AVX:
    /// on a CPU without it this fails rather than pass unchecked.
    fn packet_answers(
        tree: &KdTree,
        rays: &[Ray],
        t_max: &[f32],
        width: usize,
    ) -> (Vec<Option<Hit>>, Vec<bool>) {
        use super::super::traverse::NoTally;
        let mut hits = vec![None; rays.len()];
        let mut occluded = vec![false; rays.len()];
        let (mut closest, mut any) = (
            |i, h| hits[i] = h,
            |i, h: Option<Hit>| occluded[i] = h.is_some(),
        );
        if width == LANES {
            tree.batch_in::<crate::accel::lanes::F4, LANES, _, false>(
                rays,
                t_max,
                &mut NoTally,
                &mut closest,
            );
            tree.batch_in::<crate::accel::lanes::F4, LANES, _, true>(
                rays,
                t_max,
                &mut NoTally,
                &mut any,
            );
        } else {
            #[cfg(target_arch = "x86_64")]
            {
                assert!(
                    super::super::lanes8::has_avx(),
                    "no AVX here: eight lanes untested"
                );
                // SAFETY: the CPU has AVX (asserted above).
                unsafe {
                    tree.batch_avx::<_, false>(rays, t_max, &mut NoTally, &mut closest);
                    tree.batch_avx::<_, true>(rays, t_max, &mut NoTally, &mut any);
                }
            }
            #[cfg(not(target_arch = "x86_64"))]
            return packet_answers(tree, rays, t_max, LANES);
        }
        (hits, occluded)
    }

    #[test]
    fn grouping_takes_runs_of_one_octant() {
        let r = |x: f32, y: f32| Ray::new(Vec3::ZERO, Vec3::new(x, y, 1.0));
        let rays = [
            r(1.0, 1.0),
            r(1.0, 1.0),
            r(-1.0, 1.0),
            r(0.0, 1.0),
            r(1.0, 1.0),
            r(1.0, 1.0),
            r(1.0, 1.0),
            r(1.0, 1.0),
            r(1.0, 1.0),
        ];
        let seen: Vec<(usize, usize)> = group(&rays, LANES)
            .map(|r| match r {
                Run::Single(i) => (i, i + 1),
                Run::Packet(a, b, _) => (a, b),
            })
            .collect();
        assert_eq!(seen, vec![(0, 2), (2, 3), (3, 4), (4, 8), (8, 9)]);
    }
}
