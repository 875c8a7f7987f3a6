//! Views of a posed frame traced on the GPU (`[render] backend = "gpu"`): the camera samples are
//! the CPU's (`render::PixelSamples` and `EyeCamera::ray`, so both backends sample the same film
//! points), every view's rays of a band of rows go in one batch, and each pixel is the mean of
//! its samples summed in sample order, as `render/frame.rs` does. The trees are the CPU's, part
//! for part (`accel::Updater`: static geometry, instances, refitted or rebuilt deforming
//! meshes), and a frame uploads only what its update changed (`accel.rs`), with the span of
//! vertices that moved.

use super::accel::{GpuAccel, Uploads};
use super::device::Gpu;
use super::whitted::{GpuScene, GpuWhitted};
use crate::accel::{Ray, TwoLevel};
use crate::error::Result;
use crate::output::Image;
use crate::render::{PixelSamples, RayCounts, Rendered, SceneView, TILE, TraceSettings, ViewFilm};
use glam::{Vec2, Vec3};
use std::sync::atomic::{AtomicBool, Ordering};

/// Camera rays per batch: 2^20 rays hold 32 MiB of rays and 16 MiB of radiance.
const BATCH_RAYS: usize = 1 << 20;

/// The adapter, the compiled integrator, and the last frame's trees and surfaces.
pub struct GpuFrames {
    gpu: Gpu,
    whitted: GpuWhitted,
    accel: GpuAccel,
    surfaces: Option<GpuScene>,
    /// Bytes of surfaces written so far.
    surface_bytes: u64,
}

impl GpuFrames {
    pub fn open() -> Result<GpuFrames> {
        let gpu = Gpu::open()?;
        let whitted = GpuWhitted::new(&gpu)?;
        let accel = GpuAccel::new(&gpu)?;
        Ok(GpuFrames {
            gpu,
            whitted,
            accel,
            surfaces: None,
            surface_bytes: 0,
        })
    }

    /// The adapter, its driver and limits.
    pub fn describe(&self) -> String {
        self.gpu.describe()
    }

    /// What was sent to the GPU so far; `bytes` counts the surfaces too.
    pub fn uploads(&self) -> Uploads {
        let trees = self.accel.uploads();
        Uploads {
            bytes: trees.bytes + self.surface_bytes,
            ..trees
        }
    }

    /// Renders `views` (plain views of one film size and sample count, as `render_views` takes
    /// them); `on_tile(v)` once per 16x16 tile of view `v` finished. Once `stop` is set the
    /// bands not yet traced stay black. Rays are counted as the CPU counts them.
    pub fn render(
        &mut self,
        scene: &SceneView<TwoLevel>,
        settings: &TraceSettings,
        views: &[ViewFilm],
        on_tile: &(dyn Fn(usize) + Sync),
        stop: Option<&AtomicBool>,
    ) -> Result<Rendered> {
        let g = scene.geometry;
        self.accel
            .update(&self.gpu, scene.accel, g.triangles.len())?;
        let gpu = &self.gpu;
        self.surface_bytes += match &mut self.surfaces {
            Some(s) => s.update(gpu, g, scene.lights)?,
            None => {
                let s = GpuScene::upload(gpu, g, scene.materials, scene.textures, scene.lights)?;
                self.surfaces.insert(s).resident_bytes()
            }
        };
        let surfaces = self.surfaces.as_ref().expect("uploaded above");
        let first = views.first().expect("at least one view").film;
        let (w, h, spp) = (first.width, first.height, first.spp as usize);
        let mut images: Vec<Image> = views.iter().map(|_| Image::new(w, h)).collect();
        // Bands of whole tile rows, so progress counts tiles as the CPU's does.
        let per_row = w * spp * views.len();
        let band = TILE * (BATCH_RAYS / (TILE * per_row).max(1)).max(1);
        let tiles_x = w.div_ceil(TILE);
        let mut counts = RayCounts::default();
        for y0 in (0..h).step_by(band) {
            if stop.is_some_and(|s| s.load(Ordering::Relaxed)) {
                break;
            }
            let y1 = (y0 + band).min(h);
            let mut rays: Vec<Ray> = Vec::with_capacity((y1 - y0) * per_row);
            let mut limits = Vec::with_capacity(rays.capacity());
            for v in views {
                for y in y0..y1 {
                    for x in 0..w {
                        let seed = [(y * w + x) as u32, v.film.frame, v.film.eye_seed];
                        let samples = PixelSamples::new(spp as u32, seed);
                        for s in 0..spp as u32 {
                            let o = samples.get(s);
                            let f = Vec2::new(x as f32 + o.x, y as f32 + o.y);
                            let (ray, limit) = v.camera.ray(f.x, f.y);
                            rays.push(ray);
                            limits.push(limit);
                        }
                    }
                }
            }
            let (radiance, [secondary, shadow]) = self.whitted.radiance(
                &self.gpu,
                &self.accel,
                surfaces,
                settings,
                &rays,
                &limits,
            )?;
            counts.primary += rays.len() as u64;
            counts.secondary += secondary;
            counts.shadow += shadow;
            let mut samples = radiance.chunks(spp);
            for (image, _) in images.iter_mut().zip(views) {
                for y in y0..y1 {
                    for x in 0..w {
                        let sum = samples
                            .next()
                            .expect("one radiance per sample")
                            .iter()
                            .fold(Vec3::ZERO, |a, r| a + *r);
                        image.set(x, y, sum / spp as f32);
                    }
                }
            }
            for v in 0..views.len() {
                for _ in 0..tiles_x * (y1 - y0).div_ceil(TILE) {
                    on_tile(v);
                }
            }
        }
        Ok(Rendered {
            images,
            counts,
            source: None,
        })
    }
}
