//! What the source view keeps of each pixel for the views that reuse it: the pixel's camera
//! samples folded into one record while the pixel is traced. A target view then reads one
//! record per pixel whatever the samples per pixel (64 bytes, one cache line, against 48 per
//! sample when every sample was kept: 192 bytes a pixel at 4 spp, 768 at 16).

use super::super::integrator::PrimaryRecord;
use super::MAX_PARALLAX_SPREAD;
use super::plane::{self, PLANE_SAMPLES, ShadedSample};
use glam::Vec3;

/// Distinct triangles a source pixel remembers. A pixel that saw more is marked, and the target
/// pixels it lands near trace their camera rays (their candidates would be incomplete).
pub const PIXEL_SLOTS: usize = 4;

/// One source pixel's camera samples, folded (64 bytes, on a cache line of its own).
#[derive(Clone, Copy, Debug)]
#[repr(align(64))]
pub struct SourcePixel {
    /// Smallest and largest inverse depth (1 / metres along the rig's axis) of the samples
    /// that hit: their parallax range in any other eye of the rig.
    pub(super) inv_depth: [f32; 2],
    /// Where in the pixel its landing samples (hits and misses) lie along x, in 255ths of a
    /// pixel, rounded outwards: at 1 spp the pixel lands as a point, as its sample does.
    pub(super) film_x: [u8; 2],
    /// Samples that hit, and samples that missed everything. Samples whose ray passed a MASK
    /// cut-out are neither: the other eye may see a bar where this one saw a hole, so they
    /// land nowhere.
    pub(super) hits: u16,
    pub(super) misses: u16,
    pub(super) prims: [u32; PIXEL_SLOTS],
    pub(super) distinct: u8,
    /// More than `PIXEL_SLOTS` triangles were hit: the pixel keeps its samples (`edge`).
    pub(super) overflow: bool,
    /// Lights some hit reached, and lights some hit was shadowed from.
    pub(super) lit: u32,
    pub(super) shadowed: u32,
    /// The smallest highlight lobe width times distance from the eye over the hits (radians
    /// times metres): another eye at `baseline` metres sees each hit within
    /// `baseline / reach` of its lobe width. Negative where a hit's radiance cannot stand for
    /// another view's (mirror, glass, BLEND, MASK: `PrimaryRecord::lobe`).
    pub(super) reach: f32,
    /// The hits' radiance at the pixel's centre and its bound (`plane::PixelRadiance`): a
    /// plane's where `plane()`, else the hits' mean and how far any lies from it.
    pub(super) radiance: Vec3,
    pub(super) radiance_bound: f32,
    /// A pixel across a depth edge (or that hit more triangles than it holds) keeps its landing
    /// samples: `edge..edge + landed()` of its tile's `EdgeSample`s. `u32::MAX` elsewhere.
    pub(super) edge: u32,
}

/// `SourcePixel::edge` of a pixel that keeps no samples.
const NO_EDGE: u32 = u32::MAX;

/// A landing sample of a pixel across a depth edge: its film x within the pixel (0..1), its
/// hit's inverse depth (0 for a miss, which lands at infinity) and triangle. The sample brings
/// only its own triangle where it lands: a triangle of the far side among a near surface's
/// candidates would be hit behind it by a ray whose own triangle is missing.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct EdgeSample {
    pub film_x: f32,
    pub inv_depth: f32,
    pub prim: u32,
}

/// Which source pixels are depth edges: those whose samples' parallax in some view that reuses
/// them spreads over more than `MAX_PARALLAX_SPREAD`. Such a pixel's samples land apart (a
/// hole may open between them), so it keeps them; elsewhere the pixel lands as one span.
#[derive(Clone, Copy, Debug)]
pub struct EdgeTest {
    /// The largest parallax change per unit of inverse depth among the views that reuse (`b`
    /// of `EyeCamera::parallax_line`, in absolute value), pixels times metres.
    pub parallax_per_inv_depth: f32,
    /// Misses land too (no far plane).
    pub misses_land: bool,
}

impl Default for SourcePixel {
    fn default() -> SourcePixel {
        SourcePixel {
            inv_depth: [f32::INFINITY, f32::NEG_INFINITY],
            film_x: [u8::MAX, 0],
            hits: 0,
            misses: 0,
            prims: [0; PIXEL_SLOTS],
            distinct: 0,
            overflow: false,
            lit: 0,
            shadowed: 0,
            reach: f32::INFINITY,
            radiance: Vec3::ZERO,
            radiance_bound: 0.0,
            edge: NO_EDGE,
        }
    }
}

impl SourcePixel {
    /// Adds a camera sample: where it lies in the pixel along x (0..1), what its ray found,
    /// and (for a hit) the hit's depth along the rig's axis and distance from the eye. The
    /// hits' radiance is set from their samples once the pixel is done (`plane::fit`).
    pub(super) fn add(&mut self, sample: Sample, record: &PrimaryRecord) {
        if record.through_cut_out {
            return;
        }
        // Rounded down and up by truncation (x >= 0), not libm's floor and ceil.
        let x = sample.film_x.clamp(0.0, 1.0) * 255.0;
        let below = x as u8;
        let above = below + u8::from(f32::from(below) < x);
        self.film_x = [self.film_x[0].min(below), self.film_x[1].max(above)];
        let Some(hit) = record.hit else {
            self.misses = self.misses.saturating_add(1);
            return;
        };
        self.hits = self.hits.saturating_add(1);
        let inv = 1.0 / sample.depth;
        self.inv_depth = [self.inv_depth[0].min(inv), self.inv_depth[1].max(inv)];
        let n = self.distinct as usize;
        if !self.prims[..n].contains(&hit.prim) {
            if n < PIXEL_SLOTS {
                self.prims[n] = hit.prim;
                self.distinct += 1;
            } else {
                self.overflow = true;
            }
        }
        self.lit |= record.lit;
        self.shadowed |= record.shadowed;
        let reach = if record.lobe >= 0.0 {
            record.lobe * sample.distance
        } else {
            -1.0
        };
        self.reach = self.reach.min(reach);
    }

    /// Whether its radiance is a plane's (enough hits to test one): see `plane.rs`.
    pub(super) fn plane(&self) -> bool {
        usize::from(self.hits) >= PLANE_SAMPLES
    }

    /// Samples that landed: hits and misses.
    pub(super) fn landed(&self) -> usize {
        usize::from(self.hits) + usize::from(self.misses)
    }

    /// The samples it keeps, if any: `(first, count)` in its tile's `EdgeSample`s.
    pub(super) fn edge_samples(&self) -> Option<(usize, usize)> {
        (self.edge != NO_EDGE).then(|| (self.edge as usize, self.landed()))
    }
}

/// Where a camera sample lies: its film x and y within its pixel (0..1), and its hit's depth
/// along the rig's axis and distance from the eye (unused for a miss).
#[derive(Clone, Copy, Debug)]
pub struct Sample {
    pub film_x: f32,
    pub film_y: f32,
    pub depth: f32,
    pub distance: f32,
}

impl SourcePixel {
    /// The span along x where the pixel's landing samples lie, as offsets from its left edge.
    pub(super) fn film_span(&self) -> (f32, f32) {
        (
            f32::from(self.film_x[0]) / 255.0,
            f32::from(self.film_x[1]) / 255.0,
        )
    }
}

/// One tile of source pixels, row-major, as the tile is traced.
pub struct SourceTile {
    pixels: Vec<SourcePixel>,
    /// Every hit sample's place and radiance, `spp` per pixel, until the tile is done.
    shaded: Vec<ShadedSample>,
    /// Every landing sample of the tile, `spp` per pixel, until the tile is done.
    samples: Vec<EdgeSample>,
    spp: usize,
    edge_test: EdgeTest,
    nearest_inv_depth: f32,
}

impl SourceTile {
    pub fn new(pixels: usize, spp: usize, edge_test: EdgeTest) -> SourceTile {
        SourceTile {
            pixels: vec![SourcePixel::default(); pixels],
            shaded: vec![ShadedSample::default(); pixels * spp],
            samples: vec![EdgeSample::default(); pixels * spp],
            spp,
            edge_test,
            nearest_inv_depth: f32::NEG_INFINITY,
        }
    }

    /// Adds a camera sample of pixel `i` and its radiance (see `SourcePixel::add`).
    pub fn add(&mut self, i: usize, sample: Sample, record: &PrimaryRecord, radiance: Vec3) {
        let p = &mut self.pixels[i];
        let (landed, hits) = (p.landed(), usize::from(p.hits));
        p.add(sample, record);
        if usize::from(p.hits) > hits && hits < self.spp {
            self.shaded[i * self.spp + hits] = ShadedSample {
                x: sample.film_x,
                y: sample.film_y,
                radiance,
            };
        }
        if p.landed() > landed && landed < self.spp {
            let (inv_depth, prim) = match record.hit {
                Some(h) => (1.0 / sample.depth, h.prim),
                None => (0.0, 0),
            };
            self.samples[i * self.spp + landed] = EdgeSample {
                film_x: sample.film_x,
                inv_depth,
                prim,
            };
        }
        if p.hits > 0 {
            self.nearest_inv_depth = self.nearest_inv_depth.max(p.inv_depth[1]);
        }
    }

    /// The tile done: its pixels' radiance fitted, and the samples of those across a depth
    /// edge kept.
    pub fn finish(mut self) -> FinishedTile {
        let mut edges = Vec::new();
        let test = self.edge_test;
        for (i, p) in self.pixels.iter_mut().enumerate() {
            if p.hits > 0 {
                let first = i * self.spp;
                let hits = usize::from(p.hits).min(self.spp);
                let fitted = plane::fit(&self.shaded[first..first + hits], self.spp);
                // The record is read as a plane wherever it has the samples for one
                // (`SourcePixel::plane`); where they all lie on one line the gradient across it
                // is unknown, and the pixel lends no radiance.
                let bound = match fitted.plane == p.plane() {
                    true => fitted.bound,
                    false => f32::INFINITY,
                };
                (p.radiance, p.radiance_bound) = (fitted.value, bound);
            }
            let mut nearest = p.inv_depth[0];
            if p.misses > 0 && test.misses_land {
                nearest = 0.0;
            }
            let parallax = test.parallax_per_inv_depth * (p.inv_depth[1] - nearest);
            if p.hits > 0 && (parallax > MAX_PARALLAX_SPREAD || p.overflow) {
                let n = p.landed().min(self.spp);
                p.edge = edges.len() as u32;
                edges.extend_from_slice(&self.samples[i * self.spp..i * self.spp + n]);
            }
        }
        FinishedTile {
            pixels: self.pixels,
            edges,
            nearest_inv_depth: self.nearest_inv_depth,
        }
    }
}

/// A source tile's pixels, the samples of those across a depth edge, and the largest inverse
/// depth it hit.
pub struct FinishedTile {
    pixels: Vec<SourcePixel>,
    edges: Vec<EdgeSample>,
    nearest_inv_depth: f32,
}

/// The source view's pixels as its tiles made them (`tile` x `tile` pixels each, in row-major
/// tile order), and the largest inverse depth any of them hit.
pub struct SourcePixels {
    width: usize,
    height: usize,
    tile: usize,
    tiles: Vec<FinishedTile>,
    nearest_inv_depth: f32,
    spp: usize,
}

impl SourcePixels {
    /// The finished `tile` x `tile` tiles of a film of `width` x `height` traced at `spp`.
    pub fn new(
        tiles: Vec<FinishedTile>,
        (width, height): (usize, usize),
        tile: usize,
        spp: usize,
    ) -> SourcePixels {
        assert_eq!(tiles.len(), width.div_ceil(tile) * height.div_ceil(tile));
        let nearest_inv_depth = tiles
            .iter()
            .fold(f32::NEG_INFINITY, |m, t| m.max(t.nearest_inv_depth));
        SourcePixels {
            width,
            height,
            tile,
            tiles,
            nearest_inv_depth,
            spp,
        }
    }

    /// Samples per pixel.
    pub fn spp(&self) -> usize {
        self.spp
    }

    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The nearest depth a sample hit, metres (infinite when nothing was hit).
    pub fn nearest_depth(&self) -> f32 {
        1.0 / self.nearest_inv_depth.max(0.0)
    }

    /// Row `y`, left to right, as (first column, pixels, their tile's edge samples) runs, one
    /// per tile.
    pub(super) fn row(
        &self,
        y: usize,
    ) -> impl Iterator<Item = (usize, &[SourcePixel], &[EdgeSample])> {
        let tiles_x = self.width.div_ceil(self.tile);
        let (ty, ry) = (y / self.tile, y % self.tile);
        (0..tiles_x).map(move |tx| {
            let x0 = tx * self.tile;
            let tw = (x0 + self.tile).min(self.width) - x0;
            let FinishedTile { pixels, edges, .. } = &self.tiles[ty * tiles_x + tx];
            (x0, &pixels[ry * tw..(ry + 1) * tw], edges.as_slice())
        })
    }
}

// A record per cache line: `land_row` waits on its loads.
const _: () = assert!(std::mem::size_of::<SourcePixel>() == 64);
