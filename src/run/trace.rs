//! One frame of a pipeline, traced: pose the scene at the frame's time, bring the acceleration
//! structure up to date, and trace the requested views. `run` hands the result to the outputs;
//! `bench sweep` times it and measures its error. Nothing here writes a file.

use super::head_light::head_light;
use super::outputs::StereoFrame;
use super::rig_plan::{FrameProbe, FrameRig, RigPlanner};
use crate::accel::{BuildParams, Intersect, LogRow, Updater};
use crate::error::Result;
use crate::output::Image;
use crate::pipeline::LoadedPipeline;
use crate::render::{
    Backend, Budget, DepthProbe, EdgeTest, EyeCamera, EyeReuse, FilmParams, Integrator,
    ParallaxModel, ProbeCamera, RECORDED_LIGHTS, RayCounts, Reprojection, Rig, RigParams,
    SceneView, SourcePixels, TraceSettings, VIEWER_EYES, View, ViewFilm, ViewRole, render_views,
    view_window,
};
use crate::scene::{Animation, PosedScene, framing_camera};
use glam::{Mat4, Vec3};
use std::sync::atomic::AtomicBool;
use std::time::Instant;

/// Where a traced frame's time went, and what it traced.
#[derive(Debug, Default)]
pub struct FrameStats {
    pub pose_seconds: f64,
    /// The acceleration update, one row per object (static objects as one row).
    pub update: Vec<LogRow>,
    /// Tracing time per view, in the order traced.
    pub view_seconds: Vec<(View, f64)>,
    /// The rays of each view, in the same order (under `paired`, half the pass's each).
    pub view_rays: Vec<(View, RayCounts)>,
    pub rays: RayCounts,
    /// The rig the frame was traced with and its depth budget (stereo rigs).
    pub rig: Option<FrameRig>,
}

impl FrameStats {
    pub fn update_seconds(&self) -> f64 {
        self.update.iter().map(|r| r.seconds).sum()
    }

    pub fn trace_seconds(&self) -> f64 {
        self.view_seconds.iter().map(|(_, s)| s).sum()
    }
}

/// Traces frames of one pipeline in order, keeping the acceleration structures between frames.
pub struct FrameTracer<'p> {
    p: &'p LoadedPipeline,
    animations: Vec<&'p Animation>,
    updater: Updater,
    /// The scene's bounds over the pipeline's whole frame range, for the default camera and
    /// head-light (so neither moves with the animation); `None` when neither is used.
    range_bounds: Option<(Vec3, Vec3)>,
    /// Set to stop tracing (`render`'s Ctrl-C): tiles not started then stay black.
    stop: Option<&'static AtomicBool>,
    /// The rig of each frame (stereo rigs), and where it probes other frames when an automatic
    /// choice is smoothed over them.
    planner: Option<RigPlanner>,
    prober: Option<Prober<'p>>,
    /// The GPU backend, opened at the first frame it traces.
    #[cfg(feature = "gpu")]
    gpu: Option<crate::gpu::GpuFrames>,
}

/// Probes frames apart from the frame being traced, with acceleration structures of its own.
struct Prober<'p> {
    p: &'p LoadedPipeline,
    animations: Vec<&'p Animation>,
    updater: Updater,
    range_bounds: Option<(Vec3, Vec3)>,
}

impl Prober<'_> {
    fn probe(&mut self, frame: u32) -> FrameProbe {
        probe_posed(
            self.p,
            &self.animations,
            &mut self.updater,
            self.range_bounds,
            frame,
        )
    }
}

/// Poses `frame`, brings `updater`'s structures up to date and probes it.
fn probe_posed(
    p: &LoadedPipeline,
    animations: &[&Animation],
    updater: &mut Updater,
    range_bounds: Option<(Vec3, Vec3)>,
    frame: u32,
) -> FrameProbe {
    let posed = p
        .scene
        .pose_at(animations, frame as f32 / p.spec.frames.fps);
    let (accel, _) = updater.update(&posed);
    let bounds = range_bounds.or_else(|| posed.geometry.bounds());
    frame_probe(p, &posed, bounds, &accel)
}

/// The planner's rig for `frame`: probing other frames through the prober when the rig is
/// smoothed over them, the frame being traced through `here` otherwise.
fn plan_rig(
    planner: &mut Option<RigPlanner>,
    prober: &mut Option<Prober>,
    frame: u32,
    here: impl FnOnce() -> FrameProbe,
) -> Option<FrameRig> {
    let planner = planner.as_mut()?;
    Some(match prober.as_mut() {
        Some(prober) => planner.rig(frame, &mut |f| prober.probe(f)),
        None => {
            let probe = here();
            planner.rig(frame, &mut |_| probe.clone())
        }
    })
}

/// The depth probe of a posed frame through its camera, with the subject's depth.
fn frame_probe(
    p: &LoadedPipeline,
    posed: &PosedScene,
    bounds: Option<(Vec3, Vec3)>,
    accel: &impl Intersect,
) -> FrameProbe {
    let (world, yfov, znear, zfar) = frame_camera(p, posed, bounds);
    let camera = ProbeCamera {
        world,
        yfov,
        znear,
        zfar,
        width: p.spec.render.width,
        height: p.spec.render.height,
    };
    let subject = p.spec.stereo.subject.as_deref().and_then(|name| {
        let node = p.node_named(name)?;
        let origin = posed.node_world[node].transform_point3(Vec3::ZERO);
        Some(-world.inverse().transform_point3(origin).z)
    });
    FrameProbe {
        depth: DepthProbe::measure(accel, &camera),
        subject,
        camera,
    }
}

/// The parallax of each node a wobble GIF pivots on, under the frame's rig (a node behind the
/// eyes has none: its views are not shifted).
fn pivot_parallax(
    p: &LoadedPipeline,
    posed: &PosedScene,
    camera_world: &Mat4,
    rig: &RigParams,
) -> Vec<(String, f32)> {
    let model = ParallaxModel {
        rig: rig.rig,
        interaxial: rig.interaxial,
        convergence: rig.convergence,
        width: rig.width as f32,
        tan_x: (rig.yfov * 0.5).tan() * rig.width as f32 / rig.height as f32,
    };
    let to_rig = camera_world.inverse();
    p.spec
        .outputs
        .iter()
        .filter_map(|o| o.pivot_node())
        .filter_map(|name| {
            let node = p.node_named(name)?;
            let origin = posed.node_world[node].transform_point3(Vec3::ZERO);
            let depth = -to_rig.transform_point3(origin).z;
            Some((
                name.to_string(),
                if depth > 0.0 {
                    model.pixels(depth)
                } else {
                    0.0
                },
            ))
        })
        .collect()
}

/// Blackens a view's floating-window borders, `(left, right)` pixels wide; a fractional border
/// covers its last column in part, so a border that moves from frame to frame moves smoothly.
fn mask_window(image: &mut Image, (left, right): (f32, f32)) {
    let w = image.width;
    for x in 0..w {
        let from_left = (left - x as f32).clamp(0.0, 1.0);
        let from_right = (right - (w - 1 - x) as f32).clamp(0.0, 1.0);
        let keep = (1.0 - from_left) * (1.0 - from_right);
        if keep < 1.0 {
            for y in 0..image.height {
                let v = image.get(x, y);
                image.set(x, y, v * keep);
            }
        }
    }
}

impl<'p> FrameTracer<'p> {
    pub fn new(p: &'p LoadedPipeline) -> FrameTracer<'p> {
        let animations = p.selected_animations();
        let updater = Updater::new(
            &p.scene,
            &animations,
            BuildParams::with_method(p.spec.accel.split),
            p.spec.accel.update,
            p.spec.accel.auto_threshold,
        )
        // Both eyes' camera samples.
        .with_samples_per_frame(
            2 * p.spec.render.width as u64 * p.spec.render.height as u64 * p.spec.render.spp as u64,
        );
        let lit = p.scene.nodes.iter().any(|n| n.light.is_some());
        let range_bounds = (p.camera_instance.is_none() || !lit)
            .then(|| range_bounds(p, &animations))
            .flatten();
        let range = (p.spec.frames.start, p.spec.frames.end);
        let planner =
            (p.spec.stereo.rig != Rig::Mono).then(|| RigPlanner::new(&p.spec.stereo, range));
        let prober = planner
            .as_ref()
            .filter(|planner| planner.needs_neighbours())
            .map(|_| Prober {
                p,
                animations: animations.clone(),
                updater: Updater::new(
                    &p.scene,
                    &animations,
                    BuildParams::with_method(p.spec.accel.split),
                    p.spec.accel.update,
                    p.spec.accel.auto_threshold,
                ),
                range_bounds,
            });
        FrameTracer {
            p,
            animations,
            updater,
            range_bounds,
            stop: None,
            planner,
            prober,
            #[cfg(feature = "gpu")]
            gpu: None,
        }
    }

    /// The rig `frame` will be traced with, and its depth budget, without tracing it (`check
    /// --depth`); `None` for a mono rig.
    pub fn plan(&mut self, frame: u32) -> Option<FrameRig> {
        let (p, animations, range_bounds) = (self.p, &self.animations, self.range_bounds);
        let updater = &mut self.updater;
        plan_rig(&mut self.planner, &mut self.prober, frame, || {
            probe_posed(p, animations, updater, range_bounds, frame)
        })
    }

    /// The depth budget frames are held to.
    pub fn budget(&self) -> Budget {
        self.planner
            .as_ref()
            .map_or(Budget::new(0.0, 0.0, None), RigPlanner::budget)
    }

    /// Tiles not yet started are skipped once `stop` is set; a frame traced while it was set is
    /// incomplete.
    pub fn with_stop(mut self, stop: &'static AtomicBool) -> FrameTracer<'p> {
        self.stop = Some(stop);
        self
    }

    /// Traces `views` of `frame`. `on_tile` is called once per finished tile, from any thread.
    pub fn trace(
        &mut self,
        frame: u32,
        views: &[View],
        on_tile: &(dyn Fn(View) + Sync),
    ) -> Result<(StereoFrame, FrameStats)> {
        let (p, spec) = (self.p, &self.p.spec);
        let mut stats = FrameStats::default();
        let t = Instant::now();
        let time = frame as f32 / spec.frames.fps;
        let posed = p.scene.pose_at(&self.animations, time);
        stats.pose_seconds = t.elapsed().as_secs_f64();

        let (accel, update_rows) = self.updater.update(&posed);
        stats.update = update_rows;
        let bounds = self.range_bounds.or_else(|| posed.geometry.bounds());
        let (camera_world, yfov, znear, zfar) = frame_camera(p, &posed, bounds);
        let lights = if posed.lights.is_empty() {
            vec![head_light(&camera_world, bounds, || {
                frame_probe(p, &posed, bounds, &accel).depth.near_most
            })]
        } else {
            posed.lights.clone()
        };
        let settings = TraceSettings {
            max_depth: spec.render.max_depth,
            shading: spec.render.shading,
            background: Vec3::from(spec.render.background),
        };
        let integrator = Integrator::new(
            SceneView {
                accel: &accel,
                geometry: &posed.geometry,
                materials: &p.scene.materials,
                textures: &p.scene.textures,
                lights: &lights,
            },
            settings,
        );
        stats.rig = plan_rig(&mut self.planner, &mut self.prober, frame, || {
            frame_probe(p, &posed, bounds, &accel)
        });
        let rig = RigParams {
            rig: spec.stereo.rig,
            interaxial: stats
                .rig
                .map_or(spec.stereo.interaxial.fixed().unwrap_or(VIEWER_EYES), |r| {
                    r.interaxial
                }),
            convergence: stats
                .rig
                .map_or(spec.stereo.convergence.fixed().unwrap_or(1.0), |r| {
                    r.convergence
                }),
            width: spec.render.width,
            height: spec.render.height,
            yfov,
            znear,
            zfar,
        };
        let mut traced = StereoFrame {
            frame,
            views: Vec::new(),
            pivots: pivot_parallax(p, &posed, &camera_world, &rig),
        };
        let film = |view: View| FilmParams {
            width: spec.render.width as usize,
            height: spec.render.height as usize,
            spp: spec.render.spp,
            frame,
            eye_seed: view.seed(),
        };
        // Under `paired` the two eyes are traced in one pass (each gets half its time in the
        // frame log); under `reproject` the left eye keeps its camera hits and every later view
        // reuses them; every other view, and every view under `off`, on its own.
        let reuse = spec.render.eye_reuse;
        let paired = reuse == EyeReuse::Paired
            && views.contains(&View::LEFT)
            && views.contains(&View::RIGHT);
        let reproject = reuse.reprojects() && views.contains(&View::LEFT);
        // Radiance is only taken where every light's shadow answer is known (one bit each).
        let take_radiance = reuse == EyeReuse::ReprojectRadiance && lights.len() <= RECORDED_LIGHTS;
        let mut passes: Vec<Vec<View>> = Vec::new();
        for &view in views {
            match view {
                View::RIGHT if paired => {}
                View::LEFT if paired => passes.push(vec![View::LEFT, View::RIGHT]),
                _ => passes.push(vec![view]),
            }
        }
        // The GPU traces every view in one pass (validation refuses reprojection with it).
        let on_gpu = spec.render.backend == Backend::Gpu;
        if on_gpu {
            passes = vec![views.to_vec()];
        }
        let mut images = Vec::new();
        let mut source: Option<(EyeCamera, SourcePixels)> = None;
        for pass in passes {
            let cameras: Vec<EyeCamera> = pass
                .iter()
                .map(|&v| EyeCamera::new(camera_world, &rig, v))
                .collect();
            let t = Instant::now();
            let reprojection = source.as_ref().map(|(source_camera, pixels)| {
                Reprojection::new(
                    pixels,
                    source_camera,
                    &cameras[0],
                    zfar.is_none(),
                    take_radiance,
                )
            });
            let role = match (&reprojection, pass[0]) {
                (Some(r), _) => ViewRole::Target(r),
                (None, View::LEFT) if reproject => ViewRole::Source(EdgeTest {
                    parallax_per_inv_depth: views
                        .iter()
                        .map(|&v| {
                            let other = EyeCamera::new(camera_world, &rig, v);
                            cameras[0].parallax_line(&other).1.abs()
                        })
                        .fold(0.0, f32::max),
                    misses_land: zfar.is_none(),
                }),
                _ => ViewRole::Plain,
            };
            let films: Vec<ViewFilm> = cameras
                .iter()
                .zip(&pass)
                .map(|(camera, &v)| ViewFilm {
                    camera,
                    film: film(v),
                    role,
                })
                .collect();
            // Validation refuses backend = "gpu" in a build without it.
            let rendered = match on_gpu {
                #[cfg(feature = "gpu")]
                true => {
                    self.gpu_views(&integrator.scene, &settings, &films, &|k| on_tile(pass[k]))?
                }
                _ => render_views(&integrator, &films, &|k| on_tile(pass[k]), self.stop),
            };
            let secs = t.elapsed().as_secs_f64() / pass.len() as f64;
            stats.rays.add(&rendered.counts);
            if let Some(pixels) = rendered.source {
                source = Some((cameras[0].clone(), pixels));
            }
            for (view, mut image) in pass.into_iter().zip(rendered.images) {
                if let Some(r) = stats.rig.filter(|r| r.window != (0.0, 0.0)) {
                    mask_window(&mut image, view_window(view.offset_fraction(), r.window));
                }
                stats.view_seconds.push((view, secs));
                let share = rendered.counts.share(films.len() as u64);
                stats.view_rays.push((view, share));
                images.push((view, image));
            }
        }
        // The views in the order asked for.
        for view in views {
            let i = images.iter().position(|(v, _)| v == view).expect("traced");
            traced.views.push(images.swap_remove(i));
        }
        Ok((traced, stats))
    }

    /// The GPU adapter tracing this pipeline's frames, with its driver and limits, and what it
    /// was sent so far, once opened.
    pub fn device(&self) -> Option<String> {
        #[cfg(feature = "gpu")]
        return self
            .gpu
            .as_ref()
            .map(|g| format!("{}; {}", g.describe(), g.uploads()));
        #[cfg(not(feature = "gpu"))]
        None
    }

    /// What the GPU backend has uploaded (`None` before it traced).
    #[cfg(feature = "gpu")]
    pub fn gpu_uploads(&self) -> Option<crate::gpu::Uploads> {
        self.gpu.as_ref().map(|g| g.uploads())
    }

    /// `films` traced on the GPU, which is opened on first use.
    #[cfg(feature = "gpu")]
    fn gpu_views(
        &mut self,
        scene: &SceneView<crate::accel::TwoLevel>,
        settings: &TraceSettings,
        films: &[ViewFilm],
        on_tile: &(dyn Fn(usize) + Sync),
    ) -> Result<crate::render::Rendered> {
        let gpu = match &mut self.gpu {
            Some(g) => g,
            None => self.gpu.insert(crate::gpu::GpuFrames::open()?),
        };
        gpu.render(scene, settings, films, on_tile, self.stop)
    }
}

/// At most this many frames are posed to find the bounds of an animation, evenly spread over
/// the range with its first and last frame: ten seconds at 24 fps, all of a typical clip, and a
/// bounded start-up cost for a long one.
const BOUNDS_FRAMES: u32 = 240;

/// The union of the posed scene's bounds over the pipeline's `[frames]` range (not a
/// `--frames` override: a shard or a single frame gets the same camera as the whole range).
fn range_bounds(p: &LoadedPipeline, animations: &[&Animation]) -> Option<(Vec3, Vec3)> {
    let f = &p.spec.frames;
    let n = if animations.is_empty() {
        1
    } else {
        (f.end - f.start + 1).min(BOUNDS_FRAMES)
    };
    (0..n)
        .map(|i| {
            let frame = match n {
                1 => f.start,
                _ => f.start + ((f.end - f.start) as u64 * i as u64 / (n - 1) as u64) as u32,
            };
            p.scene
                .pose_at(animations, frame as f32 / f.fps)
                .geometry
                .bounds()
        })
        .reduce(|a, b| match (a, b) {
            (Some((alo, ahi)), Some((blo, bhi))) => Some((alo.min(blo), ahi.max(bhi))),
            (a, b) => a.or(b),
        })
        .flatten()
}

/// The camera placement and lens for a frame, with the scene's fallbacks applied: without a
/// camera in the scene, one that frames `bounds`.
fn frame_camera(
    p: &LoadedPipeline,
    posed: &PosedScene,
    bounds: Option<(Vec3, Vec3)>,
) -> (Mat4, f32, f32, Option<f32>) {
    match p.camera_instance {
        Some(i) => {
            let pc = &posed.cameras[i];
            let def = &p.scene.cameras[pc.camera];
            (pc.world, def.yfov, def.znear, def.zfar)
        }
        None => {
            let (lo, hi) = bounds.unwrap_or((Vec3::splat(-1.0), Vec3::splat(1.0)));
            let (def, world) = framing_camera(lo, hi);
            (world, def.yfov, def.znear, def.zfar)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// BoxAnimated has no camera and no lights, and its lid lifts: its bounds change per frame.
    fn box_animated() -> LoadedPipeline {
        let dir = std::env::temp_dir().join(format!("stereotrace-trace-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let scene = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/scenes/BoxAnimated/BoxAnimated.glb");
        let file = dir.join("p.toml");
        std::fs::write(
            &file,
            format!(
                "[scene]\npath = {:?}\nanimation = \"all\"\n[frames]\nstart = 0\nend = 47\n\
                 [[output]]\nkind = \"png\"\npath = \"f_{{frame}}_{{eye}}.png\"\n",
                scene.to_string_lossy()
            ),
        )
        .unwrap();
        let p = LoadedPipeline::load(&file).unwrap();
        let _ = std::fs::remove_dir_all(&dir);
        p
    }

    #[test]
    fn the_default_camera_and_head_light_stay_put_over_the_range() {
        let p = box_animated();
        let tracer = FrameTracer::new(&p);
        let range = tracer.range_bounds.expect("no camera: the range is framed");
        let frame = |k: u32| {
            let posed = p.scene.pose_at(&tracer.animations, k as f32 / 24.0);
            let bounds = posed.geometry.bounds().unwrap();
            let (world, ..) = frame_camera(&p, &posed, tracer.range_bounds);
            let light = head_light(&world, tracer.range_bounds, || None);
            (bounds, world, light.position, light.power)
        };
        let (first, world, position, power) = frame(0);
        let mut moved = false;
        for k in 1..48 {
            let (b, w, pos, pw) = frame(k);
            moved |= b != first;
            assert!(
                range.0.cmple(b.0).all() && range.1.cmpge(b.1).all(),
                "frame {k}"
            );
            assert_eq!((w, pos, pw), (world, position, power), "frame {k}");
        }
        assert!(moved, "the model's bounds change over the range");
    }
}
