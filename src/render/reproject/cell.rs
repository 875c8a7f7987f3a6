//! A target pixel's cell: what the source pixels that landed (in part) on it bring to the
//! rules of `mod.rs`, gathered as they land (`band.rs`).

use super::source::SourcePixel;
use glam::Vec3;

/// Distinct triangles a target cell holds. Where more land, the pixels near it trace: their
/// candidates would be incomplete.
const SLOTS: usize = 8;

/// The source pixels that landed (in part) on one target pixel.
#[derive(Clone, Copy)]
pub(super) struct Cell {
    /// The smallest and largest parallax landed; empty (`[inf, -inf]`) where nothing did.
    pub parallax: [f32; 2],
    pub prims: [u32; SLOTS],
    pub distinct: u8,
    /// A source pixel hit more triangles than it kept, or this cell more than `SLOTS`.
    pub overflow: bool,
    /// A miss landed.
    pub miss: bool,
    /// A hit landed whose radiance cannot stand for the target's.
    pub indirect: bool,
    pub lit: u32,
    pub shadowed: u32,
    /// The landed radiance, each source pixel's value weighted by the part of it that landed
    /// here, and the weights' sum.
    pub weight: f32,
    pub radiance: Vec3,
    /// Pixels whose radiance is a plane landed (`plane.rs`), and the largest of their bounds.
    pub planes: bool,
    pub plane_bound: f32,
    /// Pixels with too few hits for a plane landed, and bounds of their samples' radiance per
    /// channel (each pixel's mean give or take its spread).
    pub means: bool,
    pub radiance_lo: Vec3,
    pub radiance_hi: Vec3,
}

impl Default for Cell {
    fn default() -> Cell {
        Cell {
            parallax: [f32::INFINITY, f32::NEG_INFINITY],
            prims: [0; SLOTS],
            distinct: 0,
            overflow: false,
            miss: false,
            indirect: false,
            lit: 0,
            shadowed: 0,
            weight: 0.0,
            radiance: Vec3::ZERO,
            planes: false,
            plane_bound: 0.0,
            means: false,
            radiance_lo: Vec3::INFINITY,
            radiance_hi: Vec3::NEG_INFINITY,
        }
    }
}

impl Cell {
    pub fn covered(&self) -> bool {
        self.parallax[0] <= self.parallax[1]
    }

    /// The landed radiance, where every hit that landed may lend it and no miss landed.
    pub(super) fn lent_radiance(&self) -> Option<Vec3> {
        (self.weight > 0.0 && !self.indirect && !self.miss).then(|| self.radiance / self.weight)
    }

    fn land(&mut self, parallax: [f32; 2]) {
        self.parallax = [
            self.parallax[0].min(parallax[0]),
            self.parallax[1].max(parallax[1]),
        ];
    }

    /// Adds the hits of source pixel `p`, of which the part `share` lands here; `direct` where
    /// their radiance may stand for the target's.
    pub fn add_hits(&mut self, p: &SourcePixel, parallax: [f32; 2], share: f32, direct: bool) {
        self.land(parallax);
        self.lit |= p.lit;
        self.shadowed |= p.shadowed;
        self.overflow |= p.overflow;
        for &prim in &p.prims[..p.distinct as usize] {
            self.add_prim(prim);
        }
        self.add_radiance(p, share, direct);
    }

    /// Adds the radiance of source pixel `p`, of which the part `share` lands here, where it
    /// may stand for the target's (`direct`).
    pub fn add_radiance(&mut self, p: &SourcePixel, share: f32, direct: bool) {
        if !direct {
            self.indirect = true;
            return;
        }
        self.weight += share;
        self.radiance += share * p.radiance;
        if p.plane() {
            self.planes = true;
            self.plane_bound = self.plane_bound.max(p.radiance_bound);
        } else {
            self.means = true;
            self.radiance_lo = self.radiance_lo.min(p.radiance - p.radiance_bound);
            self.radiance_hi = self.radiance_hi.max(p.radiance + p.radiance_bound);
        }
    }

    /// Adds one hit on `prim` of source pixel `p` (a pixel that keeps its samples) at
    /// `parallax`: the pixel's shadow answers, and no radiance.
    pub fn add_hit(&mut self, prim: u32, p: &SourcePixel, parallax: f32) {
        self.land([parallax, parallax]);
        self.lit |= p.lit;
        self.shadowed |= p.shadowed;
        self.add_prim(prim);
    }

    fn add_prim(&mut self, prim: u32) {
        let n = self.distinct as usize;
        if self.prims[..n].contains(&prim) {
            return;
        }
        if n < SLOTS {
            self.prims[n] = prim;
            self.distinct += 1;
        } else {
            self.overflow = true;
        }
    }

    pub fn add_miss(&mut self, parallax: f32) {
        self.land([parallax, parallax]);
        self.miss = true;
    }
}
