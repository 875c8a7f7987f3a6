//! What the source view keeps of each pixel for the views that reuse it: the pixel's camera
//! samples folded into one record while the pixel is traced. A target view then reads one
//! record per pixel whatever the samples per pixel (80 bytes, against 48 per sample when every
//! sample was kept: 192 bytes a pixel at 4 spp, 768 at 16).

use super::super::integrator::PrimaryRecord;
use super::MAX_PARALLAX_SPREAD;
use glam::Vec3;

/// Distinct triangles a source pixel remembers. A pixel that saw more is marked, and the target
/// pixels it lands near trace their camera rays (their candidates would be incomplete).
pub const PIXEL_SLOTS: usize = 4;

/// One source pixel's camera samples, folded.
#[derive(Clone, Copy, Debug)]
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
    /// More than `PIXEL_SLOTS` triangles were hit.
    pub(super) overflow: bool,
    /// Lights some hit reached, and lights some hit was shadowed from.
    pub(super) lit: u32,
    pub(super) shadowed: u32,
    /// The smallest highlight lobe width times distance from the eye over the hits (radians
    /// times metres): another eye at `baseline` metres sees each hit within
    /// `baseline / reach` of its lobe width. Negative where a hit's radiance cannot stand for
    /// another view's (mirror, glass, BLEND, MASK: `PrimaryRecord::lobe`).
    pub(super) reach: f32,
    /// The hits' radiance summed, and its range per channel.
    pub(super) radiance: Vec3,
    pub(super) radiance_lo: Vec3,
    pub(super) radiance_hi: Vec3,
    /// A pixel across a depth edge keeps its landing samples: `edge[0]..edge[0] + edge[1]` of
    /// its tile's `EdgeSample`s (none elsewhere).
    pub(super) edge: [u32; 2],
}

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
            radiance_lo: Vec3::INFINITY,
            radiance_hi: Vec3::NEG_INFINITY,
            edge: [0, 0],
        }
    }
}

impl SourcePixel {
    /// Adds a camera sample: where it lies in the pixel along x (0..1), what its ray found,
    /// its radiance, and (for a hit) the hit's depth along the rig's axis and distance from the
    /// eye.
    pub fn add(&mut self, sample: Sample, record: &PrimaryRecord, radiance: Vec3) {
        if record.through_cut_out {
            return;
        }
        let x = sample.film_x.clamp(0.0, 1.0) * 255.0;
        self.film_x = [
            self.film_x[0].min(x.floor() as u8),
            self.film_x[1].max(x.ceil() as u8),
        ];
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
        self.radiance += radiance;
        self.radiance_lo = self.radiance_lo.min(radiance);
        self.radiance_hi = self.radiance_hi.max(radiance);
    }
}

/// Where a camera sample lies: its film x within its pixel (0..1), and its hit's depth along
/// the rig's axis and distance from the eye (unused for a miss).
#[derive(Clone, Copy, Debug)]
pub struct Sample {
    pub film_x: f32,
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
            samples: vec![EdgeSample::default(); pixels * spp],
            spp,
            edge_test,
            nearest_inv_depth: f32::NEG_INFINITY,
        }
    }

    /// Adds a camera sample of pixel `i` (see `SourcePixel::add`).
    pub fn add(&mut self, i: usize, sample: Sample, record: &PrimaryRecord, radiance: Vec3) {
        let p = &mut self.pixels[i];
        let landed = usize::from(p.hits) + usize::from(p.misses);
        p.add(sample, record, radiance);
        if usize::from(p.hits) + usize::from(p.misses) > landed && landed < self.spp {
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

    /// The tile's pixels, and the samples of those across a depth edge.
    fn finish(mut self) -> (Vec<SourcePixel>, Vec<EdgeSample>) {
        let mut edges = Vec::new();
        let test = self.edge_test;
        for (i, p) in self.pixels.iter_mut().enumerate() {
            let mut lo = p.inv_depth[0];
            if p.misses > 0 && test.misses_land {
                lo = 0.0;
            }
            let spread = test.parallax_per_inv_depth * (p.inv_depth[1] - lo);
            if p.hits > 0 && (spread > MAX_PARALLAX_SPREAD || p.overflow) {
                let n = (usize::from(p.hits) + usize::from(p.misses)).min(self.spp);
                p.edge = [edges.len() as u32, n as u32];
                edges.extend_from_slice(&self.samples[i * self.spp..i * self.spp + n]);
            }
        }
        self.samples = Vec::new();
        (self.pixels, edges)
    }
}

/// The source view's pixels as its tiles made them (`tile` x `tile` pixels each, in row-major
/// tile order), and the largest inverse depth any of them hit.
pub struct SourcePixels {
    width: usize,
    height: usize,
    tile: usize,
    tiles: Vec<(Vec<SourcePixel>, Vec<EdgeSample>)>,
    nearest_inv_depth: f32,
}

impl SourcePixels {
    pub fn new(
        tiles: Vec<SourceTile>,
        (width, height): (usize, usize),
        tile: usize,
    ) -> SourcePixels {
        assert_eq!(tiles.len(), width.div_ceil(tile) * height.div_ceil(tile));
        let nearest_inv_depth = tiles
            .iter()
            .fold(f32::NEG_INFINITY, |m, t| m.max(t.nearest_inv_depth));
        SourcePixels {
            width,
            height,
            tile,
            tiles: tiles.into_iter().map(SourceTile::finish).collect(),
            nearest_inv_depth,
        }
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
            let (pixels, edges) = &self.tiles[ty * tiles_x + tx];
            (x0, &pixels[ry * tw..(ry + 1) * tw], edges.as_slice())
        })
    }
}
