//! The frame loop: for every frame, pose the scene, bring the kd-tree up to date, trace each eye
//! once, and hand the stereo frame to every output. Data flows one way:
//! scene -> accel -> render -> outputs.

use super::LoadedPipeline;
use super::collisions::{FRAME_LOG, check_inputs_untouched, written};
use super::interrupt;
use super::outputs::Writer;
use super::trace::FrameTracer;
use crate::error::{Error, Result};
use crate::output::write_csv;
use crate::render::{RayCounts, View, tile_count};
use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;
use std::fmt;
use std::path::PathBuf;
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
    pub files: Vec<PathBuf>,
    /// Temporary files of an earlier run that was killed, removed before this one.
    pub stale_removed: Vec<PathBuf>,
}

impl fmt::Display for RunSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let r = &self.rays;
        if let Some(first) = self.stale_removed.first() {
            writeln!(
                f,
                "warning: removed {} temporary file(s) left by an interrupted run (such as {})",
                self.stale_removed.len(),
                first.display()
            )?;
        }
        write!(
            f,
            "rendered {} frame(s), {} eye image(s), {} files; {:.1} M rays ({:.1} M primary, {:.1} M secondary, {:.1} M shadow) in {:.2} s: tracing {:.2} s ({:.2} M rays/s), outputs {:.2} s",
            self.frames,
            self.eyes_traced,
            self.files.len(),
            r.total() as f64 * 1e-6,
            r.primary as f64 * 1e-6,
            r.secondary as f64 * 1e-6,
            r.shadow as f64 * 1e-6,
            self.seconds,
            self.trace_seconds,
            r.total() as f64 * 1e-6 / self.trace_seconds.max(1e-9),
            self.output_seconds,
        )
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
    check_inputs_untouched(p, &opts.out_dir, start, end)?;
    interrupt::install()?;
    let stale = interrupt::remove_stale_temporaries(&output_dirs(p, opts, start));
    let threads = opts.threads.unwrap_or(spec.render.threads);
    let mut summary = crate::thread_pool(threads)?.install(|| run_frames(p, opts, start, end))?;
    summary.stale_removed = stale;
    Ok(summary)
}

/// The folders this run writes into: `--out`, and those of the outputs' first files and videos.
fn output_dirs(p: &LoadedPipeline, opts: &RunOptions, start: u32) -> Vec<PathBuf> {
    let mut dirs = vec![opts.out_dir.clone()];
    for w in written(&p.spec, &p.templates, start, start) {
        dirs.extend(opts.out_dir.join(&w.path).parent().map(Into::into));
    }
    dirs.sort();
    dirs.dedup();
    dirs
}

fn run_frames(p: &LoadedPipeline, opts: &RunOptions, start: u32, end: u32) -> Result<RunSummary> {
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
        (end - start + 1) as u64,
        "{elapsed_precise} frames [{wide_bar}] {pos}/{len} eta {eta_precise}",
    );
    let tile_bar = bar(
        &multi,
        tile_count(w, h) as u64,
        "         tiles  [{wide_bar}] {pos}/{len} {msg}",
    );

    let mut writers: Vec<Writer> = p
        .spec
        .outputs
        .iter()
        .zip(&p.templates)
        .map(|(o, t)| Writer::new(o, t, &rig, &opts.out_dir, spec.frames.fps))
        .collect();
    let mut summary = RunSummary::default();
    let mut log: Vec<Vec<String>> = Vec::new();
    let mut tracer = FrameTracer::new(p).with_stop(interrupt::flag());
    let mut finished = None;
    for (k, frame) in (start..=end).enumerate() {
        if interrupt::requested() {
            break;
        }
        tile_bar.reset();
        let views = views_needed(p, &rig, k);
        tile_bar.set_length((tile_count(w, h) * views.len()) as u64);
        tile_bar.set_message(format!("frame {frame}"));
        let (stereo, stats) = tracer.trace(frame, &views, &|_| tile_bar.inc(1));
        if interrupt::requested() {
            // Tiles may have been skipped: the frame is not written.
            break;
        }
        let mut view_seconds = [0f64; 3];
        for (view, secs) in &stats.view_seconds {
            view_seconds[match *view {
                View::LEFT => 0,
                View::RIGHT => 1,
                _ => 2,
            }] += secs;
        }
        summary.trace_seconds += stats.trace_seconds();
        summary.rays.add(&stats.rays);
        summary.eyes_traced += stats.view_seconds.len();
        for row in &stats.update {
            log.push(vec![
                frame.to_string(),
                row.object.clone(),
                row.action.to_string(),
                row.reason.to_string(),
                format!("{:.6}", stats.pose_seconds),
                format!("{:.6}", row.seconds),
                format!("{:.6}", view_seconds[0]),
                format!("{:.6}", view_seconds[1]),
                format!("{:.6}", view_seconds[2]),
                row.sah_cost.map(|c| format!("{c:.3}")).unwrap_or_default(),
                stats.rays.reused_primary.to_string(),
                stats.rays.primary.to_string(),
                stats.rays.reused_shadow.to_string(),
                stats.rays.reused_radiance.to_string(),
            ]);
        }
        let t = Instant::now();
        // Writers are independent (each its own files and state), so they encode in parallel;
        // the files are listed in output order whatever finished first.
        let written: Vec<Result<Vec<PathBuf>>> =
            writers.par_iter_mut().map(|wr| wr.frame(&stereo)).collect();
        for files in written {
            summary.files.extend(files?);
        }
        summary.output_seconds += t.elapsed().as_secs_f64();
        summary.frames += 1;
        finished = Some(frame);
        frame_bar.inc(1);
    }
    let log_path = opts.out_dir.join(FRAME_LOG);
    if interrupt::requested() {
        // Dropping the writers stops their encoders and removes their temporary files.
        let whole_range = writers.iter().any(Writer::spans_range);
        drop(writers);
        write_csv(&log_path, &FRAME_LOG_COLUMNS, &log)?;
        tile_bar.finish_and_clear();
        frame_bar.finish_and_clear();
        let done = match finished {
            Some(last) => format!(
                "frames {start}..{last} are finished and kept ({} files)",
                summary.files.len()
            ),
            None => "no frame was finished".to_string(),
        };
        let next = finished.map_or(start, |f| f + 1);
        return Err(Error::Interrupted {
            message: format!(
                "{done}, and {} lists them. Continue with --frames {next}..{end}{}",
                log_path.display(),
                if whole_range {
                    " (videos and whole-range GIFs need the whole range: they were not written)"
                } else {
                    ""
                }
            ),
        });
    }
    let t = Instant::now();
    for wr in writers {
        summary.files.extend(wr.finish()?);
    }
    summary.output_seconds += t.elapsed().as_secs_f64();
    write_csv(&log_path, &FRAME_LOG_COLUMNS, &log)?;

    summary.files.push(log_path);
    tile_bar.finish_and_clear();
    frame_bar.finish_and_clear();
    summary.seconds = t0.elapsed().as_secs_f64();
    Ok(summary)
}

/// Columns of `frame-log.csv`: one row per frame and object, what the acceleration update did
/// and why, and where the time went (`update_s` per object; `left_s`, `right_s`, `other_s`: the
/// frame's tracing per view, repeated on each of its rows; `sah_cost` when a tree was built;
/// `reused_samples`: camera samples that took another view's hit under `eye_reuse =
/// "reproject"`, `traced_samples`: those that traced their camera ray, `reused_shadow_rays`:
/// shadow answers taken with the reused hits, `reused_radiance_samples`: reused samples that
/// took the radiance too under `"reproject-radiance"`; all per frame).
pub const FRAME_LOG_COLUMNS: [&str; 14] = [
    "frame",
    "object",
    "action",
    "reason",
    "pose_s",
    "update_s",
    "left_s",
    "right_s",
    "other_s",
    "sah_cost",
    "reused_samples",
    "traced_samples",
    "reused_shadow_rays",
    "reused_radiance_samples",
];

/// The union of the views the outputs need for frame `k` of the range, each traced once, in
/// trace order (left, right, centre, then intermediate wobble views left to right).
fn views_needed(p: &LoadedPipeline, rig: &[View], k: usize) -> Vec<View> {
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
