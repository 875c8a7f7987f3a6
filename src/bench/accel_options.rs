//! What `bench accel` is asked: the scenes, the methods, the walks and the rays, as command-line
//! options.

use super::rays::Eyes;
use crate::accel::SplitMethod;
use crate::render::Backend;
use std::path::PathBuf;

/// A method measured by `bench accel`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AccelMethod {
    /// A kd-tree by this split strategy, with this traversal cost K_T in its SAH (`None`: the
    /// builders' rule, `traversal_cost_for`).
    Split(SplitMethod, Option<f32>),
    BruteForce,
    #[cfg(feature = "baselines")]
    BvhCrate,
}

impl AccelMethod {
    pub fn name(&self) -> &'static str {
        match self {
            AccelMethod::Split(SplitMethod::Sah, _) => "sah",
            AccelMethod::Split(SplitMethod::SahExact, _) => "sah-exact",
            AccelMethod::Split(SplitMethod::Center, _) => "center",
            AccelMethod::Split(SplitMethod::Median, _) => "median",
            AccelMethod::BruteForce => "brute-force",
            #[cfg(feature = "baselines")]
            AccelMethod::BvhCrate => "bvh-crate",
        }
    }

    /// The row's name: `name`, with `@ktK` where a traversal cost was given.
    pub fn label(&self) -> String {
        match self {
            AccelMethod::Split(_, Some(kt)) => format!("{}@kt{kt}", self.name()),
            _ => self.name().to_string(),
        }
    }
}

#[derive(Clone, Debug, clap::Args)]
pub struct AccelBenchOptions {
    /// glTF files, or generated:N for a generated mesh of about N triangles.
    #[arg(required = true)]
    pub scenes: Vec<String>,
    /// Split strategies to measure.
    #[arg(
        long = "split",
        value_name = "SPLIT",
        value_enum,
        value_delimiter = ',',
        default_value = "center,median,sah"
    )]
    pub splits: Vec<SplitMethod>,
    /// The SAH's traversal cost K_T for the kd-tree builds, one set of rows per value (named
    /// `sah@ktK`), against the intersection cost K_I = 20: how the cost ratio shapes the tree and
    /// what it does to build and trace times. Default: the builders' rule by mesh size.
    #[arg(long = "traversal-cost", value_delimiter = ',', value_parser = parse_cost)]
    pub traversal_costs: Vec<f32>,
    /// Runs per measurement; the median is reported.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub repeat: u32,
    /// Times each ray set this many times per build (the median over all runs is reported):
    /// tracing takes a fraction of a second, so on a shared machine more samples steady it.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub trace_repeat: u32,
    /// How kd-tree rows trace: `single` (one ray at a time), `packet` (coherent runs of
    /// consecutive rays together as `closest_hits`/`any_hits` walk them: up to eight where the
    /// CPU has AVX, else four; rows named `METHOD+packets`) and/or `packet4` (runs of up to four
    /// on every CPU, `METHOD+packets4`). All find bit-identical hits.
    #[arg(
        long = "walk",
        value_enum,
        value_delimiter = ',',
        default_value = "single"
    )]
    pub walks: Vec<Walk>,
    /// Where kd-tree rows trace: `cpu` and/or `gpu` (built with the `gpu` cargo feature: the same
    /// tree walked on the GPU with a full stack, a short stack and kd-restart, rows
    /// `METHOD+gpu-WALK` with the adapter in the `device` column).
    #[arg(
        long = "backend",
        value_enum,
        value_delimiter = ',',
        default_value = "cpu"
    )]
    pub backends: Vec<Backend>,
    /// Write the table as CSV.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Replay primary rays from a file (u64 count, then 7 little-endian f32 per ray: origin,
    /// direction, t_max) instead of the camera's.
    #[arg(long)]
    pub rays: Option<PathBuf>,
    /// The replayed primary rays are a film of this many columns and rows (`1024x768`), row
    /// by row; needed by `--tile`.
    #[arg(long, value_parser = parse_size)]
    pub rays_film: Option<(u32, u32)>,
    /// Regroup the replayed rays into tiles of this many columns and rows (`4x2`, the
    /// renderer's packet of one eye) before tracing: the camera rays tile by tile, and the
    /// shadow rays, taken to be one per primary ray that hits in file order (as the peer
    /// workload makes them), in the order of their camera rays. Rays are still counted per ray.
    #[arg(long, value_parser = parse_size, requires = "rays_film")]
    pub tile: Option<(u32, u32)>,
    /// Replay shadow rays (any-hit) from a file in the same format.
    #[arg(long)]
    pub shadow_rays: Option<PathBuf>,
    /// Camera rays per side of the square film.
    #[arg(long, default_value_t = 512)]
    pub film: u32,
    /// The camera rays' eyes: `center` (one pinhole), or the stereo ray set, `both` eyes of an
    /// off-axis rig (interaxial a thirtieth of the convergence distance, the distance to the
    /// mesh's centre) in the order paired tracing walks them, or its `left` eye alone.
    #[arg(long, value_enum, default_value = "center")]
    pub eyes: Eyes,
    /// Brute force runs only while triangles x rays stays below this.
    #[arg(skip = 2e9)]
    pub brute_force_budget: f64,
    /// Write each scene's primary and shadow rays into this folder in the replay format
    /// (`<scene>_primary.rays`, `<scene>_shadow.rays`), so other ray tracers can be timed on
    /// identical rays.
    #[arg(long)]
    pub save_rays: Option<PathBuf>,
    /// Also draw the table as a chart: CHART.svg and CHART.png (build time against trace time,
    /// Pareto front per scene).
    #[arg(long)]
    pub chart: Option<PathBuf>,
}

/// How `bench accel` hands rays to a kd-tree.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Walk {
    Single,
    Packet,
    /// `Packet` held to four lanes where the CPU has AVX.
    #[value(name = "packet4")]
    Packet4,
}

/// `COLUMNSxROWS`, both from 1 to 65,536 (`--rays-film`, `--tile`).
fn parse_size(s: &str) -> std::result::Result<(u32, u32), String> {
    let parsed = s.split_once('x').and_then(|(w, h)| {
        let (w, h) = (w.trim().parse::<u32>().ok()?, h.trim().parse::<u32>().ok()?);
        ((1..=65_536).contains(&w) && (1..=65_536).contains(&h)).then_some((w, h))
    });
    parsed.ok_or_else(|| format!("'{s}' is not COLUMNSxROWS (each 1 to 65536)"))
}

/// A cost for `--traversal-cost`: finite and positive.
fn parse_cost(s: &str) -> std::result::Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("'{s}' is not a positive number")),
    }
}
