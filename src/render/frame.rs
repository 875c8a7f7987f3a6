//! One eye of one frame: the film is cut into tiles that rayon traces in parallel; each pixel is
//! the plain mean of its samples (a box filter over the pixel, WHITTED.md section 3). Pixel values
//! depend only on the pixel's own samples, so tile order and thread count cannot change the image.

use super::camera::EyeCamera;
use super::integrator::{Integrator, RayCounts};
use super::sampling::pixel_sample;
use crate::accel::{Intersect, LANES, Ray};
use crate::output::Image;
use glam::Vec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use smallvec::SmallVec;
use std::cell::Cell;

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
    /// Each eye is traced on its own: 2x2 pixel quads per packet.
    #[default]
    Off,
    /// Both eyes in one pass: a packet holds two neighbouring pixels of the left eye and the
    /// same two of the right, whose rays share a scanline and most of their nodes. The images
    /// are bit-identical to `off` (every lane computes its own ray's radiance exactly).
    Paired,
}

/// A view to render: its camera and film (every view of one call shares size and spp).
pub struct ViewFilm<'a> {
    pub camera: &'a EyeCamera,
    pub film: FilmParams,
}

/// Renders one view, or two together (the eyes under `EyeReuse::Paired`). `on_tile(v)` is
/// called once per finished tile of view `v` (progress bars). Returns each view's image and the
/// rays of all of them.
pub fn render_views<A: Intersect>(
    integrator: &Integrator<'_, A>,
    views: &[ViewFilm],
    on_tile: &(dyn Fn(usize) + Sync),
) -> (Vec<Image>, RayCounts) {
    let first = views.first().expect("at least one view").film;
    assert!(
        views.len() <= 2
            && views.iter().all(|v| {
                (v.film.width, v.film.height, v.film.spp, v.film.frame)
                    == (first.width, first.height, first.spp, first.frame)
            }),
        "one or two views of one film size"
    );
    let (w, h, spp) = (first.width, first.height, first.spp);
    let tiles_x = w.div_ceil(TILE);
    // A packet's pixels: a 2x2 quad of one view, or a 2x1 pair of each of two views.
    let (block_w, block_h) = if views.len() == 1 { (2, 2) } else { (2, 1) };
    // One tile per task: tiles differ in cost by orders of magnitude (sky against a glass
    // sphere), and rayon's default splitting left a core idle for about a tenth of each eye
    // waiting on the last large chunk.
    let tiles: Vec<(Vec<Vec<Vec3>>, RayCounts)> = (0..tile_count(w, h))
        .into_par_iter()
        .with_max_len(1)
        .map(|t| {
            let (x0, y0) = ((t % tiles_x) * TILE, (t / tiles_x) * TILE);
            let (x1, y1) = ((x0 + TILE).min(w), (y0 + TILE).min(h));
            let counts = Cell::new(RayCounts::default());
            let tw = x1 - x0;
            let mut pixels = vec![vec![Vec3::ZERO; tw * (y1 - y0)]; views.len()];
            // Each sample's camera rays of a block, and then their shadow, mirror and
            // refraction rays, travel the tree as packets. A pixel still sums its own samples
            // in order, so the image does not depend on the grouping.
            for by in (y0..y1).step_by(block_h) {
                for bx in (x0..x1).step_by(block_w) {
                    let mut lanes: SmallVec<[(usize, usize, usize); LANES]> = SmallVec::new();
                    for v in 0..views.len() {
                        for y in by..(by + block_h).min(y1) {
                            for x in bx..(bx + block_w).min(x1) {
                                lanes.push((v, x, y));
                            }
                        }
                    }
                    let n = lanes.len();
                    let mut sums = [Vec3::ZERO; LANES];
                    let mut rays = [Ray::new(Vec3::ZERO, Vec3::Z); LANES];
                    let mut limits = [0.0; LANES];
                    let mut radiance = [Vec3::ZERO; LANES];
                    for s in 0..spp {
                        for (i, &(v, x, y)) in lanes.iter().enumerate() {
                            let film = &views[v].film;
                            let seed = [(y * w + x) as u32, film.frame, film.eye_seed];
                            let o = pixel_sample(s, spp, seed);
                            (rays[i], limits[i]) =
                                views[v].camera.ray(x as f32 + o.x, y as f32 + o.y);
                        }
                        integrator.radiance_packet(
                            &rays[..n],
                            &limits[..n],
                            &counts,
                            &mut radiance[..n],
                        );
                        for (sum, r) in sums.iter_mut().zip(&radiance[..n]) {
                            *sum += *r;
                        }
                    }
                    for (i, &(v, x, y)) in lanes.iter().enumerate() {
                        pixels[v][(y - y0) * tw + (x - x0)] = sums[i] / spp as f32;
                    }
                }
            }
            for v in 0..views.len() {
                on_tile(v);
            }
            (pixels, counts.get())
        })
        .collect();
    let mut images: Vec<Image> = views.iter().map(|_| Image::new(w, h)).collect();
    let mut counts = RayCounts::default();
    for (t, (pixels, c)) in tiles.into_iter().enumerate() {
        let (x0, y0) = ((t % tiles_x) * TILE, (t / tiles_x) * TILE);
        let tw = (x0 + TILE).min(w) - x0;
        for (image, view_pixels) in images.iter_mut().zip(pixels) {
            for (i, p) in view_pixels.into_iter().enumerate() {
                image.set(x0 + i % tw, y0 + i / tw, p);
            }
        }
        counts.add(&c);
    }
    (images, counts)
}
