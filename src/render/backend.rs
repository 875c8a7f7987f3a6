//! Which processor traces a frame: the CPU (`render/`'s integrator on all cores) or the GPU
//! (`gpu/`, built with the cargo feature `gpu`).

use serde::Deserialize;

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Backend {
    #[default]
    Cpu,
    Gpu,
}

impl Backend {
    /// Whether this build can trace with it.
    pub fn built(self) -> bool {
        self == Backend::Cpu || cfg!(feature = "gpu")
    }

    pub fn name(self) -> &'static str {
        match self {
            Backend::Cpu => "cpu",
            Backend::Gpu => "gpu",
        }
    }
}

/// What a build without the GPU backend says when asked for it.
pub const NOT_BUILT: &str = "this stereotrace was built without the GPU backend: build it with \
                             `cargo build --release --features gpu` (or use backend = \"cpu\")";
