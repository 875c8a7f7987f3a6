//! What a sweep measured: per combination, frame and eye, its times and its error against the
//! high-quality render; the table `bench sweep` prints; and its files (`results.csv`,
//! `summary.csv`, the chart).

use super::SweepOptions;
use crate::bench::chart::{self, Chart, Front, Point, Series};
use crate::compare::Comparison;
use crate::error::{Error, Result};
use crate::output::write_csv;
use std::fmt;

/// Accuracy of one eye against the high-quality render, and against its own full trace (the
/// same combination with `eye_reuse = "off"`: what reuse changed; infinite PSNR where nothing).
#[derive(Clone, Copy, Debug, Default)]
pub struct EyeError {
    pub mean_abs: f64,
    pub psnr: f64,
    pub percent_over: f64,
    pub psnr_vs_full: f64,
    pub percent_over_vs_full: f64,
}

impl EyeError {
    /// `full`: the comparison with the full trace, `None` where the eye is its own full trace.
    pub(super) fn from(reference: &Comparison, full: Option<&Comparison>) -> EyeError {
        EyeError {
            mean_abs: reference.mean_error,
            psnr: reference.psnr,
            percent_over: reference.percent_failed(),
            psnr_vs_full: full.map_or(f64::INFINITY, |f| f.psnr),
            percent_over_vs_full: full.map_or(0.0, |f| f.percent_failed()),
        }
    }
}

/// One combination at one frame; times are over the repeats.
#[derive(Clone, Debug)]
pub struct FrameRow {
    pub frame: u32,
    pub update_s: f64,
    /// Tracing of every eye.
    pub trace_s: f64,
    /// Pose, acceleration update and tracing of every eye: median, fastest and slowest repeat.
    pub frame_s: f64,
    pub frame_s_min: f64,
    pub frame_s_max: f64,
    pub rays: u64,
    /// Tracing of the left and the right eye (medians; zero for a view not traced).
    pub left_s: f64,
    pub right_s: f64,
    /// Rays traced for the right eye per pixel (camera, secondary and shadow rays).
    pub right_rays_per_pixel: f64,
    pub eyes: Vec<(String, EyeError)>,
}

#[derive(Clone, Debug)]
pub struct CombinationResult {
    /// The swept keys and the values of this combination.
    pub values: Vec<(String, String)>,
    pub frames: Vec<FrameRow>,
    /// Peak heap bytes over the combination's repeats (when the counting allocator is in use).
    pub peak_bytes: Option<usize>,
}

impl CombinationResult {
    /// `split=sah update=auto`: the last part of each key with its value.
    pub fn label(&self) -> String {
        self.values
            .iter()
            .map(|(k, v)| format!("{}={v}", k.rsplit('.').next().unwrap_or(k)))
            .collect::<Vec<_>>()
            .join(" ")
    }

    /// Time per stereo frame, the mean over frames of each frame's median: the builds of the
    /// first frame are amortized over the range as a render of the range would see them.
    pub fn frame_seconds(&self) -> f64 {
        mean(self.frames.iter().map(|f| f.frame_s))
    }

    pub fn update_seconds(&self) -> f64 {
        mean(self.frames.iter().map(|f| f.update_s))
    }

    pub fn mrays_per_second(&self) -> f64 {
        let rays: u64 = self.frames.iter().map(|f| f.rays).sum();
        let secs: f64 = self.frames.iter().map(|f| f.trace_s).sum();
        rays as f64 * 1e-6 / secs.max(1e-12)
    }

    fn eye_errors(&self) -> impl Iterator<Item = &EyeError> {
        self.frames
            .iter()
            .flat_map(|f| f.eyes.iter().map(|(_, e)| e))
    }

    pub fn mean_abs_error(&self) -> f64 {
        mean(self.eye_errors().map(|e| e.mean_abs))
    }

    pub fn psnr(&self) -> f64 {
        mean(self.eye_errors().map(|e| e.psnr))
    }

    pub fn percent_over(&self) -> f64 {
        mean(self.eye_errors().map(|e| e.percent_over))
    }

    /// Right-eye tracing time over left-eye tracing time, the mean over frames.
    pub fn right_over_left(&self) -> f64 {
        mean(
            (self.frames.iter())
                .filter(|f| f.left_s > 0.0)
                .map(|f| f.right_s / f.left_s),
        )
    }

    /// Right-eye tracing time over the left eye's of `off`, the same combination traced with
    /// `eye_reuse = "off"` (`off_sibling`), frame by frame, the mean over frames: the left eye
    /// of a reuse mode also folds its samples for the right eye, so `right_over_left` flatters.
    pub fn right_over_off_left(&self, off: &CombinationResult) -> f64 {
        mean(
            (self.frames.iter().zip(&off.frames))
                .filter(|(_, o)| o.left_s > 0.0)
                .map(|(f, o)| f.right_s / o.left_s),
        )
    }

    /// Rays traced for the right eye per pixel, the mean over frames.
    pub fn right_rays_per_pixel(&self) -> f64 {
        mean(self.frames.iter().map(|f| f.right_rays_per_pixel))
    }

    /// The right eye's PSNR against its own full trace, the mean over frames (infinite where
    /// reuse changed nothing).
    pub fn right_psnr_vs_full(&self) -> f64 {
        mean(self.frames.iter().flat_map(|f| {
            (f.eyes.iter())
                .filter(|(eye, _)| eye == "right")
                .map(|(_, e)| e.psnr_vs_full)
        }))
    }
}

/// The key of the stereo reuse mode.
const EYE_REUSE_KEY: &str = "render.eye_reuse";

/// The combination of `results` with the values of `r` but `eye_reuse = "off"`, where the sweep
/// swept `eye_reuse` and holds it.
pub fn off_sibling<'a>(
    results: &'a [CombinationResult],
    r: &CombinationResult,
) -> Option<&'a CombinationResult> {
    if !r.values.iter().any(|(k, _)| k == EYE_REUSE_KEY) {
        return None;
    }
    results.iter().find(|q| {
        q.values.len() == r.values.len()
            && (q.values.iter().zip(&r.values)).all(|((qk, qv), (k, v))| {
                qk == k
                    && if k == EYE_REUSE_KEY {
                        qv == "off"
                    } else {
                        qv == v
                    }
            })
    })
}

fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n == 0 { f64::NAN } else { sum / n as f64 }
}

/// The table `bench sweep` prints: one line per combination.
pub struct Table<'a>(pub &'a [CombinationResult]);

impl fmt::Display for Table<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{:<40} {:>10} {:>9} {:>9} {:>12} {:>8} {:>6} {:>6} {:>8} {:>11}",
            "combination",
            "s/frame",
            "Mrays/s",
            "peak MB",
            "mean |err|",
            "PSNR",
            "R/L",
            "R/offL",
            "R ray/px",
            "R vs full"
        )?;
        for r in self.0 {
            write!(
                f,
                "\n{:<40} {:>10.4} {:>9.2} {:>9} {:>12.6} {:>8.2} {:>6.3} {:>6} {:>8.2} {:>8.2} dB",
                r.label(),
                r.frame_seconds(),
                r.mrays_per_second(),
                r.peak_bytes
                    .map_or("-".into(), |b| format!("{:.1}", b as f64 / 1048576.0)),
                r.mean_abs_error(),
                r.psnr(),
                r.right_over_left(),
                off_sibling(self.0, r).map_or("-".into(), |off| format!(
                    "{:.3}",
                    r.right_over_off_left(off)
                )),
                r.right_rays_per_pixel(),
                r.right_psnr_vs_full()
            )?;
        }
        Ok(())
    }
}

/// Columns of `results.csv` after the swept keys.
pub const RESULTS_COLUMNS: [&str; 18] = [
    "frame",
    "update_s",
    "trace_s",
    "frame_s",
    "frame_s_min",
    "frame_s_max",
    "rays",
    "mrays_s",
    "peak_mb",
    "eye",
    "mean_abs_error",
    "psnr",
    "percent_over",
    "left_s",
    "right_s",
    "right_rays_per_pixel",
    "psnr_vs_full",
    "percent_over_vs_full",
];

/// Columns of `summary.csv` after the swept keys.
pub const SUMMARY_COLUMNS: [&str; 13] = [
    "label",
    "frame_s",
    "update_s",
    "mrays_s",
    "peak_mb",
    "mean_abs_error",
    "psnr",
    "percent_over",
    "pareto",
    "right_over_left",
    "right_over_off_left",
    "right_rays_per_pixel",
    "right_psnr_vs_full",
];

pub(super) fn write_files(
    opts: &SweepOptions,
    results: &[CombinationResult],
    ref_spp: u32,
    ref_depth: u32,
) -> Result<()> {
    std::fs::create_dir_all(&opts.out_dir).map_err(|e| Error::io(&opts.out_dir, e))?;
    let keys: Vec<&str> = opts.sweeps.iter().map(|(k, _)| k.as_str()).collect();
    let head = |rest: &[&'static str]| -> Vec<&str> {
        keys.iter().copied().chain(rest.iter().copied()).collect()
    };
    let row = |r: &CombinationResult, rest: Vec<String>| -> Vec<String> {
        r.values
            .iter()
            .map(|(_, v)| v.clone())
            .chain(rest)
            .collect()
    };
    let mb = |r: &CombinationResult| {
        r.peak_bytes
            .map(|b| format!("{:.1}", b as f64 / (1 << 20) as f64))
            .unwrap_or_default()
    };
    let mut rows = Vec::new();
    for r in results {
        for f in &r.frames {
            for (eye, e) in &f.eyes {
                rows.push(row(
                    r,
                    vec![
                        f.frame.to_string(),
                        format!("{:.6}", f.update_s),
                        format!("{:.6}", f.trace_s),
                        format!("{:.6}", f.frame_s),
                        format!("{:.6}", f.frame_s_min),
                        format!("{:.6}", f.frame_s_max),
                        f.rays.to_string(),
                        format!("{:.3}", f.rays as f64 * 1e-6 / f.trace_s.max(1e-12)),
                        mb(r),
                        eye.clone(),
                        format!("{:.6}", e.mean_abs),
                        format!("{:.2}", e.psnr),
                        format!("{:.4}", e.percent_over),
                        format!("{:.6}", f.left_s),
                        format!("{:.6}", f.right_s),
                        format!("{:.3}", f.right_rays_per_pixel),
                        format!("{:.2}", e.psnr_vs_full),
                        format!("{:.4}", e.percent_over_vs_full),
                    ],
                ));
            }
        }
    }
    write_csv(
        &opts.out_dir.join("results.csv"),
        &head(&RESULTS_COLUMNS),
        &rows,
    )?;

    // The front is found on the values as `summary.csv` prints them, so that the table's
    // `pareto` column agrees with its own numbers when two times differ past the sixth decimal.
    let printed = |v: f64| format!("{v:.6}").parse::<f64>().unwrap_or(v);
    let points: Vec<Point> = results
        .iter()
        .map(|r| Point {
            label: r.label(),
            x: printed(r.frame_seconds()),
            y: printed(r.mean_abs_error()),
        })
        .collect();
    let front = chart::pareto_front(&points);
    let rows: Vec<Vec<String>> = results
        .iter()
        .enumerate()
        .map(|(i, r)| {
            row(
                r,
                vec![
                    r.label(),
                    format!("{:.6}", r.frame_seconds()),
                    format!("{:.6}", r.update_seconds()),
                    format!("{:.3}", r.mrays_per_second()),
                    mb(r),
                    format!("{:.6}", r.mean_abs_error()),
                    format!("{:.2}", r.psnr()),
                    format!("{:.4}", r.percent_over()),
                    front.contains(&i).to_string(),
                    format!("{:.4}", r.right_over_left()),
                    off_sibling(results, r)
                        .map(|off| format!("{:.4}", r.right_over_off_left(off)))
                        .unwrap_or_default(),
                    format!("{:.3}", r.right_rays_per_pixel()),
                    format!("{:.2}", r.right_psnr_vs_full()),
                ],
            )
        })
        .collect();
    write_csv(
        &opts.out_dir.join("summary.csv"),
        &head(&SUMMARY_COLUMNS),
        &rows,
    )?;

    // One colour per value of the first swept key; the front runs over all combinations.
    let series = Series::group(results.iter().zip(points).map(|(r, p)| {
        let name = r
            .values
            .first()
            .map_or_else(|| "pipeline".to_string(), |(k, v)| format!("{k}={v}"));
        (name, p)
    }));
    let name = opts
        .pipeline
        .file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    chart::write(
        &Chart {
            title: format!(
                "{name}: time per stereo frame against error ({ref_spp} spp, depth {ref_depth} reference)"
            ),
            x_label: "time per stereo frame (s)".into(),
            y_label: "mean absolute error vs reference".into(),
            series,
            front: Front::Global,
        },
        &opts.out_dir.join("chart"),
    )
}
