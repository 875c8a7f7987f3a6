//! `eye_reuse = "reproject"`: a second view borrows the primary hits of the first (Adelson and
//! Hodges, "Stereoscopic ray-tracing", 1993). Every camera sample of the source view that hit
//! something is projected into the target view's film; a target sample then takes a
//! reprojected hit instead of tracing its own camera ray when the rule below holds, and
//! otherwise traces in full.
//!
//! The rule, for a target pixel, over the reprojected samples in a window of 5x3 pixels around
//! it:
//! 1. **Nothing revealed.** Every pixel of the window has a reprojected sample in it or in a
//!    horizontal neighbour. A surface the source view cannot see shows up in the target as a
//!    run of empty pixels (a disocclusion hole); an isolated empty pixel is only sampling.
//! 2. **No step in depth.** In each row of the window, the parallax of the samples (target x
//!    minus source x) spreads over at most `MAX_PARALLAX_SPREAD` pixels. The rigs this runs on
//!    (off-axis, parallel) move points along their own row only, so a row is where a hole opens:
//!    where a near object passes in front of a far one the spread is the difference of their
//!    parallaxes, and a hole can hide between samples only where it is narrower than that. A
//!    slanted floor, whose parallax changes from row to row but smoothly along a row, reuses.
//! 3. **Not at the frame edge the source cannot see.** Near objects shift sideways between the
//!    views; a strip as wide as the largest parallax of the scene's nearest point (from its
//!    bounds) on that side of the target film is traced.
//! 4. **A verified hit.** The triangles hit by samples within one pixel of the target pixel are
//!    the candidates; the target sample's own ray is intersected with each (the same watertight
//!    test the tree uses) and the nearest hit is its primary hit. No candidate hit: it traces.
//!
//! Shading is then computed for the target's own ray (its view direction, its texture
//! coordinates), and mirror and glass rays are traced from the hit. A light's shadow answer is
//! reused only where every sample of the window that asked that light got the same answer
//! (shadow edges are traced). A reused hit is exact whenever the nearest surface along the ray
//! was seen by the source near there; the error left is where it was not (a surface seen by
//! the target alone, thinner than the rules can see) and shadow detail finer than the samples.

use super::camera::EyeCamera;
use super::integrator::{KnownHit, PrimaryRecord};
use crate::accel::{Hit, Ray, triangle};
use crate::scene::pose::Geometry;
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use smallvec::SmallVec;

/// A source-view camera sample: its film position and what it found.
#[derive(Clone, Copy, Debug)]
pub struct SourceSample {
    film: Vec2,
    /// The hit point, or for a miss the ray's direction.
    point: Vec3,
    /// The triangle hit, or `MISS`.
    prim: u32,
    lit: u32,
    shadowed: u32,
    lobe: f32,
    radiance: Vec3,
}

/// `SourceSample::prim` of a sample that hit nothing.
const MISS: u32 = u32::MAX;
/// `SourceSample::prim` of a sample whose camera ray passed a MASK cut-out: it lands nowhere,
/// so the target traces around it (the other eye may see a bar where this one saw a hole).
const THROUGH_CUT_OUT: u32 = u32::MAX - 1;

impl SourceSample {
    pub fn new(film: Vec2, ray: &Ray, record: &PrimaryRecord, radiance: Vec3) -> SourceSample {
        let (point, prim) = match record.hit {
            _ if record.through_cut_out => (record.point, THROUGH_CUT_OUT),
            Some(h) => (record.point, h.prim),
            None => (ray.dir, MISS),
        };
        SourceSample {
            film,
            point,
            prim,
            lit: record.lit,
            shadowed: record.shadowed,
            lobe: record.lobe,
            radiance,
        }
    }
}

/// `"reproject-radiance"`: the angle between the eyes' view directions may be at most this
/// fraction of a surface's GGX lobe width. At a tenth of the width the half vector moves by a
/// twentieth of it, which changes the GGX distribution by about 0.5% at its peak (`D` falls as
/// `(1 + d^2 / alpha^2)^-2` with the angle `d` off the peak).
pub const LOBE_FRACTION: f32 = 0.1;

/// `"reproject-radiance"`: the largest spread of the reused samples' radiance over a pixel and
/// its row neighbours, per channel (the per-channel error `compare --fail` counts, 0.02).
pub const RADIANCE_SPREAD: f32 = 0.02;

/// Rule 2's bound, pixels: a disocclusion narrower than half a pixel hides at most part of a
/// sample's footprint.
pub const MAX_PARALLAX_SPREAD: f32 = 0.5;
/// Half-widths of rule 1-2's window (5x3) and of rule 4's candidate window (3x3).
const WINDOW_X: usize = 2;
const WINDOW_Y: usize = 1;
const CANDIDATE_X: usize = 1;
/// Distinct triangles a pixel remembers (the first seen), and candidates a target pixel tests.
/// A triangle left out can only matter where two surfaces lie within rule 2's bound of each
/// other along the ray (a decal, a thin shell); elsewhere the ray's own surface is among the
/// candidates or the sample traces.
const SLOTS: usize = 8;
const MAX_CANDIDATES: usize = 24;

/// A sample that landed outside its band of rows: (tile, index in the tile, film position).
type Stray = (usize, usize, Vec2);

/// The reprojected samples that landed in one target pixel.
#[derive(Clone, Copy)]
struct Cell {
    count: u32,
    prims: [u32; SLOTS],
    distinct: u8,
    parallax_min: f32,
    parallax_max: f32,
    lit: u32,
    shadowed: u32,
    /// Samples whose radiance may stand for the target's, the sum of their radiance in
    /// arrival order, and its smallest and largest value per channel.
    direct: u32,
    radiance: Vec3,
    radiance_min: Vec3,
    radiance_max: Vec3,
}

impl Default for Cell {
    fn default() -> Cell {
        Cell {
            count: 0,
            prims: [0; SLOTS],
            distinct: 0,
            parallax_min: f32::INFINITY,
            parallax_max: f32::NEG_INFINITY,
            lit: 0,
            shadowed: 0,
            direct: 0,
            radiance: Vec3::ZERO,
            radiance_min: Vec3::INFINITY,
            radiance_max: Vec3::NEG_INFINITY,
        }
    }
}

impl Cell {
    /// Adds a sample; `radiance_ok` says whether its radiance may stand for the target's.
    fn add(&mut self, s: &SourceSample, parallax: f32, radiance_ok: bool) {
        let (prim, lit, shadowed) = (s.prim, s.lit, s.shadowed);
        if radiance_ok && prim != MISS {
            self.direct += 1;
            self.radiance += s.radiance;
            self.radiance_min = self.radiance_min.min(s.radiance);
            self.radiance_max = self.radiance_max.max(s.radiance);
        }
        self.count += 1;
        self.parallax_min = self.parallax_min.min(parallax);
        self.parallax_max = self.parallax_max.max(parallax);
        self.lit |= lit;
        self.shadowed |= shadowed;
        let n = self.distinct as usize;
        if prim != MISS && n < SLOTS && !self.prims[..n].contains(&prim) {
            self.prims[n] = prim;
            self.distinct += 1;
        }
    }
}

/// The source view's hits as the target film sees them.
pub struct Reprojection {
    width: usize,
    height: usize,
    /// Rows `b * band_rows..` of the target film are `bands[b]`.
    band_rows: usize,
    bands: Vec<Band>,
    /// Rule 3: target columns `x_lo..x_hi` may reuse.
    x_lo: usize,
    x_hi: usize,
}

/// A band of target rows: its cells, and rules 1 and 2 on the five pixels of a row centred on
/// each pixel. Each band is allocated and filled by the thread that fills it: one film-sized
/// allocation would be written (and its pages faulted in) by one thread alone.
struct Band {
    cells: Vec<Cell>,
    rows: Vec<RowWindow>,
}

/// What a target pixel may reuse.
pub enum PixelReuse {
    /// Every source sample around it missed: its rays miss too (the background).
    Miss,
    /// `"reproject-radiance"`: the pixel's value.
    Radiance(Vec3),
    /// Triangles for each sample's own ray to verify, and the window's shadow answers.
    Hits(HitReuse),
}

/// Candidate triangles of a pixel and the shadow answers of its window.
pub struct HitReuse {
    candidates: SmallVec<[u32; MAX_CANDIDATES]>,
    lit: u32,
    shadowed: u32,
}

impl Reprojection {
    /// Projects the source view's samples, `tiles` of `tile` x `tile` pixels in row-major tile
    /// order, from `source` into `target`'s film of `width` x `height`. Misses are projected at
    /// infinity when `misses` (no far plane: a miss is a miss at every distance); `radiance`
    /// lets rough pixels take their samples' mean radiance (`"reproject-radiance"`).
    pub fn new(
        tiles: &[Vec<SourceSample>],
        source: &EyeCamera,
        target: &EyeCamera,
        (width, height): (usize, usize),
        tile: usize,
        misses: bool,
        radiance: bool,
    ) -> Reprojection {
        let to_target = target.film_matrix();
        // A point's depth in the source eye's frame: W of its film projection.
        let source_depth = source.film_matrix().row(3);
        // Where a sample lands: its target pixel (or `None` off the film) and film position.
        let land = |s: &SourceSample| -> Option<(usize, Vec2)> {
            let h = match s.prim {
                MISS if misses => to_target * s.point.extend(0.0),
                MISS | THROUGH_CUT_OUT => return None,
                _ => to_target * s.point.extend(1.0),
            };
            let q = Vec2::new(h.x / h.w, h.y / h.w);
            // Written so that NaN (and W <= 0: behind the eye) lands outside.
            let inside =
                h.w > 0.0 && q.x >= 0.0 && q.x < width as f32 && q.y >= 0.0 && q.y < height as f32;
            inside.then(|| (q.y as usize * width + q.x as usize, q))
        };
        // The rigs this runs on keep a point's film row, so the samples of a band of tile rows
        // land in the same band of target rows: bands fill their cells in parallel, in source
        // order, and the few samples that rounding moves across a band edge follow, in source
        // order too. The result does not depend on the thread count.
        // "reproject-radiance": a sample's radiance stands for the target's where the angle
        // between the two eyes' view directions at its point (baseline over distance) is at
        // most `LOBE_FRACTION` of its highlight lobe's width.
        let (eye, baseline_sq) = (
            source.position(),
            (target.position() - source.position()).length_squared(),
        );
        let radiance_ok = |s: &SourceSample| {
            radiance
                && s.lobe >= 0.0
                && baseline_sq
                    <= (LOBE_FRACTION * s.lobe).powi(2) * (s.point - eye).length_squared()
        };
        let tiles_x = width.div_ceil(tile);
        let band_len = tile * width;
        let filled: Vec<(Vec<Cell>, Vec<Stray>, f32)> = tiles
            .par_chunks(tiles_x)
            .enumerate()
            .map(|(b, band_tiles)| {
                let mut band = vec![Cell::default(); band_len.min(width * height - b * band_len)];
                let mut strays = Vec::new();
                let mut nearest = f32::INFINITY;
                for (t, tile) in band_tiles.iter().enumerate() {
                    for (k, sample) in tile.iter().enumerate() {
                        if sample.prim != MISS && sample.prim != THROUGH_CUT_OUT {
                            nearest = nearest.min(source_depth.dot(sample.point.extend(1.0)));
                        }
                        let Some((i, q)) = land(sample) else {
                            continue;
                        };
                        match i.checked_sub(b * band_len).filter(|&j| j < band.len()) {
                            Some(j) => {
                                band[j].add(sample, q.x - sample.film.x, radiance_ok(sample))
                            }
                            None => strays.push((b * tiles_x + t, k, q)),
                        }
                    }
                }
                (band, strays, nearest)
            })
            .collect();
        let mut nearest = f32::INFINITY;
        let mut cells = Vec::with_capacity(filled.len());
        let mut strays = Vec::new();
        for (band, band_strays, band_nearest) in filled {
            nearest = nearest.min(band_nearest);
            cells.push(band);
            strays.push(band_strays);
        }
        for &(t, k, q) in strays.iter().flatten() {
            let sample = &tiles[t][k];
            let i = q.y as usize * width + q.x as usize;
            cells[i / band_len][i % band_len].add(sample, q.x - sample.film.x, radiance_ok(sample));
        }
        let bands = cells
            .into_par_iter()
            .map(|cells| Band {
                rows: row_windows(&cells, width, radiance),
                cells,
            })
            .collect();
        // Rule 3 from the nearest depth the source saw.
        let nearest = nearest.max(source.znear());
        let (x_lo, x_hi) = if nearest.is_finite() {
            let p = source.axis_point(nearest);
            match (target.project(p), source.project(p)) {
                (Some(t), Some(s)) => edge_strips(t.x - s.x, width),
                _ => (0, 0),
            }
        } else {
            (0, 0)
        };
        Reprojection {
            width,
            height,
            band_rows: tile,
            bands,
            x_lo,
            x_hi,
        }
    }

    /// Row `y`'s cells and row windows.
    fn row(&self, y: usize) -> (&[Cell], &[RowWindow]) {
        let band = &self.bands[y / self.band_rows];
        let at = (y % self.band_rows) * self.width..(y % self.band_rows + 1) * self.width;
        (&band.cells[at.clone()], &band.rows[at])
    }

    /// What the target pixel (x, y) may reuse, or `None` where it must trace (rules 1-3, and no
    /// candidate).
    pub fn pixel(&self, x: usize, y: usize) -> Option<PixelReuse> {
        if y < WINDOW_Y
            || y + WINDOW_Y >= self.height
            || x < self.x_lo + WINDOW_X
            || x + WINDOW_X >= self.x_hi
        {
            return None;
        }
        let (mut lit, mut shadowed, mut hits) = (0u32, 0u32, false);
        for cy in y - WINDOW_Y..=y + WINDOW_Y {
            let r = &self.row(cy).1[x];
            if !r.ok {
                return None;
            }
            lit |= r.lit;
            shadowed |= r.shadowed;
            hits |= r.hits;
        }
        let shadows_agree = lit & shadowed == 0;
        if shadows_agree && let Some(v) = self.row(y).1[x].radiance {
            return Some(PixelReuse::Radiance(v));
        }
        // Rule 1 holds, so the candidate pixels hold samples: with no triangle among them,
        // they all missed.
        if !hits {
            return Some(PixelReuse::Miss);
        }
        let mut candidates = SmallVec::new();
        for cy in y - WINDOW_Y..=y + WINDOW_Y {
            for c in &self.row(cy).0[x - CANDIDATE_X..=x + CANDIDATE_X] {
                for &prim in &c.prims[..c.distinct as usize] {
                    if candidates.len() < MAX_CANDIDATES && !candidates.contains(&prim) {
                        candidates.push(prim);
                    }
                }
            }
        }
        Some(PixelReuse::Hits(HitReuse {
            candidates,
            lit: lit & !shadowed,
            shadowed: shadowed & !lit,
        }))
    }
}

/// What one pixel's row contributes to the rules: whether the five pixels centred on it are all
/// covered (rule 1) and keep their parallax within the bound (rule 2), the union of their
/// samples' shadow answers, whether the three candidate pixels hold a triangle, and under
/// `"reproject-radiance"` the pixel's value where its row allows one (`row_radiance`).
/// Deciding these here, row by row, lets a target pixel read three of these instead of its
/// window's cells.
#[derive(Clone, Copy, Default)]
struct RowWindow {
    ok: bool,
    hits: bool,
    lit: u32,
    shadowed: u32,
    radiance: Option<Vec3>,
}

/// `RowWindow` for every pixel of the rows `cells`; `radiance` under `"reproject-radiance"`.
fn row_windows(cells: &[Cell], width: usize, radiance: bool) -> Vec<RowWindow> {
    let mut rows = vec![RowWindow::default(); cells.len()];
    rows.chunks_mut(width)
        .zip(cells.chunks(width))
        .for_each(|(out, row)| {
            // Rule 1: the pixel or a horizontal neighbour holds a sample.
            let covered = |x: usize| {
                row[x.saturating_sub(1)..(x + 2).min(width)]
                    .iter()
                    .any(|c| c.count > 0)
            };
            for x in WINDOW_X..width.saturating_sub(WINDOW_X) {
                let window = &row[x - WINDOW_X..=x + WINDOW_X];
                let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
                let (mut lit, mut shadowed) = (0, 0);
                for c in window.iter().filter(|c| c.count > 0) {
                    lo = lo.min(c.parallax_min);
                    hi = hi.max(c.parallax_max);
                    lit |= c.lit;
                    shadowed |= c.shadowed;
                }
                let spread = hi - lo;
                let ok = (x - WINDOW_X..=x + WINDOW_X).all(covered)
                    && !(spread > MAX_PARALLAX_SPREAD || spread.is_nan());
                let candidates = &row[x - CANDIDATE_X..=x + CANDIDATE_X];
                out[x] = RowWindow {
                    ok,
                    hits: candidates.iter().any(|c| c.distinct > 0),
                    lit,
                    shadowed,
                    radiance: (radiance && ok).then(|| row_radiance(row, x)).flatten(),
                };
            }
        });
    rows
}

/// `"reproject-radiance"`: the mean radiance of the source samples that landed in pixel `x` of
/// `row` (Adelson and Hodges' reuse of the colour), where the samples of the pixel and of its
/// two neighbours in the row all may stand for the target's and agree within
/// `RADIANCE_SPREAD` per channel: a flat patch, where where a sample sits in the pixel does not
/// matter. The pixel also needs its window to pass the rules and agree on every shadow.
fn row_radiance(row: &[Cell], x: usize) -> Option<Vec3> {
    let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for c in &row[x - 1..=x + 1] {
        if c.direct == 0 || c.direct != c.count {
            return None;
        }
        lo = lo.min(c.radiance_min);
        hi = hi.max(c.radiance_max);
    }
    let flat = (hi - lo).max_element() <= RADIANCE_SPREAD;
    let c = &row[x];
    flat.then(|| c.radiance / c.direct as f32)
}

/// Rule 3: the target columns `lo..hi` that may reuse, given the parallax (target x minus
/// source x, pixels) of the scene's nearest possible point. A negative parallax moves near
/// points left in the target, so its right strip shows what lies beyond the source's right
/// edge; a positive one the left strip.
fn edge_strips(nearest_parallax: f32, width: usize) -> (usize, usize) {
    if !nearest_parallax.is_finite() {
        return (0, 0);
    }
    let strip = nearest_parallax.abs().ceil().min(width as f32) as usize;
    if nearest_parallax < 0.0 {
        (0, width - strip)
    } else {
        (strip, width)
    }
}

impl HitReuse {
    /// Rule 4: the nearest candidate the ray hits within `t_max`, with the window's shadow
    /// answers; `None` when it hits none.
    pub fn verify(&self, ray: &Ray, t_max: f32, geometry: &Geometry) -> Option<KnownHit> {
        let pre = triangle::RayPre::new(ray);
        let mut best: Option<Hit> = None;
        let mut t_best = t_max;
        for &prim in &self.candidates {
            let tri = geometry.triangle(prim as usize);
            if let Some((t, b1, b2)) = triangle::intersect(&pre, &tri, t_best) {
                t_best = t;
                best = Some(Hit { t, prim, b1, b2 });
            }
        }
        best.map(|hit| KnownHit {
            hit,
            lit: self.lit,
            shadowed: self.shadowed,
        })
    }
}

#[cfg(test)]
mod tests;
