//! One eye of one frame: the film is cut into tiles that rayon traces in parallel; each pixel is
//! the plain mean of its samples (a box filter over the pixel, WHITTED.md section 3). Pixel values
//! depend only on the pixel's own samples, so tile order and thread count cannot change the image.

use super::BATCH;
use super::camera::EyeCamera;
use super::integrator::{Integrator, Primary, PrimaryRecord, RayCounts};
use super::reproject::{
    EdgeTest, FinishedTile, PixelReuse, Reprojection, Sample, SourcePixels, SourceTile,
};
use super::sampling::PixelSamples;
use crate::accel::{Intersect, Ray};
use crate::output::Image;
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use smallvec::SmallVec;
use std::cell::Cell;
use std::sync::atomic::{AtomicBool, Ordering};

pub const TILE: usize = 16;

/// Samples per pixel and the seed parts that make each eye and frame draw its own samples.
#[derive(Clone, Copy, Debug)]
pub struct FilmParams {
    pub width: usize,
    pub height: usize,
    pub spp: u32,
    pub frame: u32,
    pub eye_seed: u32,
}

pub fn tile_count(width: usize, height: usize) -> usize {
    width.div_ceil(TILE) * height.div_ceil(TILE)
}

/// Whether the two eyes of a frame are traced apart or together (`[render] eye_reuse`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum EyeReuse {
    /// Each eye is traced on its own: a packet holds two neighbouring pixels' samples (eight
    /// pixels at one sample a pixel).
    #[default]
    Off,
    /// Both eyes in one pass: a packet holds one pixel's samples in the left eye and the same
    /// pixel's in the right (a 2x2 quad of each at one sample a pixel), rays that share most
    /// of their nodes. The images are bit-identical to `off` (every lane computes its own
    /// ray's radiance exactly).
    Paired,
    /// The right eye (and every view after the left) takes the left eye's camera hits where
    /// the reprojection rule allows (`render/reproject/`) and traces the rest; shading,
    /// mirror and glass rays are the view's own. Approximate where the rule is wrong.
    Reproject,
    /// As `reproject`, and a pixel whose reprojected samples all hit rough surfaces (no mirror
    /// or glass ray), where the landed radiance is smooth enough along the row to interpolate
    /// within 0.02, takes it, view-dependent highlights included: Adelson and Hodges' reuse of
    /// the colour. Cheaper, and wrong by the change of the highlights between the eyes and by
    /// what the samples did not see.
    ReprojectRadiance,
}

/// What a view does besides rendering itself.
#[derive(Clone, Copy)]
pub enum ViewRole<'a> {
    Plain,
    /// Keeps what each pixel's camera samples found for other views (`Rendered::source`),
    /// and the samples of pixels across a depth edge for those views.
    Source(EdgeTest),
    /// Takes camera hits from a source view where the reprojection rule allows.
    Target(&'a Reprojection),
}

impl EyeReuse {
    /// Whether later views take the left eye's camera hits.
    pub fn reprojects(self) -> bool {
        matches!(self, EyeReuse::Reproject | EyeReuse::ReprojectRadiance)
    }
}

/// A view to render: its camera, film and role (every view of one call shares size and spp).
pub struct ViewFilm<'a> {
    pub camera: &'a EyeCamera,
    pub film: FilmParams,
    pub role: ViewRole<'a>,
}

/// What `render_views` made.
pub struct Rendered {
    pub images: Vec<Image>,
    /// The rays of all views.
    pub counts: RayCounts,
    /// A `Source` view's pixels as other views reuse them.
    pub source: Option<SourcePixels>,
}

/// Renders one view, or two together (the eyes under `EyeReuse::Paired`). `on_tile(v)` is
/// called once per finished tile of view `v` (progress bars). Once `stop` is set, tiles not
/// yet started are left black: the images are then incomplete.
pub fn render_views<A: Intersect>(
    integrator: &Integrator<'_, A>,
    views: &[ViewFilm],
    on_tile: &(dyn Fn(usize) + Sync),
    stop: Option<&AtomicBool>,
) -> Rendered {
    let first = views.first().expect("at least one view").film;
    assert!(
        views.len() <= 2
            && views.iter().all(|v| {
                (v.film.width, v.film.height, v.film.spp, v.film.frame)
                    == (first.width, first.height, first.spp, first.frame)
            })
            && (views.len() == 1 || views.iter().all(|v| matches!(v.role, ViewRole::Plain))),
        "one or two plain views of one film size"
    );
    let (w, h, spp) = (first.width, first.height, first.spp);
    let tiles_x = w.div_ceil(TILE);
    // The pixels handed to the integrator together: a 4x2 block of one view, or a 2x2 quad of
    // each of two views, a pixel's views one after the other (`Packets::trace` makes packets
    // of their samples; rays of both eyes share a packet where they share an octant).
    const _: () = assert!(BATCH == 8);
    let (block_w, block_h) = if views.len() == 1 { (4, 2) } else { (2, 2) };
    // One tile per task: tiles differ in cost by orders of magnitude (sky against a glass
    // sphere), and rayon's default splitting left a core idle for about a tenth of each eye
    // waiting on the last large chunk.
    let tiles: Vec<TileResult> = (0..tile_count(w, h))
        .into_par_iter()
        .with_max_len(1)
        .map(|t| {
            let (x0, y0) = ((t % tiles_x) * TILE, (t / tiles_x) * TILE);
            let (x1, y1) = ((x0 + TILE).min(w), (y0 + TILE).min(h));
            let tw = x1 - x0;
            let mut pixels = vec![vec![Vec3::ZERO; tw * (y1 - y0)]; views.len()];
            let mut source = match views[0].role {
                ViewRole::Source(edge) => Some(SourceTile::new(tw * (y1 - y0), spp as usize, edge)),
                _ => None,
            };
            // Once a stop is asked for, tiles not yet started stay black: the caller discards
            // the frame.
            if stop.is_some_and(|s| s.load(Ordering::Relaxed)) {
                return TileResult {
                    pixels,
                    counts: RayCounts::default(),
                    source: source.map(SourceTile::finish),
                };
            }
            let packets = Packets {
                integrator,
                views,
                spp,
                width: w,
                eye: views[0].camera.position(),
                counts: Cell::new(RayCounts::default()),
            };
            let mut out = TileOut {
                origin: (x0, y0, tw),
                pixels: &mut pixels,
                source: source.as_mut(),
            };
            let (mut radiance_taken, mut misses_taken) = (0u64, 0u64);
            // The pixels that need the integrator, `BATCH` at a time: each sample's camera rays,
            // and then their shadow, mirror and refraction rays, travel the tree as packets.
            // A pixel still sums its own samples in order, so the image does not depend on the
            // grouping. Pixels of a target view known without a ray are set on the way: where
            // every source sample around missed (the background), or, under
            // `"reproject-radiance"`, the radiance that landed there.
            let mut pending: SmallVec<[Lane; BATCH]> = SmallVec::new();
            for by in (y0..y1).step_by(block_h) {
                for bx in (x0..x1).step_by(block_w) {
                    for y in by..(by + block_h).min(y1) {
                        for x in bx..(bx + block_w).min(x1) {
                            for (v, view) in views.iter().enumerate() {
                                let reuse = match view.role {
                                    ViewRole::Target(r) => r.pixel(x, y),
                                    _ => None,
                                };
                                let fixed = match reuse {
                                    Some(PixelReuse::Miss) => {
                                        misses_taken += spp as u64;
                                        integrator.settings.background
                                    }
                                    Some(PixelReuse::Radiance(v)) => {
                                        radiance_taken += spp as u64;
                                        v
                                    }
                                    _ => {
                                        pending.push(Lane {
                                            view: v,
                                            x,
                                            y,
                                            reuse,
                                        });
                                        if pending.len() == BATCH {
                                            packets.trace(&pending, &mut out);
                                            pending.clear();
                                        }
                                        continue;
                                    }
                                };
                                out.pixels[v][(y - y0) * tw + (x - x0)] = fixed;
                            }
                        }
                    }
                }
            }
            if !pending.is_empty() {
                packets.trace(&pending, &mut out);
            }
            let counts = packets.counts;
            for v in 0..views.len() {
                on_tile(v);
            }
            let mut counts = counts.get();
            counts.reused_primary += radiance_taken + misses_taken;
            counts.reused_radiance += radiance_taken;
            // The tile's samples are folded here, on its own thread, and then dropped.
            TileResult {
                pixels,
                counts,
                source: source.map(SourceTile::finish),
            }
        })
        .collect();
    let images: Vec<Image> = (0..views.len())
        .map(|v| assemble(&tiles, v, (w, h)))
        .collect();
    let mut counts = RayCounts::default();
    let mut source = Vec::new();
    for tile in tiles {
        counts.add(&tile.counts);
        source.extend(tile.source);
    }
    let source = matches!(views[0].role, ViewRole::Source(_))
        .then(|| SourcePixels::new(source, (w, h), TILE, spp as usize));
    Rendered {
        images,
        counts,
        source,
    }
}

/// View `v`'s image of `w` x `h` from its tiles, a band of tile rows on each thread, into
/// memory not zeroed first. A 1920x1080 eye's zeroed image, filled after on one thread, took
/// 6-56 ms (over 37 in half the runs, nearly all of it the zeroing), this 5-13 ms (2 threads).
fn assemble(tiles: &[TileResult], v: usize, (w, h): (usize, usize)) -> Image {
    let tiles_x = w.div_ceil(TILE);
    let mut pixels = Vec::with_capacity(w * h);
    let bands = pixels.spare_capacity_mut()[..w * h].par_chunks_mut(TILE * w.max(1));
    bands.enumerate().for_each(|(ty, band)| {
        for (tx, tile) in tiles[ty * tiles_x..(ty + 1) * tiles_x].iter().enumerate() {
            let x0 = tx * TILE;
            let tw = (x0 + TILE).min(w) - x0;
            // Each tile of the band holds all of the band's rows (checked), and the band's
            // tiles side by side span its width: every pixel of the band is written.
            let rows = tile.pixels[v].chunks_exact(tw);
            assert_eq!(rows.len() * w, band.len(), "a tile as high as its band");
            // Row by row (a pixel at a time took a quarter longer, copied on one thread).
            for (r, row) in rows.enumerate() {
                band[r * w + x0..r * w + x0 + tw].write_copy_of_slice(row);
            }
        }
    });
    // SAFETY: every pixel was written above (the bands cover the image, and each band's
    // tiles cover the band); a failed check panics before this.
    unsafe { pixels.set_len(w * h) };
    Image {
        width: w,
        height: h,
        pixels,
    }
}

/// A pixel of a view waiting for the integrator, and what it may reuse.
struct Lane<'a> {
    view: usize,
    x: usize,
    y: usize,
    reuse: Option<PixelReuse<'a>>,
}

/// Where a tile's pixels go: its origin and width, its pixels per view, and (for a source
/// view) what other views reuse.
struct TileOut<'a> {
    origin: (usize, usize, usize),
    pixels: &'a mut [Vec<Vec3>],
    source: Option<&'a mut SourceTile>,
}

/// What tracing a packet of pixels needs.
struct Packets<'a, 'i, A: Intersect> {
    integrator: &'a Integrator<'i, A>,
    views: &'a [ViewFilm<'a>],
    spp: u32,
    width: usize,
    /// The first view's eye.
    eye: Vec3,
    counts: Cell<RayCounts>,
}

impl<A: Intersect> Packets<'_, '_, A> {
    /// Traces every sample of up to `BATCH` pixels as packets, and sets the pixels.
    fn trace(&self, lanes: &[Lane], out: &mut TileOut) {
        let (spp, w) = (self.spp, self.width);
        let (x0, y0, tw) = out.origin;
        let role = self.views[0].role;
        let geometry = self.integrator.scene.geometry;
        let mut sums = [Vec3::ZERO; BATCH];
        let n = lanes.len();
        // Samples go four at a time: a reused pixel verifies the four samples' rays against
        // its candidates together, four rays to each triangle test.
        for first in (0..spp).step_by(SAMPLE_GROUP) {
            let group = ((spp - first) as usize).min(SAMPLE_GROUP);
            // The group's rays pixel by pixel (sample k of lane i at `i * group + k`), and the
            // packets consecutive runs of them: 2 pixels of 4 samples at 4 spp and more, 8
            // pixels of one sample at 1 spp. A pixel's samples are the most alike rays there
            // are, so a packet walks fewer nodes than one of a sample of 8 pixels.
            const ALL: usize = BATCH * SAMPLE_GROUP;
            let mut rays = [Ray::new(Vec3::ZERO, Vec3::Z); ALL];
            let mut limits = [0.0; ALL];
            let mut known = [None; ALL];
            let mut film_offset = [Vec2::ZERO; ALL];
            for (i, lane) in lanes.iter().enumerate() {
                let view = &self.views[lane.view];
                let film = &view.film;
                let samples = PixelSamples::new(
                    spp,
                    [(lane.y * w + lane.x) as u32, film.frame, film.eye_seed],
                );
                // The group's camera rays four at a time (a short group repeats its last
                // sample in the lanes it does not use).
                let offsets: [Vec2; SAMPLE_GROUP] =
                    std::array::from_fn(|k| samples.get(first + k.min(group - 1) as u32));
                let (lane_rays, lane_limits) = view.camera.rays4(
                    offsets.map(|o| lane.x as f32 + o.x),
                    offsets.map(|o| lane.y as f32 + o.y),
                );
                let at = i * group;
                rays[at..at + group].copy_from_slice(&lane_rays[..group]);
                limits[at..at + group].copy_from_slice(&lane_limits[..group]);
                film_offset[at..at + group].copy_from_slice(&offsets[..group]);
                if let Some(PixelReuse::Hits(h)) = &lane.reuse {
                    let active = (1 << group) - 1;
                    let verified = h.verify4(lane_rays, active, lane_limits, geometry);
                    known[at..at + group].copy_from_slice(&verified[..group]);
                }
            }
            let mut radiance = [Vec3::ZERO; ALL];
            let mut records = [PrimaryRecord::NONE; ALL];
            let count = n * group;
            for a in (0..count).step_by(BATCH) {
                let b = (a + BATCH).min(count);
                let primary = match role {
                    ViewRole::Plain => Primary::Trace,
                    ViewRole::Source(_) => Primary::Record(&mut records[a..b]),
                    ViewRole::Target(_) => Primary::Known(&known[a..b]),
                };
                self.integrator.radiance_packet(
                    &rays[a..b],
                    &limits[a..b],
                    primary,
                    &self.counts,
                    &mut radiance[a..b],
                );
            }
            // Each pixel adds its samples in their order, whatever the packets were.
            for (i, sum) in sums[..n].iter_mut().enumerate() {
                for r in &radiance[i * group..(i + 1) * group] {
                    *sum += *r;
                }
            }
            if let Some(source) = &mut out.source {
                for (i, lane) in lanes.iter().enumerate() {
                    let at = (lane.y - y0) * tw + (lane.x - x0);
                    for j in i * group..(i + 1) * group {
                        let p = records[j].point;
                        let sample = Sample {
                            film_x: film_offset[j].x,
                            film_y: film_offset[j].y,
                            depth: self.views[0].camera.depth(p),
                            distance: p.distance(self.eye),
                        };
                        source.add(at, sample, &records[j], radiance[j]);
                    }
                }
            }
        }
        for (lane, sum) in lanes.iter().zip(sums) {
            out.pixels[lane.view][(lane.y - y0) * tw + (lane.x - x0)] = sum / spp as f32;
        }
    }
}

/// Samples of a pixel traced together (`Packets::trace`): the lanes of a triangle test.
const SAMPLE_GROUP: usize = 4;

/// One tile's pixels per view, its rays and (for a source view) what other views reuse.
struct TileResult {
    pixels: Vec<Vec<Vec3>>,
    counts: RayCounts,
    source: Option<FinishedTile>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_assemble_into_the_image_at_their_places() {
        // A film that no whole number of tiles covers, in either direction.
        let (w, h) = (2 * TILE + 5, TILE + 3);
        let value = |x: usize, y: usize| Vec3::new(x as f32, y as f32, 1.0);
        let tiles: Vec<TileResult> = (0..tile_count(w, h))
            .map(|t| {
                let tiles_x = w.div_ceil(TILE);
                let (x0, y0) = ((t % tiles_x) * TILE, (t / tiles_x) * TILE);
                let (x1, y1) = ((x0 + TILE).min(w), (y0 + TILE).min(h));
                let view = |v: f32| {
                    (y0..y1)
                        .flat_map(|y| (x0..x1).map(move |x| value(x, y) * v))
                        .collect()
                };
                TileResult {
                    pixels: vec![view(1.0), view(-1.0)],
                    counts: RayCounts::default(),
                    source: None,
                }
            })
            .collect();
        for (v, sign) in [(0, 1.0), (1, -1.0)] {
            let image = assemble(&tiles, v, (w, h));
            assert_eq!(
                (image.width, image.height, image.pixels.len()),
                (w, h, w * h)
            );
            for y in 0..h {
                for x in 0..w {
                    assert_eq!(
                        image.get(x, y),
                        value(x, y) * sign,
                        "({x}, {y}) of view {v}"
                    );
                }
            }
        }
        assert!(assemble(&[], 0, (0, 0)).pixels.is_empty());
    }
}
