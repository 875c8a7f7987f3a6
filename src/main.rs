//! Command line: parses arguments, calls the library, prints its reports and errors, and maps
//! errors to exit statuses. Every report is a `Display` of a library type.

use clap::{Parser, Subcommand};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;
use stereotrace::accel::SplitMethod;
use stereotrace::bench::{accel, memory, sweep};
use stereotrace::pipeline::{LoadedPipeline, RunOptions, parse_frame_range};
use stereotrace::{Error, Result, compare, info, thread_pool};

/// Counts heap bytes so that `bench sweep` can report each combination's peak.
#[global_allocator]
static ALLOCATOR: memory::CountingAllocator = memory::CountingAllocator;

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
        #[arg(long, value_parser = parse_frame_range)]
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
        a: PathBuf,
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
    /// Describe a glTF scene.
    Info {
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
    },
}

#[derive(Subcommand)]
enum BenchCommand {
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

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}

fn warn_all(warnings: &[String]) {
    for w in warnings {
        eprintln!("warning: {w}");
    }
}

fn run(cli: Cli) -> Result<ExitCode> {
    match cli.command {
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
            let summary = stereotrace::pipeline::run(&p, &opts)?;
            if !quiet {
                eprintln!("{summary}");
            }
        }
        Command::New { scene, output } => {
            if let Some(text) = stereotrace::pipeline::new_pipeline(&scene, output.as_deref())? {
                print!("{text}");
            }
        }
        Command::Check { pipeline } => {
            let p = LoadedPipeline::load(&pipeline)?;
            warn_all(&p.warnings);
            println!("{p}");
        }
        Command::Compare {
            a,
            b,
            thresholds,
            diff,
            scale,
            json,
        } => {
            let result = compare::compare_files_with_diff(
                &a,
                &b,
                &thresholds,
                diff.as_deref().map(|out| (out, scale)),
            )
            .map_err(|e| Error::Compare(Box::new(e)))?;
            if json {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&result).map_err(internal)?
                );
            } else {
                let report = compare::Report {
                    a: &a,
                    b: &b,
                    thresholds: &thresholds,
                    result: &result,
                };
                println!("{report}");
            }
            return Ok(ExitCode::from(result.verdict as u8));
        }
        Command::Bench(BenchCommand::Accel { options, threads }) => {
            println!("{}", accel::csv_header());
            let rows = thread_pool(threads)?
                .install(|| accel::bench_accel(&options, |row| println!("{}", row.csv())))?;
            if let Some(stem) = &options.chart {
                accel::chart(&rows, stem)?;
            }
        }
        Command::Bench(BenchCommand::ChartAccel { table, chart }) => {
            accel::chart(&accel::read_table(&table)?, &chart)?;
            eprintln!("wrote {0}.svg and {0}.png", chart.display());
        }
        Command::Bench(BenchCommand::Sweep { options, threads }) => {
            let results = thread_pool(threads)?
                .install(|| sweep::sweep(&options, |line| eprintln!("{line}")))?;
            println!("{}", sweep::Table(&results));
            eprintln!(
                "wrote {0}/results.csv, {0}/summary.csv, {0}/chart.svg and {0}/chart.png",
                options.out_dir.display()
            );
        }
        Command::Info {
            scene,
            accel,
            split,
            json,
        } => {
            let s = stereotrace::scene::Scene::load(&scene)?;
            let report = info::scene_info(&s, accel.then_some(split));
            if json {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&report).map_err(internal)?
                );
            } else {
                print!("{report}");
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// A report that cannot be serialized is a program bug, not bad input.
fn internal(e: serde_json::Error) -> Error {
    Error::Internal(format!("cannot serialize the report: {e}"))
}
