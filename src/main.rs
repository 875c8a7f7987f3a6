//! Command line: parses arguments, calls the library, prints errors and maps them to exit codes.

use clap::{Parser, Subcommand};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;
use stereotrace::accel::SplitMethod;
use stereotrace::pipeline::LoadedPipeline;
use stereotrace::pipeline::run::{RunOptions, run};
use stereotrace::{Error, info};

#[derive(Parser)]
#[command(
    name = "stereotrace",
    version,
    about = "Stereo ray tracing of animated glTF 2.0 scenes"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a pipeline: every frame, every eye, every output.
    Render {
        /// Pipeline file (TOML).
        pipeline: PathBuf,
        /// Frame range A..B (inclusive), overriding the pipeline's [frames].
        #[arg(long, value_parser = parse_range)]
        frames: Option<(u32, u32)>,
        /// Worker threads (0 = all cores), overriding [render] threads.
        #[arg(long)]
        threads: Option<usize>,
        /// Output directory; output paths are relative to it.
        #[arg(long, default_value = ".")]
        out: PathBuf,
        /// No progress bars and no summary line.
        #[arg(long)]
        quiet: bool,
    },
    /// Validate a pipeline and its scene without rendering.
    Check { pipeline: PathBuf },
    /// Describe a glTF scene.
    Info {
        scene: PathBuf,
        /// Also build the kd-tree and print its statistics.
        #[arg(long)]
        accel: bool,
        /// Split strategy for --accel.
        #[arg(long, value_enum, default_value = "sah")]
        split: SplitArg,
        /// Machine-readable output.
        #[arg(long)]
        json: bool,
    },
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum SplitArg {
    Center,
    Median,
    Sah,
}

fn parse_range(s: &str) -> Result<(u32, u32), String> {
    let (a, b) = s.split_once("..").ok_or("expected A..B, e.g. 0..23")?;
    let a: u32 = a
        .trim()
        .parse()
        .map_err(|_| format!("'{a}' is not a frame number"))?;
    let b: u32 = b
        .trim()
        .parse()
        .map_err(|_| format!("'{b}' is not a frame number"))?;
    if b < a {
        return Err(format!("{a}..{b} is empty"));
    }
    Ok((a, b))
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match execute(cli.command) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(e.exit_code() as u8)
        }
    }
}

fn warn_all(warnings: &[String]) {
    for w in warnings {
        eprintln!("warning: {w}");
    }
}

fn execute(command: Command) -> Result<(), Error> {
    match command {
        Command::Render {
            pipeline,
            frames,
            threads,
            out,
            quiet,
        } => {
            let p = LoadedPipeline::load(&pipeline)?;
            if !quiet {
                warn_all(&p.warnings);
            }
            let opts = RunOptions {
                frames,
                threads,
                out_dir: out,
                progress: !quiet && std::io::stderr().is_terminal(),
            };
            let s = run(&p, &opts)?;
            if !quiet {
                eprintln!(
                    "rendered {} frame(s), {} eye image(s), {} files; {:.1} M rays ({:.1} M primary, {:.1} M secondary, {:.1} M shadow) in {:.2} s ({:.2} M rays/s traced)",
                    s.frames,
                    s.eyes_traced,
                    s.files.len(),
                    s.rays.total() as f64 * 1e-6,
                    s.rays.primary as f64 * 1e-6,
                    s.rays.secondary as f64 * 1e-6,
                    s.rays.shadow as f64 * 1e-6,
                    s.seconds,
                    s.rays.total() as f64 * 1e-6 / s.trace_seconds.max(1e-9),
                );
            }
            Ok(())
        }
        Command::Check { pipeline } => {
            let p = LoadedPipeline::load(&pipeline)?;
            warn_all(&p.warnings);
            println!(
                "{}: ok ({} triangles, {} output(s), frames {}..{})",
                pipeline.display(),
                p.scene.triangle_count(),
                p.spec.outputs.len(),
                p.spec.frames.start,
                p.spec.frames.end
            );
            Ok(())
        }
        Command::Info {
            scene,
            accel,
            split,
            json,
        } => {
            let s = stereotrace::scene::Scene::load(&scene)?;
            let method = match split {
                SplitArg::Center => SplitMethod::Center,
                SplitArg::Median => SplitMethod::Median,
                SplitArg::Sah => SplitMethod::Sah,
            };
            let report = info::scene_info(&s, accel.then_some(method));
            if json {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&report).expect("scene info serializes to JSON")
                );
            } else {
                print!("{report}");
            }
            Ok(())
        }
    }
}
