//! `render/` turns a posed frame into linear radiance images, one per eye: the stereo rig, the
//! Whitted integrator and its shading models, pixel sampling, and the tiled parallel frame loop.
//! It sees geometry only through `accel::Intersect` and never knows an output file format.

mod camera;
mod frame;
mod integrator;
mod reproject;
mod sampling;
mod shading;
mod view;

pub use camera::{EyeCamera, Rig, RigParams};
pub use frame::{
    EyeReuse, FilmParams, Rendered, TILE, ViewFilm, ViewRole, render_views, tile_count,
};
pub use integrator::{
    Integrator, RECORDED_LIGHTS, RayCounts, SceneView, TraceSettings, offset_origin,
};
pub use reproject::{Reprojection, SourceSample};
pub use shading::ShadingModel;
pub use view::{Eye, View};
