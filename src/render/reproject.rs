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

impl SourceSample {
    pub fn new(film: Vec2, ray: &Ray, record: &PrimaryRecord, radiance: Vec3) -> SourceSample {
        let (point, prim) = match record.hit {
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
    misses: u32,
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
            misses: 0,
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
        if prim == MISS {
            self.misses += 1;
        } else if n < SLOTS && !self.prims[..n].contains(&prim) {
            self.prims[n] = prim;
            self.distinct += 1;
        }
    }
}

/// The source view's hits as the target film sees them.
pub struct Reprojection {
    width: usize,
    height: usize,
    cells: Vec<Cell>,
    /// Rules 1 and 2 on the five pixels of a row centred on each pixel.
    rows: Vec<RowWindow>,
    /// Rule 3: target columns `x_lo..x_hi` may reuse.
    x_lo: usize,
    x_hi: usize,
    /// `"reproject-radiance"`: pixels may take their samples' mean radiance.
    radiance: bool,
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
        let to_source = source.film_matrix();
        // Where a sample lands: its target pixel (or `None` off the film) and film position.
        let land = |s: &SourceSample| -> Option<(usize, Vec2)> {
            let h = match s.prim {
                MISS if misses => to_target * s.point.extend(0.0),
                MISS => return None,
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
        let (eye, baseline) = (
            source.position(),
            (target.position() - source.position()).length(),
        );
        let radiance_ok = |s: &SourceSample| {
            radiance
                && s.lobe >= 0.0
                && baseline <= LOBE_FRACTION * s.lobe * (s.point - eye).length()
        };
        let tiles_x = width.div_ceil(tile);
        let band_len = tile * width;
        let mut cells = vec![Cell::default(); width * height];
        let bands: Vec<(Vec<Stray>, f32)> = cells
            .par_chunks_mut(band_len)
            .zip(tiles.par_chunks(tiles_x))
            .enumerate()
            .map(|(b, (band, band_tiles))| {
                let mut strays = Vec::new();
                let mut nearest = f32::INFINITY;
                for (t, tile) in band_tiles.iter().enumerate() {
                    for (k, sample) in tile.iter().enumerate() {
                        if sample.prim != MISS {
                            nearest = nearest.min((to_source * sample.point.extend(1.0)).w);
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
                (strays, nearest)
            })
            .collect();
        let mut nearest = f32::INFINITY;
        for (strays, band_nearest) in &bands {
            nearest = nearest.min(*band_nearest);
            for &(t, k, q) in strays {
                let sample = &tiles[t][k];
                let i = q.y as usize * width + q.x as usize;
                cells[i].add(sample, q.x - sample.film.x, radiance_ok(sample));
            }
        }
        let rows = row_windows(&cells, width);
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
            cells,
            rows,
            x_lo,
            x_hi,
            radiance,
        }
    }

    /// `"reproject-radiance"`: the mean radiance of the source samples that landed in pixel
    /// (x, y) (Adelson and Hodges' reuse of the colour), for a pixel whose window passed the
    /// rules and agrees on every shadow, where the samples of the pixel and of its two neighbours
    /// in the row all may stand for the target's and agree within `RADIANCE_SPREAD` per
    /// channel: a flat patch, where where a sample sits in the pixel does not matter.
    fn pixel_radiance(&self, x: usize, y: usize) -> Option<Vec3> {
        if !self.radiance {
            return None;
        }
        let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for c in &self.cells[y * self.width + x - 1..=y * self.width + x + 1] {
            if c.direct == 0 || c.direct != c.count {
                return None;
            }
            lo = lo.min(c.radiance_min);
            hi = hi.max(c.radiance_max);
        }
        let flat = (hi - lo).max_element() <= RADIANCE_SPREAD;
        let c = &self.cells[y * self.width + x];
        flat.then(|| c.radiance / c.direct as f32)
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
        let (mut lit, mut shadowed) = (0u32, 0u32);
        for cy in y - WINDOW_Y..=y + WINDOW_Y {
            let r = &self.rows[cy * self.width + x];
            if !r.ok {
                return None;
            }
            lit |= r.lit;
            shadowed |= r.shadowed;
        }
        let shadows_agree = lit & shadowed == 0;
        if shadows_agree && let Some(v) = self.pixel_radiance(x, y) {
            return Some(PixelReuse::Radiance(v));
        }
        let mut candidates = SmallVec::new();
        let mut any = false;
        for cy in y - WINDOW_Y..=y + WINDOW_Y {
            let row = cy * self.width;
            for c in &self.cells[row + x - CANDIDATE_X..=row + x + CANDIDATE_X] {
                any |= c.count > 0;
                for &prim in &c.prims[..c.distinct as usize] {
                    if candidates.len() < MAX_CANDIDATES && !candidates.contains(&prim) {
                        candidates.push(prim);
                    }
                }
            }
        }
        // With no triangle among the candidate pixels' samples, they all missed.
        match (candidates.is_empty(), any) {
            (true, true) => Some(PixelReuse::Miss),
            (true, false) => None,
            (false, _) => Some(PixelReuse::Hits(HitReuse {
                candidates,
                lit: lit & !shadowed,
                shadowed: shadowed & !lit,
            })),
        }
    }
}

/// What one pixel's row contributes to the rules: whether the five pixels centred on it are all
/// covered (rule 1) and keep their parallax within the bound (rule 2), and the union of their
/// samples' shadow answers.
#[derive(Clone, Copy, Default)]
struct RowWindow {
    ok: bool,
    lit: u32,
    shadowed: u32,
}

/// `RowWindow` for every pixel, row by row in parallel.
fn row_windows(cells: &[Cell], width: usize) -> Vec<RowWindow> {
    let mut rows = vec![RowWindow::default(); cells.len()];
    rows.par_chunks_mut(width)
        .zip(cells.par_chunks(width))
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
                out[x] = RowWindow { ok, lit, shadowed };
            }
        });
    rows
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
mod tests {
    use super::*;

    #[test]
    fn the_edge_strip_sits_on_the_side_near_points_move_to() {
        assert_eq!(edge_strips(-3.2, 100), (0, 96));
        assert_eq!(edge_strips(2.0, 100), (2, 100));
        assert_eq!(edge_strips(0.0, 100), (0, 100));
        assert_eq!(edge_strips(-500.0, 100), (0, 0));
        assert_eq!(edge_strips(f32::NAN, 100), (0, 0));
    }

    /// A grid filled directly (no cameras): one sample per pixel at parallax `parallax(x)`.
    fn grid(width: usize, height: usize, parallax: impl Fn(usize, usize) -> f32) -> Reprojection {
        let mut cells = vec![Cell::default(); width * height];
        for y in 0..height {
            for x in 0..width {
                let s = SourceSample {
                    film: Vec2::ZERO,
                    point: Vec3::ZERO,
                    prim: (x / 4) as u32,
                    lit: 1,
                    shadowed: 0,
                    lobe: 1.0,
                    radiance: Vec3::ONE,
                };
                cells[y * width + x].add(&s, parallax(x, y), true);
            }
        }
        Reprojection {
            width,
            height,
            rows: row_windows(&cells, width),
            cells,
            x_lo: 0,
            x_hi: width,
            radiance: false,
        }
    }

    #[test]
    fn a_step_in_parallax_refuses_reuse_around_it_and_only_there() {
        let g = grid(20, 5, |x, _| if x < 10 { 0.0 } else { -3.0 });
        for x in 2..18 {
            let near_step = (8..=11).contains(&x);
            assert_eq!(g.pixel(x, 2).is_none(), near_step, "x={x}");
        }
        // The frame border is traced.
        assert!(g.pixel(1, 2).is_none() && g.pixel(5, 0).is_none() && g.pixel(5, 4).is_none());
    }

    #[test]
    fn a_parallax_that_changes_from_row_to_row_still_reuses() {
        // A receding floor: one pixel more parallax per row, constant along each row.
        let g = grid(20, 6, |_, y| y as f32);
        assert!((1..5).all(|y| g.pixel(8, y).is_some()));
        // Along a row the same change is a step.
        let g = grid(20, 6, |x, _| x as f32);
        assert!(g.pixel(8, 2).is_none());
    }

    #[test]
    fn an_uncovered_pixel_refuses_its_window() {
        let mut g = grid(20, 5, |_, _| 0.0);
        for x in 9..=11 {
            g.cells[2 * 20 + x] = Cell::default();
        }
        g.rows = row_windows(&g.cells, 20);
        assert!(g.pixel(8, 2).is_none() && g.pixel(12, 1).is_none());
        assert!(g.pixel(7, 2).is_some() && g.pixel(13, 2).is_some());
    }

    #[test]
    fn candidates_come_from_the_neighbouring_pixels_and_shadow_answers_must_agree() {
        let hits = |g: &Reprojection| match g.pixel(8, 2) {
            Some(PixelReuse::Hits(h)) => h,
            _ => panic!("a flat window reuses hits"),
        };
        let mut g = grid(20, 5, |_, _| 0.0);
        let r = hits(&g);
        // Pixels 7..=9 saw triangles 1 and 2 (x / 4).
        assert_eq!(r.candidates.as_slice(), &[1, 2]);
        assert_eq!((r.lit, r.shadowed), (1, 0));
        g.cells[3 * 20 + 10].shadowed = 1;
        g.rows = row_windows(&g.cells, 20);
        let r = hits(&g);
        assert_eq!((r.lit, r.shadowed), (0, 0), "a disagreeing light is traced");
    }

    #[test]
    fn a_flat_rough_pixel_takes_its_samples_mean_radiance_and_an_edge_does_not() {
        let mut g = grid(20, 5, |_, _| 0.0);
        g.radiance = true;
        assert!(matches!(g.pixel(8, 2), Some(PixelReuse::Radiance(v)) if v == Vec3::ONE));
        // A neighbour in the row that differs by more than the spread: the pixel traces its
        // own samples on the reused hits.
        g.cells[2 * 20 + 9].radiance_max = Vec3::splat(1.5);
        assert!(matches!(g.pixel(8, 2), Some(PixelReuse::Hits(_))));
    }

    #[test]
    fn a_window_of_misses_is_the_background() {
        let mut g = grid(20, 5, |_, _| 0.0);
        for c in &mut g.cells {
            *c = Cell::default();
            let miss = SourceSample {
                film: Vec2::ZERO,
                point: Vec3::Z,
                prim: MISS,
                lit: 0,
                shadowed: 0,
                lobe: -1.0,
                radiance: Vec3::ZERO,
            };
            c.add(&miss, 0.0, false);
        }
        g.rows = row_windows(&g.cells, 20);
        assert!(matches!(g.pixel(8, 2), Some(PixelReuse::Miss)));
    }
}
