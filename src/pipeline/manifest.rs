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

use super::LoadedPipeline;
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

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

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn sha256(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

/// The running executable's hash: a rebuilt tool may trace differently, so its frames are not
/// taken for this one's.
fn tool_hash() -> &'static str {
    static HASH: OnceLock<String> = OnceLock::new();
    HASH.get_or_init(|| {
        std::env::current_exe()
            .and_then(std::fs::read)
            .map(|b| sha256(&b))
            .unwrap_or_else(|_| "unknown".into())
    })
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
        tool_hash()
    ));
    h.update(format!("{spec:?}\n"));
    for file in &p.scene.files {
        // A file the scene names but never reads (an unused image) may be missing.
        let content = std::fs::read(file).map(|b| sha256(&b));
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

/// Frame numbers as ranges: `3..5, 9, 12..20` (the first 12 ranges, then how many more).
fn ranges(frames: &[u32]) -> String {
    const SHOWN: usize = 12;
    let mut runs: Vec<(u32, u32)> = Vec::new();
    for &f in frames {
        match runs.last_mut() {
            Some((_, b)) if *b + 1 == f => *b = f,
            _ => runs.push((f, f)),
        }
    }
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
pub fn describe_stale(stale: &[(Stale, u32)]) -> Vec<String> {
    let mut lines = Vec::new();
    for kind in [
        Stale::NeverFinished.kind(),
        Stale::MadeDifferently.kind(),
        Stale::FileChanged(String::new()).kind(),
    ] {
        let mine: Vec<&(Stale, u32)> = stale.iter().filter(|(s, _)| s.kind() == kind).collect();
        let Some((first, _)) = mine.first() else {
            continue;
        };
        let mut frames: Vec<u32> = mine.iter().map(|(_, f)| *f).collect();
        frames.sort_unstable();
        let example = match first {
            Stale::FileChanged(why) => format!(" (first: {why})"),
            _ => String::new(),
        };
        lines.push(format!(
            "{} frame(s) {kind}: {}{example}",
            frames.len(),
            ranges(&frames)
        ));
    }
    lines
}

/// Every line of every manifest in a folder.
#[derive(Debug, Default)]
pub struct Manifest {
    entries: Vec<Entry>,
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
                    Ok(e) => m.entries.push(e),
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
        let lines = self
            .entries
            .iter()
            .rev()
            .filter(|e| e.frame == frame && e.sequence == sequence);
        for e in lines {
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
            describe_stale(&stale),
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
        let _ = std::fs::remove_dir_all(&dir);
    }
}
