//! The kd-tree's answers to `Intersect`: one ray through the single-ray walk (`traverse`), a
//! batch of rays in packets where consecutive rays share an octant (`packet`), singly elsewhere.
//! Kept apart so that neither walk depends on the other's module.

use super::packet::{self, Run};
use super::traverse::{NoTally, Tally, WalkCounts, any_hit, closest_hit, walk_one};
use super::tree::KdTree;
use super::{Hit, Intersect, Ray};

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
    fn batch<T: Tally, const ANY: bool>(
        &self,
        rays: &[Ray],
        t_max: &[f32],
        tally: &mut T,
        out: impl FnMut(usize, Option<Hit>),
    ) {
        assert_eq!(rays.len(), t_max.len(), "one limit per ray");
        let walk = |run| match run {
            Run::Single(i) => [
                walk_one::<ANY>(self, &rays[i], t_max[i], tally),
                None,
                None,
                None,
            ],
            Run::Packet(a, b, oct) => {
                self.packet_walk::<_, ANY>(&rays[a..b], &t_max[a..b], oct, tally)
            }
        };
        packet::for_each_hit(rays, walk, out);
    }
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
