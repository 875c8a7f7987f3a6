//! The command line's documentation made from its clap definitions: shell completion scripts
//! and man pages, so that neither can drift from the arguments `cli.rs` declares.

use crate::cli::Cli;
use clap::CommandFactory;
use std::path::{Path, PathBuf};
use stereotrace::Result;
use stereotrace::output::write_atomic;

/// Writes the completion script for `shell` to standard output.
pub fn completions(shell: clap_complete::Shell) {
    clap_complete::generate(
        shell,
        &mut Cli::command(),
        "stereotrace",
        &mut std::io::stdout(),
    );
}

/// Writes `stereotrace.1` and a page per command and subcommand (`stereotrace-bench-accel.1`)
/// into `dir`, each atomically; returns the files written.
pub fn man_pages(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut written = Vec::new();
    let mut pending = vec![(String::from("stereotrace"), Cli::command())];
    while let Some((name, command)) = pending.pop() {
        for sub in command.get_subcommands().filter(|s| s.get_name() != "help") {
            pending.push((format!("{name}-{}", sub.get_name()), sub.clone()));
        }
        let path = dir.join(format!("{name}.1"));
        let page = clap_mangen::Man::new(command.name(name.clone()));
        write_atomic(&path, |w| page.render(w))?;
        written.push(path);
    }
    written.sort();
    Ok(written)
}
