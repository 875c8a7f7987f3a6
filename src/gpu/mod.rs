//! The GPU backend (cargo feature `gpu`): wgpu compute shaders in WGSL, portable across Vulkan,
//! Metal and DX12, and run without a card by Mesa's software Vulkan driver (lavapipe). `device`
//! chooses and names the adapter, `buffers` and `split_array` hold the plumbing; `accel` uploads
//! the CPU's trees unchanged, part for part, and `kdtree` walks rays through them (`walk.wgsl`,
//! `parts.wgsl`, `rays.wgsl`); `whitted` uploads a posed
//! frame's surfaces, materials, textures and lights and runs the Whitted integrator of
//! `render/` on camera rays (`whitted.wgsl`); `frame` traces a frame's views with them. Nothing
//! here builds a tree of its own: the GPU walks the CPU's.

mod accel;
mod buffers;
mod device;
mod frame;
mod kdtree;
mod split_array;
mod whitted;

pub use accel::{GpuAccel, Uploads};
pub use device::{ADAPTER_VAR, Gpu};
pub use frame::GpuFrames;
pub use kdtree::{GpuRays, GpuTracer, GpuWalk};
pub use whitted::{GpuScene, GpuWhitted};
