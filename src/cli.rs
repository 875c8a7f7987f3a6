//! The command line's arguments and help: what each command and argument is, with examples.

use clap::{Parser, Subcommand};
use std::path::PathBuf;
use stereotrace::accel::SplitMethod;
use stereotrace::bench::{accel, sweep};
use stereotrace::compare;
use stereotrace::pipeline::parse_frame_range;
use stereotrace::run::{MemoryLimit, ShardArg, parse_memory_limit, parse_shard};

#[derive(Parser)]
#[command(
    name = "stereotrace",
    version,
    about = "Stereo ray tracing of animated glTF 2.0 scenes",
    after_help = "Examples:\n  \
      stereotrace new model.glb -o my.toml      write a pipeline for a model\n  \
      stereotrace check my.toml                 validate it and load its scene\n  \
      stereotrace render my.toml --out out      render every frame into out/\n  \
      stereotrace render my.toml --frames 12    render frame 12 only\n  \
      stereotrace info model.glb                what the model holds\n  \
      stereotrace compare a.exr b.exr --fail 0.02 --diff err.png\n\n\
      docs/guide/pipeline.md lists every key of a pipeline file; `stereotrace man` writes the man pages."
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand)]
pub enum Command {
    /// Render a pipeline: every frame, every eye, every output.
    #[command(after_help = "Examples:\n  \
        stereotrace render pipelines/default.toml\n  \
        stereotrace render my.toml --out out --frames 0..23 --threads 8\n  \
        stereotrace render my.toml --out out --shard 2/8     one of 8 farm tasks\n  \
        stereotrace render my.toml --out out --shard auto    the task of a Slurm job array\n  \
        stereotrace render my.toml --out out --resume        after a crash: only what is left\n\n\
        Ctrl-C stops after the tiles being traced and keeps every finished frame (exit 130).\n\
        Every finished frame is listed in OUT/manifest*.jsonl with its files' hashes; --resume\n\
        skips the frames listed there whose files are unchanged and that this pipeline made.")]
    Render {
        /// Pipeline file (TOML).
        pipeline: PathBuf,
        /// Frame range A..B (inclusive) or one frame N, overriding the pipeline's [frames].
        #[arg(long, value_parser = parse_frame_range)]
        frames: Option<(u32, u32)>,
        /// Worker threads (0 = all cores), overriding [render] threads.
        #[arg(long)]
        threads: Option<usize>,
        /// Output directory; output paths are relative to it.
        #[arg(long, default_value = ".")]
        out: PathBuf,
        /// No progress bars and no summary line (warnings are still printed).
        #[arg(long)]
        quiet: bool,
        /// Render the I-th of N contiguous blocks of the range (I/N), or the scheduler's task:
        /// `auto` (Slurm job arrays) or `auto/N` (Kubernetes Indexed Jobs of N completions).
        /// Videos, pseudo-stereo and whole-range GIFs are then left to `assemble`.
        #[arg(long, value_parser = parse_shard, conflicts_with = "frames")]
        shard: Option<ShardArg>,
        /// Skip frames already finished, by this pipeline, with unchanged files (the manifest);
        /// over the whole range, the sequence outputs are made at the end.
        #[arg(long)]
        resume: bool,
        /// Refuse before allocating when the render would need more memory than SIZE (512M,
        /// 16G, or none); default: three quarters of the machine's memory.
        #[arg(long, value_name = "SIZE", value_parser = parse_memory_limit)]
        max_memory: Option<MemoryLimit>,
        /// Trace on the CPU or the GPU (built with `--features gpu`), overriding [render]
        /// backend.
        #[arg(long, value_enum)]
        backend: Option<stereotrace::render::Backend>,
    },
    /// Check that every frame of a farm's shards is finished and current, merge their frame
    /// logs, and write the outputs that need the whole sequence (videos, pseudo-stereo frames,
    /// whole-range wobble GIFs). Exit 1 with the missing or stale frames listed otherwise.
    Assemble {
        /// Pipeline file (TOML).
        pipeline: PathBuf,
        /// The output directory the shards rendered into.
        #[arg(long, default_value = ".")]
        out: PathBuf,
        /// Worker threads (0 = all cores).
        #[arg(long)]
        threads: Option<usize>,
        /// No summary line.
        #[arg(long)]
        quiet: bool,
    },
    /// Validate a pipeline and its scene without rendering.
    #[command(after_help = "Examples:\n  \
        stereotrace check my.toml\n  \
        stereotrace check my.toml --depth              each frame's rig and parallax, no render\n  \
        stereotrace check my.toml --depth --frames 0..47")]
    Check {
        /// Pipeline file (TOML).
        pipeline: PathBuf,
        /// Probe every frame's depth (one closest-hit ray per probe pixel, no shading) and print
        /// the rig each frame gets and its parallax against the depth budget: what the render
        /// will log in frame-log.csv.
        #[arg(long)]
        depth: bool,
        /// With --depth: frame range A..B (inclusive) or one frame N instead of [frames].
        #[arg(long, value_parser = parse_frame_range, requires = "depth")]
        frames: Option<(u32, u32)>,
        /// With --depth: worker threads (0 = all cores).
        #[arg(long, requires = "depth")]
        threads: Option<usize>,
        /// Refuse before allocating when the render would need more memory than SIZE (512M,
        /// 16G, or none); default: three quarters of the machine's memory.
        #[arg(long, value_name = "SIZE", value_parser = parse_memory_limit)]
        max_memory: Option<MemoryLimit>,
    },
    /// Write a commented pipeline for a scene (its cameras, animations and frame range filled
    /// in, every output kind present): `stereotrace new scene.glb -o my.toml`.
    New {
        /// The glTF scene (.gltf or .glb).
        scene: PathBuf,
        /// Pipeline file to create (default: standard output).
        #[arg(short, long)]
        output: Option<PathBuf>,
    },
    /// Compare two images with OpenImageIO idiff's rules and exit statuses (0 pass, 1 warning,
    /// 2 failure, 4 unreadable input); multi-view EXR files are compared view by view.
    Compare {
        /// First image (EXR, PNG or JPEG).
        a: PathBuf,
        /// Second image, compared with the first.
        b: PathBuf,
        #[command(flatten)]
        thresholds: compare::Thresholds,
        /// Write the absolute difference (times --scale) as a float EXR, or as a grey PNG of
        /// each pixel's largest channel difference when DIFF ends in .png (one file per view,
        /// the view name added before the extension when there are several).
        #[arg(long)]
        diff: Option<PathBuf>,
        /// Scale of the difference image.
        #[arg(long, default_value_t = 1.0)]
        scale: f32,
        /// Machine-readable report on stdout.
        #[arg(long)]
        json: bool,
    },
    /// Speed measurements.
    #[command(subcommand)]
    Bench(BenchCommand),
    /// Print a shell completion script for bash, zsh, fish, elvish or powershell.
    #[command(after_help = "Examples:\n  \
        stereotrace completions bash > ~/.local/share/bash-completion/completions/stereotrace\n  \
        stereotrace completions zsh > ~/.zfunc/_stereotrace          (with fpath+=~/.zfunc)\n  \
        stereotrace completions fish > ~/.config/fish/completions/stereotrace.fish")]
    Completions {
        /// The shell.
        #[arg(value_enum)]
        shell: clap_complete::Shell,
    },
    /// Write the man pages: stereotrace.1 and one page per command (stereotrace-render.1, ...).
    #[command(after_help = "Examples:\n  \
        stereotrace man --out ~/.local/share/man/man1 && man stereotrace-render")]
    Man {
        /// Folder the pages are written into.
        #[arg(long, default_value = ".")]
        out: PathBuf,
    },
    /// Describe a glTF scene.
    Info {
        /// The glTF scene (.gltf or .glb).
        scene: PathBuf,
        /// Also build the kd-tree and print its statistics.
        #[arg(long)]
        accel: bool,
        /// Split strategy for --accel.
        #[arg(long, value_enum, default_value = "sah")]
        split: SplitMethod,
        /// Machine-readable output.
        #[arg(long)]
        json: bool,
        /// Refuse before allocating when the kd-tree of --accel would need more memory than SIZE (512M,
        /// 16G, or none); default: three quarters of the machine's memory.
        #[arg(long, value_name = "SIZE", value_parser = parse_memory_limit)]
        max_memory: Option<MemoryLimit>,
    },
}

#[derive(Subcommand)]
pub enum BenchCommand {
    /// kd-tree build time and ray throughput per split strategy, with baselines on identical rays.
    Accel {
        #[command(flatten)]
        options: accel::AccelBenchOptions,
        /// Worker threads (0 = all cores).
        #[arg(long, default_value_t = 0)]
        threads: usize,
    },
    /// Chart a table written by `bench accel --csv` without measuring again.
    ChartAccel {
        /// The CSV table.
        table: PathBuf,
        /// Chart path without extension: CHART.svg and CHART.png are written.
        chart: PathBuf,
    },
    /// Render a pipeline for every combination of swept keys; time each and measure its error
    /// against a high-quality render. Writes results.csv, summary.csv and chart.svg/.png.
    Sweep {
        #[command(flatten)]
        options: sweep::SweepOptions,
        /// Worker threads (0 = all cores).
        #[arg(long, default_value_t = 0)]
        threads: usize,
    },
}
