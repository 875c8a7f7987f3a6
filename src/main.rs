//! Command line: parses arguments, calls the library, prints its reports and errors, and maps
//! errors to exit statuses. Every report is a `Display` of a library type.

use clap::Parser;
use std::io::IsTerminal;
use std::process::ExitCode;
use stereotrace::bench::{accel, memory, sweep};
use stereotrace::huge_pages::HugePageSystem;
use stereotrace::pipeline::LoadedPipeline;
use stereotrace::run::{Bytes, MemoryEstimate, RunOptions, assemble, depth_check, memory_limit};
use stereotrace::{Error, Result, compare, info, thread_pool};

mod cli;
mod manual;
use cli::{BenchCommand, Cli, Command};

/// Counts heap bytes so that `bench sweep` can report each combination's peak, over the system
/// allocator with huge pages for large blocks.
#[global_allocator]
static ALLOCATOR: memory::CountingAllocator<HugePageSystem> =
    memory::CountingAllocator(HugePageSystem);

/// Writes a report line to standard output (see `emit`).
macro_rules! out {
    ($($arg:tt)*) => { emit(format_args!($($arg)*), true) };
}

/// Writes a message line to standard error; a standard error that cannot be written is no reason
/// to fail a render.
macro_rules! note {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($arg)*);
    }};
}

/// Writes to standard output. A closed pipe (`stereotrace info x.glb | head -1`) ends the program
/// quietly, as other command-line tools do; any other failure (a full disk) exits 1, saying so.
fn emit(args: std::fmt::Arguments, newline: bool) {
    use std::io::Write as _;
    let mut stdout = std::io::stdout().lock();
    let written = stdout
        .write_fmt(args)
        .and_then(|()| {
            if newline {
                stdout.write_all(b"\n")
            } else {
                Ok(())
            }
        })
        .and_then(|()| stdout.flush());
    match written {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => std::process::exit(0),
        Err(e) => {
            note!("error: cannot write to standard output: {e}");
            std::process::exit(1);
        }
    }
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(code) => code,
        Err(e) => {
            note!("error: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}

fn warn_all(warnings: &[String]) {
    for w in warnings {
        note!("warning: {w}");
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
            shard,
            resume,
            max_memory,
            backend,
        } => {
            let mut p = LoadedPipeline::load(&pipeline)?;
            if let Some(b) = backend {
                p = p.with_overrides(&[("render.backend".into(), b.name().into())])?;
            }
            MemoryEstimate::of(&p).check(&p.file, memory_limit(max_memory))?;
            // Warnings say what the render will not do as asked: --quiet keeps them.
            warn_all(&p.warnings);
            let opts = RunOptions {
                frames,
                threads,
                out_dir: out,
                progress: !quiet && std::io::stderr().is_terminal(),
                shard,
                resume,
            };
            let summary = stereotrace::run::run(&p, &opts)?;
            if !quiet {
                note!("{summary}");
            } else if let Some(w) = summary.depth.warning() {
                note!("warning: {w}");
            }
        }
        Command::Assemble {
            pipeline,
            out,
            threads,
            quiet,
        } => {
            let p = LoadedPipeline::load(&pipeline)?;
            warn_all(&p.warnings);
            let threads = threads.unwrap_or(p.spec.render.threads);
            let done = thread_pool(threads)?.install(|| assemble(&p, &out))?;
            if !quiet {
                note!("{done}");
            }
        }
        Command::New { scene, output } => {
            if let Some(text) = stereotrace::pipeline::new_pipeline(&scene, output.as_deref())? {
                emit(format_args!("{text}"), false);
            }
        }
        Command::Check {
            pipeline,
            max_memory,
            depth,
            frames,
            threads,
        } => {
            let p = LoadedPipeline::load(&pipeline)?;
            warn_all(&p.warnings);
            let estimate = MemoryEstimate::of(&p);
            estimate.check(&p.file, memory_limit(max_memory))?;
            out!("{p}; about {} of memory", Bytes(estimate.total()));
            if depth {
                let threads = threads.unwrap_or(p.spec.render.threads);
                let report = thread_pool(threads)?.install(|| depth_check(&p, frames))?;
                out!("{report}");
                if let Some(w) = report.summary.warning() {
                    note!("warning: {w}");
                }
            }
        }
        Command::Compare {
            a,
            b,
            thresholds,
            diff,
            scale,
            json,
        } => {
            if let Some(d) = &diff {
                compare::check_diff_target(&a, &b, d)?;
            }
            let result = compare::compare_files_with_diff(
                &a,
                &b,
                &thresholds,
                diff.as_deref().map(|out| (out, scale)),
            )
            .map_err(|e| Error::Compare(Box::new(e)))?;
            if json {
                out!(
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
                out!("{report}");
            }
            return Ok(ExitCode::from(result.verdict as u8));
        }
        Command::Bench(BenchCommand::Accel { options, threads }) => {
            out!("{}", accel::csv_header());
            let rows = thread_pool(threads)?.install(|| {
                accel::bench_accel(
                    &options,
                    |row| out!("{}", row.csv()),
                    |line| note!("{line}"),
                )
            })?;
            if let Some(stem) = &options.chart {
                accel::chart(&rows, stem)?;
            }
        }
        Command::Bench(BenchCommand::ChartAccel { table, chart }) => {
            accel::chart(&accel::read_table(&table)?, &chart)?;
            note!("wrote {0}.svg and {0}.png", chart.display());
        }
        Command::Bench(BenchCommand::Sweep { options, threads }) => {
            let results =
                thread_pool(threads)?.install(|| sweep::sweep(&options, |line| note!("{line}")))?;
            out!("{}", sweep::Table(&results));
            note!(
                "wrote {0}/results.csv, {0}/summary.csv, {0}/chart.svg and {0}/chart.png",
                options.out_dir.display()
            );
        }
        Command::Completions { shell } => manual::completions(shell),
        Command::Man { out } => {
            for page in manual::man_pages(&out)? {
                note!("wrote {}", page.display());
            }
        }
        Command::Info {
            scene,
            accel,
            split,
            json,
            max_memory,
        } => {
            let s = stereotrace::scene::Scene::load(&scene)?;
            let report = info::scene_info(&s, accel.then_some(split), memory_limit(max_memory))?;
            if json {
                out!(
                    "{}",
                    serde_json::to_string_pretty(&report).map_err(internal)?
                );
            } else {
                emit(format_args!("{report}"), false);
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// A report that cannot be serialized is a program bug, not bad input.
fn internal(e: serde_json::Error) -> Error {
    Error::Internal(format!("cannot serialize the report: {e}"))
}
