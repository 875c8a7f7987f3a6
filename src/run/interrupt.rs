//! Ctrl-C (SIGINT) and SIGTERM during `render`: the first stops the run after the tiles being
//! traced, keeps every finished frame, writes the frame log and removes every temporary file;
//! a second one exits at once. Temporaries that a killed run left behind are removed by the
//! next run that writes into the same folders.

use super::outputs::Writer;
use crate::error::{Error, Result};
use crate::output::host_id;
use crate::pipeline::LoadedPipeline;
use crate::pipeline::written;
use std::path::{Path, PathBuf};
use std::sync::Once;
use std::sync::atomic::{AtomicBool, Ordering};

static REQUESTED: AtomicBool = AtomicBool::new(false);

/// Installs the handler once per process (later calls do nothing).
pub fn install() -> Result<()> {
    static INSTALL: Once = Once::new();
    let mut result = Ok(());
    INSTALL.call_once(|| {
        result = ctrlc::set_handler(|| {
            if REQUESTED.swap(true, Ordering::SeqCst) {
                // The second request: the user does not want to wait for the current tiles.
                std::process::exit(130);
            }
            eprintln!("\nstopping after the tiles being traced (Ctrl-C again to quit at once)");
        })
        .map_err(|e| Error::Internal(format!("cannot handle SIGINT and SIGTERM: {e}")));
    });
    result
}

/// The flag the handler sets; the tracer stops starting tiles once it is set.
pub fn flag() -> &'static AtomicBool {
    &REQUESTED
}

pub fn requested() -> bool {
    REQUESTED.load(Ordering::SeqCst)
}

/// The process and machine that made a temporary file, from its name: `.NAME.tmp-PID-HOST`
/// (atomic writes) or `.tmp-PID-HOST-NAME` (videos, whose name must keep its extension for
/// ffmpeg), HOST being `output::host_id` in 8 hex digits.
fn temporary_owner(name: &str) -> Option<(u32, u32)> {
    let rest = name.strip_prefix('.')?;
    let tag = match rest.strip_prefix("tmp-") {
        Some(r) => r,
        None => rest.rsplit_once(".tmp-")?.1,
    };
    let mut parts = tag.splitn(3, '-');
    let pid = parts.next()?.parse().ok()?;
    let host = parts.next().filter(|h| h.len() == 8)?;
    Some((pid, u32::from_str_radix(host, 16).ok()?))
}

/// Whether process `pid` runs. A killed process that its parent has not yet reaped (a zombie,
/// state `Z` in `/proc/PID/stat`) writes nothing more: it counts as gone.
fn running(proc: &Path, pid: u32) -> bool {
    let Ok(stat) = std::fs::read_to_string(proc.join(pid.to_string()).join("stat")) else {
        return false;
    };
    // `PID (COMMAND) STATE ...`; the command may itself hold spaces and parentheses.
    let state = stat
        .rsplit_once(')')
        .and_then(|(_, rest)| rest.split_whitespace().next());
    !matches!(state, Some("Z" | "X"))
}

/// Removes the temporary files in `dirs` whose process no longer runs (a run that was killed),
/// and returns them. Where processes cannot be looked up (no `/proc`), nothing is removed.
pub fn remove_stale_temporaries(dirs: &[PathBuf]) -> Vec<PathBuf> {
    let proc = Path::new("/proc");
    if !proc.join("self").exists() {
        return Vec::new();
    }
    let mut removed = Vec::new();
    for dir in dirs {
        let Ok(entries) = std::fs::read_dir(dir) else {
            continue;
        };
        for e in entries.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            // Another machine's temporaries belong to a worker this one cannot see: kept.
            let stale = temporary_owner(&name).is_some_and(|(pid, host)| {
                host == host_id() && pid != std::process::id() && !running(proc, pid)
            });
            if stale && e.path().is_file() && std::fs::remove_file(e.path()).is_ok() {
                removed.push(e.path());
            }
        }
    }
    removed.sort();
    removed.dedup();
    removed
}

/// The folders the frames `first..=last` write into: `--out`, and those of the outputs' files
/// and stored sequence frames.
pub(super) fn output_dirs(
    p: &LoadedPipeline,
    writers: &[Writer],
    out_dir: &Path,
    (first, last): (u32, u32),
) -> Vec<PathBuf> {
    let mut dirs = vec![out_dir.to_path_buf()];
    for w in written(&p.spec, &p.templates, first, last) {
        dirs.extend(out_dir.join(&w.path).parent().map(Into::into));
    }
    for w in writers {
        dirs.extend(
            w.sequence_source(first)
                .and_then(|s| s.parent().map(Into::into)),
        );
    }
    dirs.sort();
    dirs.dedup();
    dirs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temporary_names_give_their_process() {
        let ours = |name: &str| name.replace("TAG", &crate::output::temporary_tag());
        let me = Some((std::process::id(), host_id()));
        assert_eq!(temporary_owner(&ours(".f_0001_left.png.tmp-TAG")), me);
        assert_eq!(temporary_owner(&ours(".tmp-TAG-anaglyph.mp4")), me);
        assert_eq!(
            temporary_owner(".tmp-4242-00c0ffee-a-b.mkv"),
            Some((4242, 0xc0ffee))
        );
        assert_eq!(temporary_owner("f_0001_left.png"), None);
        assert_eq!(temporary_owner(".hidden"), None);
        assert_eq!(temporary_owner(".a.tmp-x"), None);
        assert_eq!(temporary_owner(".a.tmp-4242"), None);
    }

    #[test]
    fn this_process_runs_and_a_reaped_one_does_not() {
        let proc = Path::new("/proc");
        if !proc.join("self").exists() {
            return;
        }
        assert!(running(proc, std::process::id()));
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let pid = child.id();
        // Exited but not yet reaped: a zombie.
        std::thread::sleep(std::time::Duration::from_millis(200));
        assert!(!running(proc, pid));
        child.wait().unwrap();
        assert!(!running(proc, pid));
    }
}
