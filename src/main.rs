//! Command line: parses arguments, calls the library, prints its reports and errors, and maps
//! errors to exit statuses. Every report is a `Display` of a library type.

use clap::Parser;
use std::io::IsTerminal;
use std::process::ExitCode;
use stereotrace::bench::{accel, memory, sweep};
use stereotrace::pipeline::{LoadedPipeline, RunOptions};
use stereotrace::{Error, Result, compare, info, thread_pool};

mod cli;
use cli::{BenchCommand, Cli, Command};

/// Counts heap bytes so that `bench sweep` can report each combination's peak.
#[global_allocator]
static ALLOCATOR: memory::CountingAllocator = memory::CountingAllocator;

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
            // Warnings say what the render will not do as asked: --quiet keeps them.
            warn_all(&p.warnings);
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
