//! The frame loop: for every frame, pose the scene, bring the kd-tree up to date, trace each eye
//! once, and hand the stereo frame to every output. Data flows one way:
//! scene -> accel -> render -> outputs. After each frame's files are in place, a manifest line
//! records them (see `manifest`); a farm run (`--shard`, `--resume`) leaves what needs the whole
//! sequence to `assemble`, a plain run makes it as the frames come.

use super::assemble::assemble;
use super::frame_log::{self, FRAME_LOG, FRAME_LOG_COLUMNS};
use super::interrupt::{self, output_dirs};
use super::manifest::{self, Entry, MANIFEST, Manifest};
use super::outputs::{FrameFiles, Sequence, Writer};
use super::rig_plan::DepthSummary;
use super::shard::{Shard, ShardArg};
use super::trace::FrameTracer;
use crate::error::{Error, Result};
use crate::output::CsvStream;
use crate::pipeline::LoadedPipeline;
use crate::pipeline::check_inputs_untouched;
use crate::render::{RayCounts, View, tile_count};
use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;
use std::collections::BTreeSet;
use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Clone, Debug)]
pub struct RunOptions {
    /// Inclusive frame range overriding the pipeline's.
    pub frames: Option<(u32, u32)>,
    /// Thread count overriding the pipeline's (0 = all cores).
    pub threads: Option<usize>,
    pub out_dir: PathBuf,
    /// Draw progress bars (the caller decides: not with --quiet, not when stderr is no terminal).
    pub progress: bool,
    /// Render only this block of the range (a render farm's task).
    pub shard: Option<ShardArg>,
    /// Skip the frames the manifest shows finished, by this pipeline, with unchanged files.
    pub resume: bool,
}

#[derive(Clone, Debug, Default)]
pub struct RunSummary {
    pub frames: usize,
    /// Eye images traced (a stereo frame traces two).
    pub eyes_traced: usize,
    pub rays: RayCounts,
    pub seconds: f64,
    pub trace_seconds: f64,
    /// Time spent turning traced frames into files (all outputs).
    pub output_seconds: f64,
    /// Files written (counted, not listed: a long range writes millions).
    pub files: usize,
    /// Temporary files of an earlier run that was killed, removed before this one.
    pub stale_removed: Vec<PathBuf>,
    /// What a farm run skipped and why, and what is left to do.
    pub notes: Vec<String>,
    /// The frames' parallax against the depth budget (stereo rigs).
    pub depth: DepthSummary,
    /// The GPU adapter that traced, with its driver and limits (`backend = "gpu"`).
    pub device: Option<String>,
}

impl fmt::Display for RunSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let r = &self.rays;
        for note in &self.notes {
            writeln!(f, "{note}")?;
        }
        if let Some(first) = self.stale_removed.first() {
            writeln!(
                f,
                "warning: removed {} temporary file(s) left by an interrupted run (such as {})",
                self.stale_removed.len(),
                first.display()
            )?;
        }
        if self.frames == 0 {
            return write!(f, "rendered no frames");
        }
        write!(
            f,
            "rendered {} frame(s), {} eye image(s), {} files; {:.1} M rays ({:.1} M primary, {:.1} M secondary, {:.1} M shadow) in {:.2} s: tracing {:.2} s ({:.2} M rays/s), outputs {:.2} s",
            self.frames,
            self.eyes_traced,
            self.files,
            r.total() as f64 * 1e-6,
            r.primary as f64 * 1e-6,
            r.secondary as f64 * 1e-6,
            r.shadow as f64 * 1e-6,
            self.seconds,
            self.trace_seconds,
            r.total() as f64 * 1e-6 / self.trace_seconds.max(1e-9),
            self.output_seconds,
        )?;
        if let Some(d) = &self.device {
            write!(f, "\ntraced on the GPU: {d}")?;
        }
        let depth = self.depth.to_string();
        if !depth.is_empty() {
            write!(f, "\n{depth}")?;
        }
        if let Some(w) = self.depth.warning() {
            write!(f, "\nwarning: {w}")?;
        }
        Ok(())
    }
}

fn bar(multi: &MultiProgress, len: u64, template: &str) -> ProgressBar {
    let b = multi.add(ProgressBar::new(len));
    b.set_style(
        ProgressStyle::with_template(template)
            .expect("progress templates are constant and valid")
            .progress_chars("=> "),
    );
    b
}

pub fn run(p: &LoadedPipeline, opts: &RunOptions) -> Result<RunSummary> {
    let spec = &p.spec;
    let (start, end) = opts.frames.unwrap_or((spec.frames.start, spec.frames.end));
    if end < start {
        return Err(Error::input(
            &p.file,
            format!("frame range {start}..{end} is empty"),
        ));
    }
    if end > start
        && let Some(i) = p
            .templates
            .iter()
            .zip(&p.spec.outputs)
            .position(|(t, o)| !t.has_frame() && !o.single_file())
    {
        return Err(Error::input(
            &p.file,
            format!(
                "[[output]] number {} has no {{frame}} in its path but frames {start}..{end} are requested",
                i + 1
            ),
        ));
    }
    let shard = opts
        .shard
        .map(|s| s.resolve(|name| std::env::var(name).ok()))
        .transpose()
        .map_err(|m| Error::input(Path::new("--shard"), m))?;
    let mut notes = Vec::new();
    let (first, last) = match shard.map(|s| (s, s.block(start, end))) {
        None => (start, end),
        Some((_, Some(block))) => block,
        Some((s, None)) => {
            notes.push(format!(
                "shard {s} has no frames: {start}..{end} has only {} (nothing to do)",
                end - start + 1
            ));
            return Ok(RunSummary {
                notes,
                ..RunSummary::default()
            });
        }
    };
    check_inputs_untouched(p, &opts.out_dir, first, last)?;
    interrupt::install()?;
    let writers = Writer::all(p, &opts.out_dir);
    let stale = interrupt::remove_stale_temporaries(&output_dirs(
        p,
        &writers,
        &opts.out_dir,
        (first, last),
    ));
    let fingerprint = manifest::fingerprint(p)?;
    let mut frames = FrameSet {
        first,
        last,
        skip: BTreeSet::new(),
    };
    if opts.resume {
        let found = Manifest::read(&opts.out_dir)?;
        let status = found.check_range(&opts.out_dir, &fingerprint, (first, last));
        frames.skip = status.current.keys().copied().collect();
        notes.push(format!(
            "resume: {} of {} frame(s) finished and unchanged, skipped; rendering {}",
            frames.skip.len(),
            frames.span(),
            frames.len()
        ));
        notes.extend(status.describe().into_iter().map(|l| format!("  {l}")));
        if found.torn > 0 {
            notes.push(format!(
                "  ignored {} torn manifest line(s), written by a run that was killed",
                found.torn
            ));
        }
    }
    let plan = Plan {
        frames,
        fingerprint,
        manifest: opts.out_dir.join(match shard {
            Some(s) => format!("manifest-shard-{}-of-{}.jsonl", s.index, s.count),
            None => MANIFEST.to_string(),
        }),
        streaming: !opts.resume && shard.is_none(),
    };
    let threads = opts.threads.unwrap_or(spec.render.threads);
    let pool = crate::thread_pool(threads)?;
    let mut summary = pool.install(|| run_frames(p, opts, writers, &plan))?;
    summary.stale_removed = stale;
    if !plan.streaming {
        if shard.is_none() && (first, last) == (spec.frames.start, spec.frames.end) {
            let t = Instant::now();
            let assembled = pool.install(|| assemble(p, &opts.out_dir))?;
            summary.output_seconds += t.elapsed().as_secs_f64();
            notes.push(assembled.to_string());
            summary.files += assembled.files.len();
        } else {
            notes.push(farm_hint(p, opts, shard, (first, last)));
        }
    }
    notes.append(&mut summary.notes);
    summary.notes = notes;
    Ok(summary)
}

/// What a farm run that did not cover the whole range leaves to do.
fn farm_hint(
    p: &LoadedPipeline,
    opts: &RunOptions,
    shard: Option<Shard>,
    (a, b): (u32, u32),
) -> String {
    let which = shard.map_or(String::new(), |s| format!("shard {s}: "));
    format!(
        "{which}frames {a}..{b} are done. When every frame of {}..{} is, `stereotrace assemble {} --out {}` \
         checks them, merges the frame logs and writes what needs the whole sequence",
        p.spec.frames.start,
        p.spec.frames.end,
        p.file.display(),
        opts.out_dir.display()
    )
}

/// The frames a run renders: a range less the frames `--resume` found finished. Never a list of
/// every frame: a range may span a billion frames, and only the skipped ones are stored.
struct FrameSet {
    first: u32,
    last: u32,
    skip: BTreeSet<u32>,
}

impl FrameSet {
    fn span(&self) -> u64 {
        u64::from(self.last - self.first) + 1
    }

    fn len(&self) -> u64 {
        self.span() - self.skip.len() as u64
    }

    fn iter(&self) -> impl Iterator<Item = u32> + '_ {
        (self.first..=self.last).filter(|f| !self.skip.contains(f))
    }
}

/// Which frames a run renders and how it records them.
struct Plan {
    frames: FrameSet,
    fingerprint: String,
    /// This run's manifest file.
    manifest: PathBuf,
    /// Make the sequence outputs as frames come (a plain run), rather than leave them to
    /// `assemble`.
    streaming: bool,
}

fn run_frames(
    p: &LoadedPipeline,
    opts: &RunOptions,
    writers: Vec<Writer>,
    plan: &Plan,
) -> Result<RunSummary> {
    let spec = &p.spec;
    let t0 = Instant::now();
    let rig = p.rig_views();
    let (w, h) = (spec.render.width as usize, spec.render.height as usize);

    let multi = MultiProgress::with_draw_target(if opts.progress {
        ProgressDrawTarget::stderr()
    } else {
        ProgressDrawTarget::hidden()
    });
    // Both bars take the terminal's width (a fixed width wrapped on narrow terminals). The
    // range's elapsed time and estimate sit on the frame bar; a frame's tiles finish too fast
    // and too unevenly for an estimate of their own.
    let frame_bar = bar(
        &multi,
        plan.frames.len(),
        "{elapsed_precise} frames [{wide_bar}] {pos}/{len} eta {eta_precise}",
    );
    let tile_bar = bar(
        &multi,
        tile_count(w, h) as u64,
        "         tiles  [{wide_bar}] {pos}/{len} {msg}",
    );

    let mut sequences: Vec<Sequence> = if plan.streaming {
        spec.outputs
            .iter()
            .zip(&p.templates)
            .filter_map(|(o, t)| Sequence::new(o, t, &opts.out_dir, spec.frames.fps))
            .collect()
    } else {
        Vec::new()
    };
    let mut sequence_files = Vec::new();
    let mut summary = RunSummary::default();
    // A plain run writes the frame log as frames finish (a farm's shards keep their rows in the
    // manifest for `assemble`), so a long range never holds its rows in memory.
    let log_path = opts.out_dir.join(FRAME_LOG);
    let mut log = if plan.streaming {
        Some(CsvStream::create(&log_path, &FRAME_LOG_COLUMNS)?)
    } else {
        None
    };
    let mut tracer = FrameTracer::new(p).with_stop(interrupt::flag());
    let mut finished: Option<(u32, u32)> = None;
    for frame in plan.frames.iter() {
        if interrupt::requested() {
            break;
        }
        tile_bar.reset();
        let k = frame.saturating_sub(spec.frames.start) as usize;
        let views = views_needed(p, &rig, k);
        tile_bar.set_length((tile_count(w, h) * views.len()) as u64);
        tile_bar.set_message(format!("frame {frame}"));
        let (stereo, stats) = tracer.trace(frame, &views, &|_| tile_bar.inc(1))?;
        if interrupt::requested() {
            // Tiles may have been skipped: the frame is not written.
            break;
        }
        summary.trace_seconds += stats.trace_seconds();
        summary.device = tracer.device();
        summary.rays.add(&stats.rays);
        summary.eyes_traced += stats.view_seconds.len();
        if let Some(rig) = &stats.rig {
            summary.depth.add(frame, rig, tracer.budget());
        }
        let rows = frame_log::rows(frame, &stats);
        let t = Instant::now();
        // Writers are independent (each its own files), so they encode in parallel; the files
        // are listed in output order whatever finished first.
        let made: Vec<FrameFiles> = writers
            .par_iter()
            .map(|wr| wr.frame(&stereo))
            .collect::<Result<_>>()?;
        let mut files = Vec::new();
        let mut sequence_frames = Vec::new();
        for m in made {
            files.extend(m.files);
            sequence_frames.extend(m.sequence);
        }
        // Every file of the frame is in place: now the manifest may say so.
        manifest::append(
            &plan.manifest,
            &Entry {
                frame: Some(frame),
                sequence: None,
                fingerprint: plan.fingerprint.clone(),
                files: manifest::record(&opts.out_dir, &files)?,
                log: rows.clone(),
            },
        )?;
        let pushed: Vec<Vec<PathBuf>> = sequences
            .par_iter_mut()
            .zip(sequence_frames)
            .map(|(seq, rgb)| seq.push(frame, rgb))
            .collect::<Result<_>>()?;
        sequence_files.extend(pushed.into_iter().flatten());
        summary.files += files.len();
        summary.output_seconds += t.elapsed().as_secs_f64();
        if let Some(log) = log.as_mut() {
            log.append(&rows)?;
        }
        summary.frames += 1;
        finished = Some((finished.map_or(frame, |(a, _)| a), frame));
        frame_bar.inc(1);
    }
    if interrupt::requested() {
        // Dropping the sequences stops their encoders and removes their temporary files.
        let whole_range = sequences.iter().any(Sequence::spans_range);
        drop(sequences);
        if let Some(log) = log {
            log.finish()?;
        }
        tile_bar.finish_and_clear();
        frame_bar.finish_and_clear();
        let done = match finished {
            Some((a, b)) => format!(
                "{} frame(s) from {a} to {b} are finished and kept ({} files)",
                summary.frames, summary.files
            ),
            None => "no frame was finished".to_string(),
        };
        return Err(Error::Interrupted {
            message: format!(
                "{done}; the manifest in {} lists them. The same command with --resume renders the rest{}",
                opts.out_dir.display(),
                if whole_range {
                    " (videos and whole-range GIFs need the whole range: they were not written)"
                } else {
                    ""
                }
            ),
        });
    }
    if plan.streaming {
        let t = Instant::now();
        for seq in sequences {
            sequence_files.extend(seq.finish()?);
        }
        summary.output_seconds += t.elapsed().as_secs_f64();
        if let Some((a, b)) = finished
            && !sequence_files.is_empty()
        {
            manifest::append(
                &plan.manifest,
                &Entry {
                    frame: None,
                    sequence: Some((a, b)),
                    fingerprint: plan.fingerprint.clone(),
                    files: manifest::record(&opts.out_dir, &sequence_files)?,
                    log: Vec::new(),
                },
            )?;
        }
        summary.files += sequence_files.len();
        if let Some(log) = log {
            log.finish()?;
            summary.files += 1;
        }
    }
    tile_bar.finish_and_clear();
    frame_bar.finish_and_clear();
    summary.seconds = t0.elapsed().as_secs_f64();
    Ok(summary)
}

/// The union of the views the outputs need for frame `k` of the range, each traced once, in
/// trace order (left, right, centre, then intermediate wobble views left to right).
pub(super) fn views_needed(p: &LoadedPipeline, rig: &[View], k: usize) -> Vec<View> {
    let mut views: Vec<View> = Vec::new();
    for o in &p.spec.outputs {
        for v in o.views(rig, k) {
            if !views.contains(&v) {
                views.push(v);
            }
        }
    }
    views.sort_by(View::trace_order);
    views
}
