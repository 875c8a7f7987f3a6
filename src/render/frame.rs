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
            let tw = x1 - x0;
            let mut pixels = vec![Vec3::ZERO; tw * (y1 - y0)];
            // Pixels in 2x2 quads: each sample's four camera rays, and then their shadow rays,
            // travel the tree as a packet. A pixel still sums its own samples in order.
            for qy in (y0..y1).step_by(2) {
                for qx in (x0..x1).step_by(2) {
                    let mut quad: SmallVec<[(usize, usize); LANES]> = SmallVec::new();
                    for (x, y) in [(qx, qy), (qx + 1, qy), (qx, qy + 1), (qx + 1, qy + 1)] {
                        if x < x1 && y < y1 {
                            quad.push((x, y));
                        }
                    }
                    let mut sums = [Vec3::ZERO; LANES];
                    let mut rays = [Ray::new(Vec3::ZERO, Vec3::Z); LANES];
                    let mut limits = [0.0; LANES];
                    let mut radiance = [Vec3::ZERO; LANES];
                    for s in 0..film.spp {
                        for (i, &(x, y)) in quad.iter().enumerate() {
                            let seed = [(y * w + x) as u32, film.frame, film.eye_seed];
                            let o = pixel_sample(s, film.spp, seed);
                            (rays[i], limits[i]) = camera.ray(x as f32 + o.x, y as f32 + o.y);
                        }
                        let n = quad.len();
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
                    for (i, &(x, y)) in quad.iter().enumerate() {
                        pixels[(y - y0) * tw + (x - x0)] = sums[i] / film.spp as f32;
                    }
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
