//! `eye_reuse = "reproject"`: a second view borrows the primary hits of the first (Adelson and
//! Hodges, "Stereoscopic ray-tracing", 1993). While the source view traces a pixel it folds the
//! pixel's camera samples into one record (`source.rs`): the depth range of its hits, where in
//! the pixel its samples lie, the triangles hit, the shadow answers, the radiance. Each record
//! lands in the target view's film on the span its samples move to (`band.rs`); a pixel whose
//! samples lie across a depth edge keeps them, and they land one by one. A target sample then
//! takes a landed hit instead of tracing its own camera ray when the rule below holds, and
//! otherwise traces in full. What a target view reads grows with the pixels, not the samples.
//!
//! The rule, for a target pixel, over what landed in a window of 5x3 pixels around it:
//! 1. **Nothing revealed.** Every pixel of the window has something landed in it or in a
//!    horizontal neighbour. A surface the source view cannot see shows up in the target as a
//!    run of empty pixels (a disocclusion hole); an isolated empty pixel is only sampling.
//! 2. **No step in depth.** In each row of the window, the parallax of the samples (target x
//!    minus source x) spreads over at most `MAX_PARALLAX_SPREAD` pixels. The rigs this runs on
//!    (off-axis, parallel) move points along their own row only, so a row is where a hole opens:
//!    where a near object passes in front of a far one the spread is the difference of their
//!    parallaxes, and a hole can hide between samples only where it is narrower than that. A
//!    slanted floor, whose parallax changes from row to row but smoothly along a row, reuses.
//! 3. **Not at the frame edge the source cannot see.** Near objects shift sideways between the
//!    views; a strip as wide as the largest parallax of the nearest point the source saw, on
//!    that side of the target film, is traced. The film's own border cuts the windows instead:
//!    nothing lies beyond it in either view.
//! 4. **A verified hit.** The triangles hit by what landed within one pixel of the target
//!    pixel are the candidates (where there are more than a pixel holds, it traces); the
//!    target sample's own ray is intersected with each (the same watertight test the tree
//!    uses) and the nearest hit is its primary hit. No candidate hit: it traces.
//!
//! Shading is then computed for the target's own ray (its view direction, its texture
//! coordinates), and mirror and glass rays are traced from the hit. A light's shadow answer is
//! reused only where every sample of the window that asked that light got the same answer
//! (shadow edges are traced). A reused hit is exact whenever the nearest surface along the ray
//! was seen by the source near there; the error left is where it was not (a surface seen by
//! the target alone, thinner than the rules can see) and shadow detail finer than the samples.
//!
//! Under `"reproject-radiance"` a target pixel may also take the radiance that landed on it,
//! with no ray at all: each record's radiance is a plane fitted to its samples (`plane.rs`),
//! and the pixel takes the landed values where a bound on their error is within
//! `RADIANCE_BOUND` (`window.rs`, `window_error`).

use super::camera::EyeCamera;
use super::integrator::KnownHit;
use super::sampling::unseen_strip;
use crate::accel::{Ray, triangle};
use crate::scene::pose::Geometry;
use band::{BandPlan, Landing, Plan, Ring, plan_band};
use glam::Vec3;
use rayon::prelude::*;
use std::ops::Range;

mod band;
mod cell;
mod plane;
mod source;
mod window;

pub use source::{EdgeTest, FinishedTile, Sample, SourcePixels, SourceTile};

/// `"reproject-radiance"`: the angle between the eyes' view directions may be at most this
/// fraction of a surface's GGX lobe width. At a tenth of the width the half vector moves by a
/// twentieth of it, which changes the GGX distribution by about 0.5% at its peak (`D` falls as
/// `(1 + d^2 / alpha^2)^-2` with the angle `d` off the peak).
pub const LOBE_FRACTION: f32 = 0.1;

/// `"reproject-radiance"`: the largest error bound of a reused pixel radiance, per channel
/// (the per-channel error `compare --fail` counts, 0.02).
pub const RADIANCE_BOUND: f32 = 0.02;

/// Rule 2's bound, pixels: a disocclusion narrower than half a pixel hides at most part of a
/// sample's footprint.
pub const MAX_PARALLAX_SPREAD: f32 = 0.5;

/// Target rows planned together. A band lands one row more on each side of it (the rules'
/// windows are three rows high): an eighth more landing at 16 rows (the tile height, which
/// bands had before), 3% at 64, where the six bands of a 640x360 film still spread over the
/// cores. On the diffuse scene at 640x360 the planning took 8.4 ms instead of 9.1.
const BAND_ROWS: usize = 64;

/// The source view's hits as the target film sees them: each target pixel's plan, by bands of
/// `BAND_ROWS` rows.
pub struct Reprojection {
    width: usize,
    bands: Vec<BandPlan>,
}

/// What a target pixel may reuse.
pub enum PixelReuse<'a> {
    /// Every source sample around it missed: its rays miss too (the background).
    Miss,
    /// `"reproject-radiance"`: the pixel's value.
    Radiance(Vec3),
    /// Triangles for each sample's own ray to verify, and the window's shadow answers.
    Hits(HitReuse<'a>),
}

/// Candidate triangles of a pixel and the shadow answers of its window.
pub struct HitReuse<'a> {
    candidates: &'a [u32],
    lit: u32,
    shadowed: u32,
}

impl Reprojection {
    /// Lands the source view's pixels from `source_camera` in `target`'s film (of the same
    /// size) and plans every target pixel, a band of rows at a time. Misses land at infinity
    /// when `misses` (no far plane); `radiance` lets smooth rough pixels take the landed radiance
    /// (`"reproject-radiance"`).
    pub fn new(
        source: &SourcePixels,
        source_camera: &EyeCamera,
        target: &EyeCamera,
        misses: bool,
        radiance: bool,
    ) -> Reprojection {
        let (width, height) = source.size();
        let (a, b) = source_camera.parallax_line(target);
        let landing = Landing {
            a,
            b,
            misses,
            baseline: radiance.then(|| target.position().distance(source_camera.position())),
            unseen: unseen_strip(source.spp()),
        };
        // Rule 3 from the nearest depth the source saw.
        let nearest = source.nearest_depth().max(source_camera.znear());
        let columns = if nearest.is_finite() {
            edge_strips(a + b / nearest, width)
        } else {
            0..width
        };
        // Each thread keeps its ring of rows from band to band.
        let bands = (0..height.div_ceil(BAND_ROWS))
            .into_par_iter()
            .map_init(Ring::default, |ring, band| {
                let rows = band * BAND_ROWS..((band + 1) * BAND_ROWS).min(height);
                plan_band(source, &landing, rows, columns.clone(), ring)
            })
            .collect();
        Reprojection { width, bands }
    }

    /// What the target pixel (x, y) may reuse, or `None` where it must trace.
    pub fn pixel(&self, x: usize, y: usize) -> Option<PixelReuse<'_>> {
        let band = &self.bands[y / BAND_ROWS];
        match band.plans[(y % BAND_ROWS) * self.width + x] {
            Plan::Trace => None,
            Plan::Miss => Some(PixelReuse::Miss),
            Plan::Radiance(v) => Some(PixelReuse::Radiance(v)),
            Plan::Hits {
                lit,
                shadowed,
                first,
                len,
            } => Some(PixelReuse::Hits(HitReuse {
                candidates: &band.candidates[first as usize..first as usize + len as usize],
                lit,
                shadowed,
            })),
        }
    }
}

/// Rule 3: the target columns `lo..hi` that may reuse, given the parallax (target x minus
/// source x, pixels) of the scene's nearest possible point. A negative parallax moves near
/// points left in the target, so its right strip shows what lies beyond the source's right
/// edge; a positive one the left strip.
fn edge_strips(nearest_parallax: f32, width: usize) -> Range<usize> {
    if !nearest_parallax.is_finite() {
        return 0..0;
    }
    let strip = nearest_parallax.abs().ceil().min(width as f32) as usize;
    if nearest_parallax < 0.0 {
        0..width - strip
    } else {
        strip..width
    }
}

impl HitReuse<'_> {
    /// Rule 4 for up to four of the pixel's samples (the rays whose bit is set in `active`):
    /// the nearest candidate each ray hits within its `t_max`, with the window's shadow answers;
    /// `None` where it hits none. Four rays share each triangle test.
    pub fn verify4(
        &self,
        rays: [Ray; 4],
        active: u32,
        t_max: [f32; 4],
        geometry: &Geometry,
    ) -> [Option<KnownHit>; 4] {
        let candidates = (self.candidates.iter()).map(|&p| (p, geometry.triangle(p as usize)));
        triangle::nearest4(rays, active, t_max, candidates).map(|hit| {
            hit.map(|hit| KnownHit {
                hit,
                lit: self.lit,
                shadowed: self.shadowed,
            })
        })
    }
}

#[cfg(test)]
mod tests;
