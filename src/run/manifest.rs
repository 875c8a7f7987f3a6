//! The render manifest: one JSON line per finished frame, appended after the frame's files are
//! renamed into place, with every file's path, size and SHA-256 and a fingerprint of what made
//! it. `--resume` and `assemble` trust a frame only when its line matches today's fingerprint
//! and its files still hash the same, so a torn file, a placeholder or a frame made before an
//! edit is never counted as done.
//!
//! Each line is one `write` to a file opened for appending, then `fsync`: a crash leaves at most
//! a torn last line, which reading ignores. Each process appends to the manifest of its own
//! shard (`manifest.jsonl` for a whole range), so workers on a shared file system never write
//! the same file; reading takes the lines of every `manifest*.jsonl` in the folder.

use super::tool_id::{hex, sha256_of, tool_id};
use crate::error::{Error, Result};
use crate::pipeline::LoadedPipeline;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// The manifest of a whole-range run, and the stem every shard's manifest shares.
pub const MANIFEST: &str = "manifest.jsonl";

/// One file as it was written: its path relative to `--out` (with `/`), size and hash.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct FileRecord {
    pub path: String,
    pub size: u64,
    pub sha256: String,
}

/// One manifest line: a finished frame (`frame`), or the sequence outputs `assemble` or a whole
/// run made of the frames `sequence` (first and last).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Entry {
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub frame: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub sequence: Option<(u32, u32)>,
    pub fingerprint: String,
    pub files: Vec<FileRecord>,
    /// The frame's rows of `frame-log.csv`, so that `assemble` can merge the shards' logs.
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub log: Vec<Vec<String>>,
}

fn sha256(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

/// What made a render's files: the pipeline after defaults (all but its thread count, which
/// never changes an image), the bytes of every scene file, and the tool's version and build.
pub fn fingerprint(p: &LoadedPipeline) -> Result<String> {
    let mut spec = p.spec.clone();
    spec.render.threads = 0;
    let mut h = Sha256::new();
    h.update(format!(
        "stereotrace {} {}\n",
        env!("CARGO_PKG_VERSION"),
        tool_id()
    ));
    h.update(format!("{spec:?}\n"));
    for file in &p.scene.files {
        // A file the scene names but never reads (an unused image) may be missing.
        let content = std::fs::File::open(file).and_then(sha256_of);
        h.update(format!(
            "{}\n",
            content.unwrap_or_else(|e| format!("unreadable: {}", e.kind()))
        ));
    }
    Ok(hex(&h.finalize()))
}

/// `path` relative to `out_dir`, with `/` between its parts.
fn relative(out_dir: &Path, path: &Path) -> String {
    let rel = path.strip_prefix(out_dir).unwrap_or(path);
    rel.components()
        .map(|c| c.as_os_str().to_string_lossy())
        .collect::<Vec<_>>()
        .join("/")
}

/// Records files just written under `out_dir`.
pub fn record(out_dir: &Path, files: &[PathBuf]) -> Result<Vec<FileRecord>> {
    files
        .iter()
        .map(|f| {
            let bytes = std::fs::read(f).map_err(|e| Error::io(f, e))?;
            Ok(FileRecord {
                path: relative(out_dir, f),
                size: bytes.len() as u64,
                sha256: sha256(&bytes),
            })
        })
        .collect()
}

/// Appends one line and waits until it is on the disk.
pub fn append(path: &Path, entry: &Entry) -> Result<()> {
    let mut line = serde_json::to_string(entry)
        .map_err(|e| Error::Internal(format!("cannot serialize a manifest line: {e}")))?;
    line.push('\n');
    let written = (|| {
        let mut f = std::fs::OpenOptions::new()
            .create(true)
            .read(true)
            .append(true)
            .open(path)?;
        // A line torn by a crash must not swallow this one: end it first.
        let len = f.metadata()?.len();
        if len > 0 {
            let mut last = [0u8];
            f.seek(SeekFrom::Start(len - 1))?;
            f.read_exact(&mut last)?;
            if last[0] != b'\n' {
                line.insert(0, '\n');
            }
        }
        // One write: appends of whole lines by several processes never interleave.
        f.write_all(line.as_bytes())?;
        f.sync_data()
    })();
    written.map_err(|e| Error::io(path, e))
}

/// Why a frame (or the sequence outputs) cannot be taken as done.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Stale {
    /// No manifest line: never finished (or finished by a run whose line was torn).
    NeverFinished,
    /// Made by another pipeline, scene or build of the tool.
    MadeDifferently,
    /// A file changed, went missing or was cut short after it was written.
    FileChanged(String),
}

impl std::fmt::Display for Stale {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Stale::FileChanged(why) => write!(f, "{why}"),
            other => write!(f, "{}", other.kind()),
        }
    }
}

/// Sorted frame numbers as runs of consecutive frames.
fn runs(frames: &[u32]) -> Vec<(u32, u32)> {
    let mut runs: Vec<(u32, u32)> = Vec::new();
    for &f in frames {
        match runs.last_mut() {
            Some((_, b)) if *b + 1 == f => *b = f,
            _ => runs.push((f, f)),
        }
    }
    runs
}

/// Runs of frames as text: `3..5, 9, 12..20` (the first 12 runs, then how many more).
fn show_runs(runs: &[(u32, u32)]) -> String {
    const SHOWN: usize = 12;
    let mut text: Vec<String> = runs
        .iter()
        .take(SHOWN)
        .map(|&(a, b)| {
            if a == b {
                a.to_string()
            } else {
                format!("{a}..{b}")
            }
        })
        .collect();
    if runs.len() > SHOWN {
        text.push(format!("and {} more ranges", runs.len() - SHOWN));
    }
    text.join(", ")
}

impl Stale {
    /// The reason without its details, as the frames it applies to are listed under.
    fn kind(&self) -> &'static str {
        match self {
            Stale::NeverFinished => "never finished",
            Stale::MadeDifferently => "made by a different pipeline, scene or build of stereotrace",
            Stale::FileChanged(_) => "whose files changed",
        }
    }
}

/// One line per reason: how many frames, which, and (for changed files) the first file.
/// `never` holds the runs of frames that have no manifest line at all.
fn describe_stale(stale: &[(Stale, u32)], never: &[(u32, u32)]) -> Vec<String> {
    let mut lines = Vec::new();
    for kind in [
        Stale::NeverFinished.kind(),
        Stale::MadeDifferently.kind(),
        Stale::FileChanged(String::new()).kind(),
    ] {
        let mine: Vec<&(Stale, u32)> = stale.iter().filter(|(s, _)| s.kind() == kind).collect();
        let mut frames: Vec<u32> = mine.iter().map(|(_, f)| *f).collect();
        frames.sort_unstable();
        let mut found = runs(&frames);
        if kind == Stale::NeverFinished.kind() {
            found.extend_from_slice(never);
            found.sort_unstable();
        }
        if found.is_empty() {
            continue;
        }
        let count: u64 = found.iter().map(|&(a, b)| u64::from(b - a) + 1).sum();
        let example = match mine.first() {
            Some((Stale::FileChanged(why), _)) => format!(" (first: {why})"),
            _ => String::new(),
        };
        lines.push(format!(
            "{count} frame(s) {kind}: {}{example}",
            show_runs(&found)
        ));
    }
    lines
}

/// What a manifest says of the frames `first..=last`: the current line of each finished frame,
/// and why each other frame is not done. Frames without any line are kept as runs, so a range
/// of a billion frames costs what its manifest holds, not what the range spans.
pub struct RangeStatus<'a> {
    pub current: BTreeMap<u32, &'a Entry>,
    pub stale: Vec<(Stale, u32)>,
    pub never: Vec<(u32, u32)>,
}

impl RangeStatus<'_> {
    /// Frames of the range that are not finished and current.
    pub fn not_done(&self) -> u64 {
        self.stale.len() as u64
            + self
                .never
                .iter()
                .map(|&(a, b)| u64::from(b - a) + 1)
                .sum::<u64>()
    }

    pub fn describe(&self) -> Vec<String> {
        describe_stale(&self.stale, &self.never)
    }
}

/// What a manifest line records: a frame, or the sequence outputs of a range.
type Recorded = (Option<u32>, Option<(u32, u32)>);

/// Every line of every manifest in a folder.
#[derive(Debug, Default)]
pub struct Manifest {
    entries: Vec<Entry>,
    /// Lines by what they record (frame, sequence range), oldest first: resuming a long range
    /// looks each frame up instead of scanning every line for it.
    index: HashMap<Recorded, Vec<usize>>,
    /// Lines that did not parse (a crash tore them).
    pub torn: usize,
}

impl Manifest {
    pub fn read(out_dir: &Path) -> Result<Manifest> {
        let mut m = Manifest::default();
        let Ok(dir) = std::fs::read_dir(out_dir) else {
            return Ok(m);
        };
        let mut files: Vec<PathBuf> = dir
            .flatten()
            .map(|e| e.path())
            .filter(|p| {
                p.file_name()
                    .and_then(|n| n.to_str())
                    .is_some_and(|n| n.starts_with("manifest") && n.ends_with(".jsonl"))
            })
            .collect();
        files.sort();
        for file in files {
            let text = std::fs::read(&file).map_err(|e| Error::io(&file, e))?;
            for line in text.split(|&b| b == b'\n').filter(|l| !l.is_empty()) {
                match serde_json::from_slice::<Entry>(line) {
                    Ok(e) => {
                        m.index
                            .entry((e.frame, e.sequence))
                            .or_default()
                            .push(m.entries.len());
                        m.entries.push(e);
                    }
                    Err(_) => m.torn += 1,
                }
            }
        }
        Ok(m)
    }

    /// The newest line of `frame` (or of the sequence over `sequence`) that `fingerprint` made
    /// and whose files are unchanged under `out_dir`, or why there is none.
    pub fn current(
        &self,
        out_dir: &Path,
        fingerprint: &str,
        frame: Option<u32>,
        sequence: Option<(u32, u32)>,
    ) -> std::result::Result<&Entry, Stale> {
        let mut why = Stale::NeverFinished;
        let lines = self.index.get(&(frame, sequence)).into_iter().flatten();
        for e in lines.rev().map(|&i| &self.entries[i]) {
            if e.fingerprint != fingerprint {
                why = why.max(Stale::MadeDifferently);
                continue;
            }
            match unchanged(out_dir, &e.files) {
                Ok(()) => return Ok(e),
                Err(changed) => why = why.max(Stale::FileChanged(changed)),
            }
        }
        Err(why)
    }

    /// The status of every frame of `first..=last` (see `RangeStatus`).
    pub fn check_range(
        &self,
        out_dir: &Path,
        fingerprint: &str,
        (first, last): (u32, u32),
    ) -> RangeStatus<'_> {
        let mut status = RangeStatus {
            current: BTreeMap::new(),
            stale: Vec::new(),
            never: Vec::new(),
        };
        let recorded: BTreeSet<u32> = self
            .index
            .keys()
            .filter_map(|&(frame, sequence)| frame.filter(|_| sequence.is_none()))
            .filter(|f| (first..=last).contains(f))
            .collect();
        let mut next = Some(first);
        for &f in &recorded {
            if let Some(n) = next.filter(|&n| n < f) {
                status.never.push((n, f - 1));
            }
            next = f.checked_add(1).filter(|&n| n <= last);
            match self.current(out_dir, fingerprint, Some(f), None) {
                Ok(e) => {
                    status.current.insert(f, e);
                }
                Err(why) => status.stale.push((why, f)),
            }
        }
        if let Some(n) = next {
            status.never.push((n, last));
        }
        status
    }
}

/// Whether every recorded file is still what was written.
fn unchanged(out_dir: &Path, files: &[FileRecord]) -> std::result::Result<(), String> {
    for f in files {
        let path = out_dir.join(&f.path);
        let bytes = match std::fs::read(&path) {
            Ok(b) => b,
            Err(_) => return Err(format!("{} is missing", f.path)),
        };
        if bytes.len() as u64 != f.size {
            return Err(format!(
                "{} has {} bytes, not the {} written",
                f.path,
                bytes.len(),
                f.size
            ));
        }
        if sha256(&bytes) != f.sha256 {
            return Err(format!("{} changed since it was written", f.path));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(frame: u32, fingerprint: &str, files: Vec<FileRecord>) -> Entry {
        Entry {
            frame: Some(frame),
            sequence: None,
            fingerprint: fingerprint.into(),
            files,
            log: Vec::new(),
        }
    }

    #[test]
    fn stale_frames_are_described_by_reason_in_ranges() {
        let stale = [
            (Stale::NeverFinished, 5),
            (Stale::NeverFinished, 3),
            (Stale::NeverFinished, 4),
            (Stale::NeverFinished, 9),
            (Stale::FileChanged("a.png is missing".into()), 7),
        ];
        assert_eq!(
            describe_stale(&stale, &[]),
            [
                "4 frame(s) never finished: 3..5, 9",
                "1 frame(s) whose files changed: 7 (first: a.png is missing)"
            ]
        );
    }

    #[test]
    fn only_current_unchanged_frames_count_and_torn_lines_are_ignored() {
        let dir = std::env::temp_dir().join(format!("stereotrace-manifest-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let a = dir.join("a.png");
        std::fs::write(&a, b"frame one").unwrap();
        let files = record(&dir, std::slice::from_ref(&a)).unwrap();
        assert_eq!(files[0].path, "a.png");
        let log = dir.join(MANIFEST);
        append(&log, &entry(1, "old", files.clone())).unwrap();
        append(&log, &entry(1, "new", files.clone())).unwrap();
        append(&log, &entry(2, "new", files.clone())).unwrap();
        // A crash in the middle of a line.
        let mut f = std::fs::OpenOptions::new().append(true).open(&log).unwrap();
        f.write_all(br#"{"frame":3,"finger"#).unwrap();
        drop(f);
        // The next line still stands on its own.
        append(&log, &entry(4, "new", files.clone())).unwrap();

        let m = Manifest::read(&dir).unwrap();
        assert_eq!(m.torn, 1);
        assert!(m.current(&dir, "new", Some(1), None).is_ok());
        assert!(m.current(&dir, "new", Some(4), None).is_ok());
        assert_eq!(
            m.current(&dir, "newer", Some(1), None).unwrap_err(),
            Stale::MadeDifferently
        );
        assert_eq!(
            m.current(&dir, "new", Some(3), None).unwrap_err(),
            Stale::NeverFinished
        );
        std::fs::write(&a, b"frame 1ne").unwrap();
        assert!(matches!(
            m.current(&dir, "new", Some(2), None),
            Err(Stale::FileChanged(w)) if w.contains("changed")
        ));
        std::fs::write(&a, b"frame").unwrap();
        assert!(matches!(
            m.current(&dir, "new", Some(2), None),
            Err(Stale::FileChanged(w)) if w.contains("5 bytes")
        ));
        std::fs::remove_file(&a).unwrap();
        assert!(matches!(
            m.current(&dir, "new", Some(2), None),
            Err(Stale::FileChanged(w)) if w.contains("missing")
        ));
        // Over a range, frames without a line are runs, never a list of every frame.
        let status = m.check_range(&dir, "new", (0, 1_000_000_000));
        assert!(status.current.is_empty());
        assert_eq!(status.never, [(0, 0), (3, 3), (5, 1_000_000_000)]);
        assert_eq!(status.not_done(), 1_000_000_001);
        assert_eq!(
            status.describe()[0],
            "999999998 frame(s) never finished: 0, 3, 5..1000000000"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
