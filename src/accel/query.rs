//! The kd-tree's answers to `Intersect`: one ray through the single-ray walk (`traverse`), a
//! batch of rays in packets where consecutive rays share an octant (`packet`), singly elsewhere.
//! Kept apart so that neither walk depends on the other's module.

use super::lanes::{F4, Lanes};
#[cfg(target_arch = "x86_64")]
use super::lanes8::F8;
use super::packet::{self, LANES, Run, WIDE_LANES};
use super::traverse::{NoTally, Tally, WalkCounts, any_hit, closest_hit, walk_one};
use super::tree::KdTree;
use super::{Hit, Intersect, Ray};
use std::sync::atomic::{AtomicBool, Ordering};

impl KdTree {
    /// `closest_hit` with its work counted.
    pub fn closest_hit_counted(&self, ray: &Ray, t_max: f32, c: &mut WalkCounts) -> Option<Hit> {
        closest_hit(self, ray, t_max, c)
    }

    /// `any_hit` with its work counted.
    pub fn any_hit_counted(&self, ray: &Ray, t_max: f32, c: &mut WalkCounts) -> bool {
        any_hit(self, ray, t_max, c)
    }

    /// `closest_hits` with its work counted (a packet's node counts once for all its rays).
    pub fn closest_hits_counted(
        &self,
        rays: &[Ray],
        t_max: &[f32],
        hits: &mut [Option<Hit>],
        c: &mut WalkCounts,
    ) {
        self.batch::<_, false>(rays, t_max, c, |i, h| hits[i] = h);
    }

    /// `any_hits` with its work counted.
    pub fn any_hits_counted(
        &self,
        rays: &[Ray],
        t_max: &[f32],
        occluded: &mut [bool],
        c: &mut WalkCounts,
    ) {
        self.batch::<_, true>(rays, t_max, c, |i, h| occluded[i] = h.is_some());
    }

    /// Walks `rays` in packets where they share an octant, singly elsewhere; `out(i, hit)`.
    /// Packets are eight rays wide where the CPU has AVX, four otherwise; a ray's hit is the
    /// same either way (bit for bit its single-ray walk's).
    #[inline(always)]
    fn batch<T: Tally, const ANY: bool>(
        &self,
        rays: &[Ray],
        t_max: &[f32],
        tally: &mut T,
        out: impl FnMut(usize, Option<Hit>),
    ) {
        assert_eq!(rays.len(), t_max.len(), "one limit per ray");
        #[cfg(target_arch = "x86_64")]
        if self.packet_lanes() == WIDE_LANES {
            // SAFETY: `packet_lanes` gives `WIDE_LANES` only where the CPU has AVX.
            return unsafe { self.batch_avx::<T, ANY>(rays, t_max, tally, out) };
        }
        self.batch_in::<F4, LANES, T, ANY>(rays, t_max, tally, out);
    }

    /// Rays per packet `closest_hits` and `any_hits` walk on this CPU: `WIDE_LANES` where it has
    /// AVX (unless `force_narrow_packets` asked for `LANES`), else `LANES`.
    pub fn packet_lanes(&self) -> usize {
        #[cfg(target_arch = "x86_64")]
        if !NARROW.load(Ordering::Relaxed) && super::lanes8::has_avx() {
            return WIDE_LANES;
        }
        LANES
    }

    /// `batch` in eight AVX lanes: the walk and its lane operations inline into this function,
    /// which alone is compiled for AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    pub(super) fn batch_avx<T: Tally, const ANY: bool>(
        &self,
        rays: &[Ray],
        t_max: &[f32],
        tally: &mut T,
        out: impl FnMut(usize, Option<Hit>),
    ) {
        self.batch_in::<F8, WIDE_LANES, T, ANY>(rays, t_max, tally, out);
    }

    /// `batch` in packets of `N` lanes `L`. Written without closures around the walk: a closure
    /// is not always inlined, and the eight-lane walk must inline whole into `batch_avx` (out of
    /// it, each lane operation became a call: 0.86 against 17 Mrays/s).
    #[inline(always)]
    pub(super) fn batch_in<L: Lanes<N>, const N: usize, T: Tally, const ANY: bool>(
        &self,
        rays: &[Ray],
        t_max: &[f32],
        tally: &mut T,
        mut out: impl FnMut(usize, Option<Hit>),
    ) {
        for run in packet::group(rays, N) {
            match run {
                Run::Single(i) => out(i, walk_one::<ANY>(self, &rays[i], t_max[i], tally)),
                Run::Packet(a, b, oct) => {
                    let hits =
                        self.packet_walk::<L, N, _, ANY>(&rays[a..b], &t_max[a..b], oct, tally);
                    for (k, h) in hits.into_iter().take(b - a).enumerate() {
                        out(a + k, h);
                    }
                }
            }
        }
    }
}

/// Set by `force_narrow_packets`.
static NARROW: AtomicBool = AtomicBool::new(false);

/// Makes every later batch walk packets of `LANES` rays even where the CPU has AVX: for
/// `bench accel --walk packet4` and the tests that hold both widths to the single-ray walk.
pub fn force_narrow_packets(narrow: bool) {
    NARROW.store(narrow, Ordering::Relaxed);
}

impl Intersect for KdTree {
    fn closest_hit(&self, ray: &Ray, t_max: f32) -> Option<Hit> {
        closest_hit(self, ray, t_max, &mut NoTally)
    }

    fn any_hit(&self, ray: &Ray, t_max: f32) -> bool {
        any_hit(self, ray, t_max, &mut NoTally)
    }

    fn closest_hits(&self, rays: &[Ray], t_max: &[f32], hits: &mut [Option<Hit>]) {
        self.batch::<_, false>(rays, t_max, &mut NoTally, |i, h| hits[i] = h);
    }

    fn any_hits(&self, rays: &[Ray], t_max: &[f32], occluded: &mut [bool]) {
        self.batch::<_, true>(rays, t_max, &mut NoTally, |i, h| occluded[i] = h.is_some());
    }
}
