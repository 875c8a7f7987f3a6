//! stereotrace: renders animated glTF 2.0 scenes in stereo by Whitted ray tracing.
//!
//! A pipeline file drives a frame loop; each frame flows one way through
//! `scene` (pose at time t) -> `accel` (kd-tree) -> `render` (trace both eyes) -> `output`.

pub mod accel;
pub mod bench;
pub mod compare;
pub mod error;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod huge_pages;
pub mod info;
pub mod output;
mod paths;
pub mod pipeline;
pub mod render;
pub mod run;
pub mod scene;

pub use error::{Error, Result};

/// The worker pool a command runs on (0 threads: one per core).
pub fn thread_pool(threads: usize) -> Result<rayon::ThreadPool> {
    // The bound the pipeline's `[render] threads` has, for `--threads` too.
    if threads > 1024 {
        return Err(Error::input(
            std::path::Path::new("--threads"),
            format!("must be between 0 (all cores) and 1024, got {threads}"),
        ));
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| {
            Error::input(
                std::path::Path::new("--threads"),
                format!("cannot start {threads} threads: {e}"),
            )
        })
}
