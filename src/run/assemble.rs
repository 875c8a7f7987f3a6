//! `stereotrace assemble`: the last step of a render farm. It checks that every frame of the
//! pipeline's range is finished, by this pipeline, with its files unchanged (the manifest),
//! merges the shards' frame logs into `frame-log.csv`, and makes what needs the whole sequence
//! (videos, pseudo-stereo frames, wobble GIFs over the range) from the 8-bit frames the shards
//! wrote. The files come out byte-identical to a single run over the range.

use super::frame_log::{FRAME_LOG, FRAME_LOG_COLUMNS};
use super::interrupt::{output_dirs, remove_stale_temporaries};
use super::manifest::{self, Entry, MANIFEST, Manifest};
use super::outputs::{Sequence, Writer};
use crate::error::{Error, Result};
use crate::output::{read_rgb8, write_csv};
use crate::pipeline::LoadedPipeline;
use crate::pipeline::check_inputs_untouched;
use rayon::prelude::*;
use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Debug, Default)]
pub struct Assembled {
    pub frames: (u32, u32),
    /// The sequence outputs written, then the frame log.
    pub files: Vec<PathBuf>,
    /// The sequence outputs were already made from these frames and unchanged: not remade.
    pub already_current: bool,
    pub seconds: f64,
}

impl fmt::Display for Assembled {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (a, b) = self.frames;
        let made = if self.already_current {
            "the sequence outputs were current".to_string()
        } else {
            format!("wrote {} file(s)", self.files.len())
        };
        write!(
            f,
            "assembled frames {a}..{b}: every frame finished and current; {made} in {:.2} s",
            self.seconds
        )
    }
}

pub fn assemble(p: &LoadedPipeline, out_dir: &Path) -> Result<Assembled> {
    let t0 = Instant::now();
    let (start, end) = (p.spec.frames.start, p.spec.frames.end);
    check_inputs_untouched(p, out_dir, start, end)?;
    let writers = Writer::all(p, out_dir);
    remove_stale_temporaries(&output_dirs(p, &writers, out_dir, (start, end)));
    let fingerprint = manifest::fingerprint(p)?;
    let found = Manifest::read(out_dir)?;
    let status = found.check_range(out_dir, &fingerprint, (start, end));
    if status.not_done() > 0 {
        return Err(Error::Incomplete {
            message: format!(
                "{}: {} of the {} frames of {start}..{end} are missing or stale, so nothing was assembled:\n  {}",
                out_dir.display(),
                status.not_done(),
                u64::from(end - start) + 1,
                status.describe().join("\n  ")
            ),
        });
    }
    let entries: Vec<&Entry> = status.current.values().copied().collect();
    let mut files = Vec::new();
    let already_current = found
        .current(out_dir, &fingerprint, None, Some((start, end)))
        .is_ok();
    if !already_current {
        let fps = p.spec.frames.fps;
        let sequences: Vec<_> = writers
            .iter()
            .zip(p.spec.outputs.iter().zip(&p.templates))
            .filter_map(|(w, (o, t))| Sequence::new(o, t, out_dir, fps).map(|s| (w, s)))
            .collect();
        let made: Vec<Vec<PathBuf>> = sequences
            .into_par_iter()
            .map(|(w, mut seq)| {
                let mut files = Vec::new();
                for frame in start..=end {
                    let source = w.sequence_source(frame).ok_or_else(|| {
                        Error::Internal("a sequence output has no frame source".into())
                    })?;
                    files.extend(seq.push(frame, read_rgb8(&source)?)?);
                }
                files.extend(seq.finish()?);
                Ok(files)
            })
            .collect::<Result<_>>()?;
        files = made.into_iter().flatten().collect();
        if !files.is_empty() {
            manifest::append(
                &out_dir.join(MANIFEST),
                &Entry {
                    frame: None,
                    sequence: Some((start, end)),
                    fingerprint: fingerprint.clone(),
                    files: manifest::record(out_dir, &files)?,
                    log: Vec::new(),
                },
            )?;
        }
    }
    let rows: Vec<&Vec<String>> = entries.iter().flat_map(|e| &e.log).collect();
    let log = out_dir.join(FRAME_LOG);
    write_csv(&log, &FRAME_LOG_COLUMNS, &rows)?;
    files.push(log);
    Ok(Assembled {
        frames: (start, end),
        files,
        already_current,
        seconds: t0.elapsed().as_secs_f64(),
    })
}
