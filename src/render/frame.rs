//! One eye of one frame: the film is cut into tiles that rayon traces in parallel; each pixel is
//! the plain mean of its samples (a box filter over the pixel, WHITTED.md section 3). Pixel values
//! depend only on the pixel's own samples, so tile order and thread count cannot change the image.

use super::camera::EyeCamera;
use super::integrator::{Integrator, RayCounts};
use super::sampling::pixel_sample;
use crate::accel::Intersect;
use crate::output::Image;
use glam::Vec3;
use rayon::prelude::*;
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

/// Renders one eye. `on_tile` is called once per finished tile (progress bars).
pub fn render_eye<A: Intersect>(
    integrator: &Integrator<'_, A>,
    camera: &EyeCamera,
    film: &FilmParams,
    on_tile: &(dyn Fn() + Sync),
) -> (Image, RayCounts) {
    let (w, h) = (film.width, film.height);
    let tiles_x = w.div_ceil(TILE);
    // One tile per task: tiles differ in cost by orders of magnitude (sky against a glass
    // sphere), and rayon's default splitting left a core idle for about a tenth of each eye
    // waiting on the last large chunk.
    let tiles: Vec<(Vec<Vec3>, RayCounts)> = (0..tile_count(w, h))
        .into_par_iter()
        .with_max_len(1)
        .map(|t| {
            let (x0, y0) = ((t % tiles_x) * TILE, (t / tiles_x) * TILE);
            let (x1, y1) = ((x0 + TILE).min(w), (y0 + TILE).min(h));
            let counts = Cell::new(RayCounts::default());
            let mut pixels = Vec::with_capacity((x1 - x0) * (y1 - y0));
            for y in y0..y1 {
                for x in x0..x1 {
                    let seed = [(y * w + x) as u32, film.frame, film.eye_seed];
                    let mut sum = Vec3::ZERO;
                    for s in 0..film.spp {
                        let o = pixel_sample(s, film.spp, seed);
                        let (ray, t_max) = camera.ray(x as f32 + o.x, y as f32 + o.y);
                        sum += integrator.radiance(&ray, t_max, &counts);
                    }
                    pixels.push(sum / film.spp as f32);
                }
            }
            on_tile();
            (pixels, counts.get())
        })
        .collect();
    let mut image = Image::new(w, h);
    let mut counts = RayCounts::default();
    for (t, (pixels, c)) in tiles.into_iter().enumerate() {
        let (x0, y0) = ((t % tiles_x) * TILE, (t / tiles_x) * TILE);
        let tw = (x0 + TILE).min(w) - x0;
        for (i, p) in pixels.into_iter().enumerate() {
            image.set(x0 + i % tw, y0 + i / tw, p);
        }
        counts.add(&c);
    }
    (image, counts)
}
