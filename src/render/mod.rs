//! `render/` turns a posed frame into linear radiance images, one per eye: the stereo rig, the
//! Whitted integrator and its shading models, pixel sampling, the tiled parallel frame loop, and
//! the depth probe with the stereo comfort rules it feeds.
//! It sees geometry only through `accel::Intersect` and never knows an output file format.

mod alpha;
mod backend;
mod camera;
mod comfort;
mod depth;
mod direct;
mod frame;
mod integrator;
mod reproject;
mod sampling;
mod shading;
mod surface;
mod view;

/// Rays the renderer hands the tree at once: the widest packet the tree walks
/// (`accel::WIDE_LANES`, eight where the CPU has AVX). Elsewhere the tree walks them as two
/// packets of four, with the same hits, so images do not depend on the CPU.
const BATCH: usize = crate::accel::WIDE_LANES;

pub use backend::{Backend, NOT_BUILT};
pub use camera::{EyeCamera, Rig, RigParams};
pub use comfort::{
    Budget, DepthRange, FloatingWindow, ParallaxModel, VIEWER_EYES, auto_interaxial,
    divergence_limit, view_window, window_need,
};
pub use depth::{DepthProbe, PROBE_COLUMNS, ProbeCamera, probe_grid};
pub use frame::{
    EyeReuse, FilmParams, Rendered, TILE, ViewFilm, ViewRole, render_views, tile_count,
};
pub use integrator::{Integrator, RECORDED_LIGHTS, RayCounts, TraceSettings, offset_origin};
pub use reproject::{EdgeTest, Reprojection, SourcePixels};
pub use sampling::{PixelSamples, pixel_sample};
pub use shading::ShadingModel;
pub use surface::SceneView;
pub use view::{Eye, View};
