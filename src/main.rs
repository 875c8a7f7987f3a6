//! Command line: parses arguments, calls the library, prints errors and maps them to exit codes.

use clap::{Parser, Subcommand};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;
use stereotrace::accel::SplitMethod;
use stereotrace::bench::{accel, memory, sweep};
use stereotrace::pipeline::LoadedPipeline;
use stereotrace::pipeline::run::{RunOptions, run};
use stereotrace::{Error, compare, info};

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
    /// Compare two images with OpenImageIO idiff's rules and exit statuses (0 pass, 1 warning,
    /// 2 failure, 4 unreadable input); multi-view EXR files are compared view by view.
    Compare {
        a: PathBuf,
        b: PathBuf,
        /// Failure threshold on the absolute difference of a value.
        #[arg(long, default_value_t = 1e-6)]
        fail: f32,
        /// Warning threshold on the absolute difference of a value.
        #[arg(long, default_value_t = 1e-6)]
        warn: f32,
        /// Relative failure threshold (difference over the mean magnitude of the two values).
        #[arg(long, default_value_t = 0.0)]
        failrelative: f32,
        /// Relative warning threshold.
        #[arg(long, default_value_t = 0.0)]
        warnrelative: f32,
        /// Percentage of pixels allowed to fail.
        #[arg(long, default_value_t = 0.0)]
        failpercent: f32,
        /// Percentage of pixels allowed to warn.
        #[arg(long, default_value_t = 0.0)]
        warnpercent: f32,
        /// Fail if any value differs by more than this.
        #[arg(long, default_value_t = f32::INFINITY)]
        hardfail: f32,
        /// Warn if any value differs by more than this.
        #[arg(long, default_value_t = f32::INFINITY)]
        hardwarn: f32,
        /// Number of failing pixels that still pass.
        #[arg(long, default_value_t = 0)]
        allowfailures: u64,
        /// Write the absolute difference (times --scale) as a float EXR (one file per view,
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
        split: SplitArg,
        /// Machine-readable output.
        #[arg(long)]
        json: bool,
    },
}

#[derive(Subcommand)]
enum BenchCommand {
    /// kd-tree build time and ray throughput per split strategy, with baselines on identical rays.
    Accel {
        /// glTF files, or generated:N for a generated mesh of about N triangles.
        #[arg(required = true)]
        scenes: Vec<String>,
        /// Split strategies to measure.
        #[arg(
            long,
            value_enum,
            value_delimiter = ',',
            default_value = "center,median,sah"
        )]
        split: Vec<SplitArg>,
        /// Runs per measurement; the median is reported.
        #[arg(long, default_value_t = 3)]
        repeat: usize,
        /// Write the table as CSV.
        #[arg(long)]
        csv: Option<PathBuf>,
        /// Replay primary rays from a file (u64 count, then 7 little-endian f32 per ray:
        /// origin, direction, t_max) instead of the camera's.
        #[arg(long)]
        rays: Option<PathBuf>,
        /// Replay shadow rays (any-hit) from a file in the same format.
        #[arg(long)]
        shadow_rays: Option<PathBuf>,
        /// Write each scene's primary and shadow rays into this folder in the replay format.
        #[arg(long)]
        save_rays: Option<PathBuf>,
        /// Camera rays per side of the square film.
        #[arg(long, default_value_t = 512)]
        film: u32,
        /// Worker threads (0 = all cores).
        #[arg(long, default_value_t = 0)]
        threads: usize,
        /// Also draw the table as a chart: CHART.svg and CHART.png (build time against trace
        /// time, Pareto front per scene).
        #[arg(long)]
        chart: Option<PathBuf>,
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
        /// Pipeline file (TOML).
        pipeline: PathBuf,
        /// KEY=V1,V2,...: a pipeline key by path and the values to try (repeatable), e.g.
        /// accel.split=center,sah  render.spp=1,4,16  render.shading=phong,cook-torrance.
        #[arg(long = "sweep", value_parser = sweep::parse_sweep)]
        sweeps: Vec<(String, Vec<String>)>,
        /// Runs per combination; times are medians with the fastest and slowest run.
        #[arg(long, default_value_t = 3)]
        repeat: usize,
        /// Folder for the results.
        #[arg(long, default_value = "out/sweep")]
        out: PathBuf,
        /// Frame range A..B (inclusive), overriding the pipeline's [frames].
        #[arg(long, value_parser = parse_range)]
        frames: Option<(u32, u32)>,
        /// Samples per pixel of the high-quality render [default: 4x the most swept, at least 64].
        #[arg(long)]
        reference_spp: Option<u32>,
        /// Recursion depth of the high-quality render [default: the deepest swept].
        #[arg(long)]
        reference_depth: Option<u32>,
        /// Per-channel error above which a pixel counts as wrong.
        #[arg(long, default_value_t = 0.02)]
        threshold: f32,
        /// Worker threads (0 = all cores).
        #[arg(long, default_value_t = 0)]
        threads: usize,
    },
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum SplitArg {
    Center,
    Median,
    Sah,
}

impl From<SplitArg> for SplitMethod {
    fn from(s: SplitArg) -> SplitMethod {
        match s {
            SplitArg::Center => SplitMethod::Center,
            SplitArg::Median => SplitMethod::Median,
            SplitArg::Sah => SplitMethod::Sah,
        }
    }
}

fn thread_pool(threads: usize) -> Result<rayon::ThreadPool, Error> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| Error::input(std::path::Path::new("--threads"), e.to_string()))
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
    if let Command::Compare { .. } = cli.command {
        return ExitCode::from(compare_command(cli.command));
    }
    match execute(cli.command) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(e.exit_code() as u8)
        }
    }
}

/// `compare` keeps idiff's exit statuses: its errors exit 4, not 2.
fn compare_command(command: Command) -> u8 {
    let Command::Compare {
        a,
        b,
        fail,
        warn,
        failrelative,
        warnrelative,
        failpercent,
        warnpercent,
        hardfail,
        hardwarn,
        allowfailures,
        diff,
        scale,
        json,
    } = command
    else {
        unreachable!("compare_command is only called for Command::Compare");
    };
    let t = compare::Thresholds {
        fail,
        warn,
        fail_relative: failrelative,
        warn_relative: warnrelative,
        fail_percent: failpercent,
        warn_percent: warnpercent,
        hard_fail: hardfail,
        hard_warn: hardwarn,
        allow_failures: allowfailures,
    };
    let result = compare::compare_files(&a, &b, &t).and_then(|r| {
        if let Some(out) = &diff {
            write_diffs(&a, &b, out, scale)?;
        }
        Ok(r)
    });
    let r = match result {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {e}");
            return 4;
        }
    };
    if json {
        println!(
            "{}",
            serde_json::to_string_pretty(&r).expect("comparison serializes to JSON")
        );
    } else {
        println!("Comparing \"{}\" and \"{}\"", a.display(), b.display());
        for (view, c) in &r.views {
            if !view.is_empty() {
                println!("view {view}:");
            }
            println!(
                "  Mean error = {:.6}  RMS error = {:.6}  Peak SNR = {:.3} dB",
                c.mean_error, c.rms_error, c.psnr
            );
            println!(
                "  Max error  = {} @ ({}, {}, {})",
                c.max_error,
                c.max_at.0,
                c.max_at.1,
                c.channels.get(c.max_at.2).map_or("?", String::as_str)
            );
            for (i, name) in c.channels.iter().enumerate() {
                println!(
                    "  {name:>6}: mean {:.6}  rms {:.6}  max {:.6}",
                    c.per_channel_mean[i], c.per_channel_rms[i], c.per_channel_max[i]
                );
            }
            println!(
                "  {} pixels ({:.3}%) over {}",
                c.warnings,
                100.0 * c.warnings as f64 / c.pixels as f64,
                warn
            );
            println!(
                "  {} pixels ({:.3}%) over {}",
                c.failures,
                c.percent_failed(),
                fail
            );
        }
        for m in &r.missing_views {
            println!("view '{m}' is in only one of the files");
        }
        println!(
            "{}",
            match r.verdict {
                compare::Verdict::Pass => "PASS",
                compare::Verdict::Warn => "WARNING",
                compare::Verdict::Fail => "FAILURE",
            }
        );
    }
    r.verdict as u8
}

fn write_diffs(
    a: &std::path::Path,
    b: &std::path::Path,
    out: &std::path::Path,
    scale: f32,
) -> Result<(), Error> {
    let va = compare::read_views(a)?;
    let vb = compare::read_views(b)?;
    let several = va.len() > 1;
    for (name, pa) in &va {
        if let Some((_, pb)) = vb.iter().find(|(n, _)| n == name) {
            let path = if several {
                let stem = out
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_default();
                out.with_file_name(format!("{stem}_{name}.exr"))
            } else {
                out.to_path_buf()
            };
            stereotrace::output::exr::write_planes(
                &path,
                &compare::difference_planes(pa, pb, scale),
            )?;
        }
    }
    Ok(())
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
                    "rendered {} frame(s), {} eye image(s), {} files; {:.1} M rays ({:.1} M primary, {:.1} M secondary, {:.1} M shadow) in {:.2} s: tracing {:.2} s ({:.2} M rays/s), outputs {:.2} s",
                    s.frames,
                    s.eyes_traced,
                    s.files.len(),
                    s.rays.total() as f64 * 1e-6,
                    s.rays.primary as f64 * 1e-6,
                    s.rays.secondary as f64 * 1e-6,
                    s.rays.shadow as f64 * 1e-6,
                    s.seconds,
                    s.trace_seconds,
                    s.rays.total() as f64 * 1e-6 / s.trace_seconds.max(1e-9),
                    s.output_seconds,
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
        Command::Bench(BenchCommand::Accel {
            scenes,
            split,
            repeat,
            csv,
            rays,
            shadow_rays,
            save_rays,
            film,
            threads,
            chart,
        }) => {
            let opts = accel::AccelBenchOptions {
                scenes,
                splits: split.into_iter().map(SplitMethod::from).collect(),
                repeat,
                csv,
                rays,
                shadow_rays,
                film,
                brute_force_budget: 2e9,
                save_rays,
            };
            println!("{}", accel::CSV_HEADER);
            let rows = thread_pool(threads)?
                .install(|| accel::bench_accel(&opts, |row| println!("{}", row.csv())))?;
            if let Some(stem) = chart {
                accel::chart(&rows, &stem)?;
            }
            Ok(())
        }
        Command::Bench(BenchCommand::ChartAccel { table, chart }) => {
            accel::chart(&accel::read_csv(&table)?, &chart)?;
            eprintln!("wrote {0}.svg and {0}.png", chart.display());
            Ok(())
        }
        Command::Bench(BenchCommand::Sweep {
            pipeline,
            sweeps,
            repeat,
            out,
            frames,
            reference_spp,
            reference_depth,
            threshold,
            threads,
        }) => {
            let opts = sweep::SweepOptions {
                pipeline,
                sweeps,
                repeat,
                out_dir: out.clone(),
                frames,
                reference_spp,
                reference_depth,
                threshold,
            };
            let results = thread_pool(threads)?
                .install(|| sweep::sweep(&opts, |line| eprintln!("{line}")))?;
            println!(
                "{:<40} {:>10} {:>9} {:>9} {:>12} {:>8}",
                "combination", "s/frame", "Mrays/s", "peak MB", "mean |err|", "PSNR"
            );
            for r in &results {
                println!(
                    "{:<40} {:>10.4} {:>9.2} {:>9} {:>12.6} {:>8.2}",
                    r.label(),
                    r.frame_seconds(),
                    r.mrays_per_second(),
                    r.peak_bytes
                        .map_or("-".into(), |b| format!("{:.1}", b as f64 / 1048576.0)),
                    r.mean_abs_error(),
                    r.psnr()
                );
            }
            eprintln!(
                "wrote {0}/results.csv, {0}/summary.csv, {0}/chart.svg and {0}/chart.png",
                out.display()
            );
            Ok(())
        }
        Command::Compare { .. } => unreachable!("compare is dispatched before execute"),
        Command::Info {
            scene,
            accel,
            split,
            json,
        } => {
            let s = stereotrace::scene::Scene::load(&scene)?;
            let report = info::scene_info(&s, accel.then_some(split.into()));
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
