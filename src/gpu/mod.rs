//! The GPU backend (cargo feature `gpu`): wgpu compute shaders in WGSL, portable across Vulkan,
//! Metal and DX12, and run without a card by Mesa's software Vulkan driver (lavapipe). `device`
//! chooses and names the adapter; `kdtree` uploads the CPU's kd-tree unchanged and walks rays
//! through it. Nothing here builds a tree or shades: the GPU answers the same two questions as
//! `accel`, on the same tree.

mod device;
mod kdtree;

pub use device::{ADAPTER_VAR, Gpu};
pub use kdtree::{GpuRays, GpuTracer, GpuTree, GpuWalk};
