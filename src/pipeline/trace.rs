//! One frame of a pipeline, traced: pose the scene at the frame's time, bring the acceleration
//! structure up to date, and trace the requested views. `run` hands the result to the outputs;
//! `bench sweep` times it and measures its error. Nothing here writes a file.

use super::LoadedPipeline;
use super::outputs::StereoFrame;
use crate::accel::{BuildParams, LogRow, Updater};
use crate::render::{
    EyeCamera, EyeReuse, FilmParams, Integrator, RECORDED_LIGHTS, RayCounts, Reprojection,
    RigParams, SceneView, SourceSample, TILE, TraceSettings, View, ViewFilm, ViewRole,
    render_views,
};
use crate::scene::{Animation, Light, LightKind, PosedScene, framing_camera};
use glam::{Mat4, Vec3};
use std::time::Instant;

/// Where a traced frame's time went, and what it traced.
#[derive(Debug, Default)]
pub struct FrameStats {
    pub pose_seconds: f64,
    /// The acceleration update, one row per object (static objects as one row).
    pub update: Vec<LogRow>,
    /// Tracing time per view, in the order traced.
    pub view_seconds: Vec<(View, f64)>,
    pub rays: RayCounts,
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
        FrameTracer {
            p,
            animations,
            updater,
        }
    }

    /// Traces `views` of `frame`. `on_tile` is called once per finished tile, from any thread.
    pub fn trace(
        &mut self,
        frame: u32,
        views: &[View],
        on_tile: &(dyn Fn(View) + Sync),
    ) -> (StereoFrame, FrameStats) {
        let (p, spec) = (self.p, &self.p.spec);
        let mut stats = FrameStats::default();
        let t = Instant::now();
        let time = frame as f32 / spec.frames.fps;
        let posed = p.scene.pose_at(&self.animations, time);
        stats.pose_seconds = t.elapsed().as_secs_f64();

        let (accel, update_rows) = self.updater.update(&posed);
        stats.update = update_rows;
        let (camera_world, yfov, znear, zfar) = frame_camera(p, &posed);
        let lights = if posed.lights.is_empty() {
            vec![head_light(&camera_world, &posed)]
        } else {
            posed.lights.clone()
        };
        let integrator = Integrator {
            scene: SceneView {
                accel: &accel,
                geometry: &posed.geometry,
                materials: &p.scene.materials,
                textures: &p.scene.textures,
                lights: &lights,
            },
            settings: TraceSettings {
                max_depth: spec.render.max_depth,
                shading: spec.render.shading,
                background: Vec3::from(spec.render.background),
            },
        };
        let rig = RigParams {
            rig: spec.stereo.rig,
            interaxial: spec.stereo.interaxial,
            convergence: spec.stereo.convergence,
            width: spec.render.width,
            height: spec.render.height,
            yfov,
            znear,
            zfar,
        };
        let mut traced = StereoFrame {
            frame,
            views: Vec::new(),
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
        let mut images = Vec::new();
        let mut source: Option<(EyeCamera, Vec<Vec<SourceSample>>)> = None;
        for pass in passes {
            let cameras: Vec<EyeCamera> = pass
                .iter()
                .map(|&v| EyeCamera::new(camera_world, &rig, v))
                .collect();
            let t = Instant::now();
            let reprojection = source.as_ref().map(|(source_camera, samples)| {
                Reprojection::new(
                    samples,
                    source_camera,
                    &cameras[0],
                    (spec.render.width as usize, spec.render.height as usize),
                    TILE,
                    zfar.is_none(),
                    take_radiance,
                )
            });
            let role = match (&reprojection, pass[0]) {
                (Some(r), _) => ViewRole::Target(r),
                (None, View::LEFT) if reproject => ViewRole::Source,
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
            let rendered = render_views(&integrator, &films, &|k| on_tile(pass[k]));
            let secs = t.elapsed().as_secs_f64() / pass.len() as f64;
            stats.rays.add(&rendered.counts);
            if matches!(role, ViewRole::Source) {
                source = Some((cameras[0].clone(), rendered.samples));
            }
            for (view, image) in pass.into_iter().zip(rendered.images) {
                stats.view_seconds.push((view, secs));
                images.push((view, image));
            }
        }
        // The views in the order asked for.
        for view in views {
            let i = images.iter().position(|(v, _)| v == view).expect("traced");
            traced.views.push(images.swap_remove(i));
        }
        (traced, stats)
    }
}

/// The camera placement and lens for a frame, with the scene's fallbacks applied.
fn frame_camera(p: &LoadedPipeline, posed: &PosedScene) -> (Mat4, f32, f32, Option<f32>) {
    match p.camera_instance {
        Some(i) => {
            let pc = &posed.cameras[i];
            let def = &p.scene.cameras[pc.camera];
            (pc.world, def.yfov, def.znear, def.zfar)
        }
        None => {
            let (lo, hi) = posed
                .geometry
                .bounds()
                .unwrap_or((Vec3::splat(-1.0), Vec3::splat(1.0)));
            let (def, world) = framing_camera(lo, hi);
            (world, def.yfov, def.znear, def.zfar)
        }
    }
}

/// A scene without lights gets a head-light: a point light at the rig's centre whose intensity is
/// `pi * d^2` (d: distance to the centre of the scene's bounds), so a white diffuse surface facing
/// the camera at the centre has radiance 1.
fn head_light(camera: &Mat4, posed: &PosedScene) -> Light {
    let position = camera.transform_point3(Vec3::ZERO);
    let center = posed
        .geometry
        .bounds()
        .map_or(Vec3::ZERO, |(lo, hi)| (lo + hi) * 0.5);
    let d2 = (center - position).length_squared().max(1e-6);
    Light {
        kind: LightKind::Point,
        power: Vec3::splat(std::f32::consts::PI * d2),
        position,
        direction: camera.transform_vector3(Vec3::NEG_Z),
        range: None,
    }
}
