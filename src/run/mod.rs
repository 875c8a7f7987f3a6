//! The run: how frames are made from a loaded pipeline and kept. `frame_loop` drives every
//! frame, `trace` poses the scene, brings the kd-tree up to date and traces one frame's views,
//! `rig_plan` places the eyes (depth budget, auto interaxial and convergence), `head_light` lights
//! a scene that has none, `outputs` writes what each output makes of a frame, `frame_log` records
//! each frame's figures, `memory` estimates what a render needs before it starts, `interrupt`
//! stops cleanly on Ctrl-C, and `depth_check` reports the rig's parallax without rendering. A
//! render farm splits the range (`shard`), records each finished frame (`manifest`, with
//! `tool_id` naming the executable that made it) and joins the shards' work (`assemble`).

mod assemble;
mod depth_check;
mod frame_log;
mod frame_loop;
mod head_light;
mod interrupt;
mod manifest;
mod memory;
mod outputs;
mod rig_plan;
mod shard;
mod tool_id;
mod trace;

pub use assemble::{Assembled, assemble};
pub use depth_check::{DepthReport, depth_check};
pub use frame_log::FRAME_LOG_COLUMNS;
pub use frame_loop::{RunOptions, RunSummary, run};
pub use memory::{
    BYTES_PER_TRIANGLE, Bytes, MemoryEstimate, MemoryLimit, memory_limit, parse_memory_limit,
};
pub use outputs::StereoFrame;
pub use rig_plan::{DepthSummary, FrameProbe, FrameRig, RigPlanner};
pub use shard::{Shard, ShardArg, parse_shard};
pub use trace::{FrameStats, FrameTracer};
