//! Image comparison with OpenImageIO `idiff`'s meaning of every flag and of the exit status, so a
//! verdict here is the verdict `idiff` gives on the same pair (CI checks that on a set of pairs).
//!
//! What idiff (OpenImageIO 3.x, `ImageBufAlgo::compare`) does, and this module mirrors:
//! - images are compared over the union of their sizes and channel counts; a pixel or channel
//!   one image lacks reads as 0;
//! - per value `f = |a - b|` (in double precision); a pixel *fails* once if any channel has
//!   `f > fail` and `f > failrelative * (|a| + |b|) / 2`, and *warns* likewise;
//! - a NaN or infinite value facing a different value makes the max error infinite but is not
//!   counted as a failure, nor in the mean; NaN facing NaN (or equal infinities) is no error;
//! - mean and RMS are over all values, PSNR = 20 log10(1 / RMS);
//! - verdict: pass if failures <= `allowfailures`; else fail if failures exceed `failpercent`
//!   of the pixels or the max error exceeds `hardfail`; else warn if warnings exceed
//!   `warnpercent` or the max error exceeds `hardwarn`; else pass. (The first rule means a
//!   comparison with no failures passes whatever its warnings, as idiff does.)
//!
//! Exit statuses are idiff's: 0 pass, 1 warning, 2 failure, 4 an input could not be read.
//! Multi-view EXR files are compared view by view (idiff compares channels of the first part);
//! a view present on one side only is a failure. Two files of one view each are compared
//! directly, whatever their view names.

use crate::error::{Error, Result};
pub use crate::output::Planes;
use crate::output::exr;
use crate::output::read_planes;
use serde::Serialize;
use std::fmt;
use std::path::{Path, PathBuf};

/// idiff's flags, with idiff's names and defaults.
#[derive(Clone, Copy, Debug, Serialize, clap::Args)]
pub struct Thresholds {
    /// Failure threshold on the absolute difference of a value.
    #[arg(long, default_value_t = 1e-6)]
    pub fail: f32,
    /// Warning threshold on the absolute difference of a value.
    #[arg(long, default_value_t = 1e-6)]
    pub warn: f32,
    /// Relative failure threshold (difference over the mean magnitude of the two values).
    #[arg(
        long = "failrelative",
        value_name = "FAILRELATIVE",
        default_value_t = 0.0
    )]
    pub fail_relative: f32,
    /// Relative warning threshold.
    #[arg(
        long = "warnrelative",
        value_name = "WARNRELATIVE",
        default_value_t = 0.0
    )]
    pub warn_relative: f32,
    /// Percentage of pixels allowed to fail.
    #[arg(
        long = "failpercent",
        value_name = "FAILPERCENT",
        default_value_t = 0.0
    )]
    pub fail_percent: f32,
    /// Percentage of pixels allowed to warn.
    #[arg(
        long = "warnpercent",
        value_name = "WARNPERCENT",
        default_value_t = 0.0
    )]
    pub warn_percent: f32,
    /// Fail if any value differs by more than this.
    #[arg(long = "hardfail", value_name = "HARDFAIL", default_value_t = f32::INFINITY)]
    pub hard_fail: f32,
    /// Warn if any value differs by more than this.
    #[arg(long = "hardwarn", value_name = "HARDWARN", default_value_t = f32::INFINITY)]
    pub hard_warn: f32,
    /// Number of failing pixels that still pass.
    #[arg(
        long = "allowfailures",
        value_name = "ALLOWFAILURES",
        default_value_t = 0
    )]
    pub allow_failures: u64,
}

impl Default for Thresholds {
    fn default() -> Self {
        Thresholds {
            fail: 1e-6,
            warn: 1e-6,
            fail_relative: 0.0,
            warn_relative: 0.0,
            fail_percent: 0.0,
            warn_percent: 0.0,
            hard_fail: f32::INFINITY,
            hard_warn: f32::INFINITY,
            allow_failures: 0,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Verdict {
    Pass = 0,
    Warn = 1,
    Fail = 2,
}

/// Metrics of one comparison.
#[derive(Clone, Debug, Serialize)]
pub struct Comparison {
    pub width: usize,
    pub height: usize,
    pub channels: Vec<String>,
    /// Pixels of the first image (idiff's denominator for the percentages).
    pub pixels: usize,
    pub mean_error: f64,
    pub rms_error: f64,
    pub psnr: f64,
    pub max_error: f64,
    /// (x, y, channel) of the first largest error.
    pub max_at: (usize, usize, usize),
    pub per_channel_mean: Vec<f64>,
    pub per_channel_rms: Vec<f64>,
    pub per_channel_max: Vec<f64>,
    pub failures: u64,
    pub warnings: u64,
    pub verdict: Verdict,
}

impl Comparison {
    pub fn percent_failed(&self) -> f64 {
        100.0 * self.failures as f64 / self.pixels.max(1) as f64
    }
}

/// Compares two images with idiff's rules.
pub fn compare(a: &Planes, b: &Planes, t: &Thresholds) -> Comparison {
    let (w, h) = (a.width.max(b.width), a.height.max(b.height));
    let nc = a.data.len().max(b.data.len());
    let mut sum = vec![0f64; nc];
    let mut sq = vec![0f64; nc];
    let mut cmax = vec![0f64; nc];
    let (mut max_error, mut max_at) = (0f64, (0, 0, 0));
    let (mut failures, mut warnings) = (0u64, 0u64);
    for y in 0..h {
        for x in 0..w {
            let (mut failed, mut warned) = (false, false);
            for c in 0..nc {
                let (av, bv) = (a.value(c, x, y) as f64, b.value(c, x, y) as f64);
                if !av.is_finite() || !bv.is_finite() {
                    let same = (av.is_nan() && bv.is_nan()) || av == bv;
                    if !same && max_error != f64::INFINITY {
                        max_error = f64::INFINITY;
                        max_at = (x, y, c);
                        cmax[c] = f64::INFINITY;
                    }
                    continue;
                }
                let f = (av - bv).abs();
                sum[c] += f;
                sq[c] += f * f;
                cmax[c] = cmax[c].max(f);
                if f > max_error {
                    max_error = f;
                    max_at = (x, y, c);
                }
                let mean_mag = (av.abs() + bv.abs()) * 0.5;
                if !warned && f > t.warn as f64 && f > t.warn_relative as f64 * mean_mag {
                    warned = true;
                    warnings += 1;
                }
                if !failed && f > t.fail as f64 && f > t.fail_relative as f64 * mean_mag {
                    failed = true;
                    failures += 1;
                }
            }
        }
    }
    let per_pixel = (w * h).max(1) as f64;
    let values = per_pixel * nc.max(1) as f64;
    let rms = (sq.iter().sum::<f64>() / values).sqrt();
    let pixels = (a.width * a.height).max(1);
    let mut c = Comparison {
        width: w,
        height: h,
        channels: if a.names.len() >= b.names.len() {
            a.names.clone()
        } else {
            b.names.clone()
        },
        pixels,
        mean_error: sum.iter().sum::<f64>() / values,
        rms_error: rms,
        psnr: 20.0 * (1.0 / rms).log10(),
        max_error,
        max_at,
        per_channel_mean: sum.iter().map(|s| s / per_pixel).collect(),
        per_channel_rms: sq.iter().map(|s| (s / per_pixel).sqrt()).collect(),
        per_channel_max: cmax,
        failures,
        warnings,
        verdict: Verdict::Pass,
    };
    c.verdict = verdict(&c, t);
    c
}

/// idiff's decision, in idiff's order.
pub fn verdict(c: &Comparison, t: &Thresholds) -> Verdict {
    let n = c.pixels as f64;
    if c.failures <= t.allow_failures {
        Verdict::Pass
    } else if c.failures as f64 > t.fail_percent as f64 / 100.0 * n
        || c.max_error > t.hard_fail as f64
    {
        Verdict::Fail
    } else if c.warnings as f64 > t.warn_percent as f64 / 100.0 * n
        || c.max_error > t.hard_warn as f64
    {
        Verdict::Warn
    } else {
        Verdict::Pass
    }
}

/// Result of comparing two files view by view.
#[derive(Clone, Debug, Serialize)]
pub struct FileComparison {
    pub views: Vec<(String, Comparison)>,
    /// Views present in only one file.
    pub missing_views: Vec<String>,
    pub verdict: Verdict,
}

pub fn compare_files(a: &Path, b: &Path, t: &Thresholds) -> Result<FileComparison> {
    compare_views(&read_planes(a)?, &read_planes(b)?, t)
}

/// `compare_files`, and with `diff = Some((out, scale))` the difference images too, reading
/// each file once.
/// The input a difference image at `path` would be written over, if any.
fn overwritten_input<'a>(path: &Path, inputs: [&'a Path; 2]) -> Option<&'a Path> {
    let target = std::fs::canonicalize(path).ok()?;
    inputs
        .into_iter()
        .find(|i| std::fs::canonicalize(i).is_ok_and(|i| i == target))
}

fn refuse_overwrite(diff: &Path, input: &Path) -> Error {
    Error::input(
        diff,
        format!(
            "--diff would overwrite {}, an image being compared: choose another path",
            input.display()
        ),
    )
}

/// Refuses a difference image that would be written over one of the images compared
/// (`compare a.exr b.exr --diff a.exr`), before anything is read: bad usage, status 2. (The
/// per-view names of a multi-view difference are checked again before each is written.)
pub fn check_diff_target(a: &Path, b: &Path, diff: &Path) -> Result<()> {
    match overwritten_input(diff, [a, b]) {
        Some(input) => Err(refuse_overwrite(diff, input)),
        None => Ok(()),
    }
}

pub fn compare_files_with_diff(
    a: &Path,
    b: &Path,
    t: &Thresholds,
    diff: Option<(&Path, f32)>,
) -> Result<FileComparison> {
    let (va, vb) = (read_planes(a)?, read_planes(b)?);
    let result = compare_views(&va, &vb, t)?;
    if let Some((out, scale)) = diff {
        write_differences(&va, &vb, out, scale, [a, b])?;
    }
    Ok(result)
}

/// Compares the views of two files, read already.
fn compare_views(
    va: &[(String, Planes)],
    vb: &[(String, Planes)],
    t: &Thresholds,
) -> Result<FileComparison> {
    if let ([(name, pa)], [(_, pb)]) = (va, vb) {
        // One view each: compare them whatever they are called (a plain RGB file against one
        // eye of a stereo pair), as idiff would.
        let c = compare(pa, pb, t);
        let verdict = c.verdict;
        return Ok(FileComparison {
            views: vec![(name.clone(), c)],
            missing_views: Vec::new(),
            verdict,
        });
    }
    let mut views = Vec::new();
    let mut missing = Vec::new();
    for (name, pa) in va {
        match vb.iter().find(|(n, _)| n == name) {
            Some((_, pb)) => views.push((name.clone(), compare(pa, pb, t))),
            None => missing.push(name.clone()),
        }
    }
    missing.extend(
        vb.iter()
            .filter(|(n, _)| !va.iter().any(|(m, _)| m == n))
            .map(|(n, _)| n.clone()),
    );
    let worst = views
        .iter()
        .map(|(_, c)| c.verdict)
        .max()
        .unwrap_or(Verdict::Pass);
    let verdict = if missing.is_empty() {
        worst
    } else {
        Verdict::Fail
    };
    Ok(FileComparison {
        views,
        missing_views: missing,
        verdict,
    })
}

/// `|a - b| * scale` per channel over the union size, for `--diff`.
pub fn difference_planes(a: &Planes, b: &Planes, scale: f32) -> Planes {
    let (w, h) = (a.width.max(b.width), a.height.max(b.height));
    let nc = a.data.len().max(b.data.len());
    let data = (0..nc)
        .map(|c| {
            (0..w * h)
                .map(|i| ((a.value(c, i % w, i / w) - b.value(c, i % w, i / w)).abs()) * scale)
                .collect()
        })
        .collect();
    let names = if a.names.len() >= b.names.len() {
        a.names.clone()
    } else {
        b.names.clone()
    };
    Planes {
        width: w,
        height: h,
        names,
        data,
    }
}

/// `--diff OUT`: the absolute difference (times `scale`) of every view both files hold, as a
/// float EXR, or for an OUT ending in `.png` as an 8-bit grey image of each pixel's largest
/// channel difference (times `scale`, clipped to 1: a picture of where two renders differ);
/// with several views, one file per view, the view name added before the extension. Returns
/// the files written.
fn write_differences(
    va: &[(String, Planes)],
    vb: &[(String, Planes)],
    out: &Path,
    scale: f32,
    inputs: [&Path; 2],
) -> Result<Vec<PathBuf>> {
    let several = va.len() > 1;
    let png = out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    let mut written = Vec::new();
    for (name, pa) in va {
        // One view each is compared whatever the views are called (`compare_views`), and so
        // is its difference written.
        let pb = match vb {
            [(_, only)] if va.len() == 1 => only,
            _ => match vb.iter().find(|(n, _)| n == name) {
                Some((_, pb)) => pb,
                None => continue,
            },
        };
        let path = if several {
            let stem = out
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            let ext = if png { "png" } else { "exr" };
            out.with_file_name(format!("{stem}_{name}.{ext}"))
        } else {
            out.to_path_buf()
        };
        if let Some(input) = overwritten_input(&path, inputs) {
            return Err(refuse_overwrite(&path, input));
        }
        let d = difference_planes(pa, pb, scale);
        if png {
            let grey: Vec<u8> = (0..d.width * d.height)
                .flat_map(|i| {
                    let m = d.data.iter().map(|c| c[i]).fold(0.0f32, f32::max);
                    [(m.clamp(0.0, 1.0) * 255.0).round() as u8; 3]
                })
                .collect();
            crate::output::write_rgb8(&path, d.width, d.height, &grey)?;
        } else {
            exr::write_planes(&path, &d)?;
        }
        written.push(path);
    }
    Ok(written)
}

/// The text report of a comparison, laid out as idiff prints its own.
pub struct Report<'a> {
    pub a: &'a Path,
    pub b: &'a Path,
    pub thresholds: &'a Thresholds,
    pub result: &'a FileComparison,
}

impl fmt::Display for Report<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (r, t) = (self.result, self.thresholds);
        writeln!(
            f,
            "Comparing \"{}\" and \"{}\"",
            self.a.display(),
            self.b.display()
        )?;
        for (view, c) in &r.views {
            if !view.is_empty() {
                writeln!(f, "view {view}:")?;
            }
            writeln!(
                f,
                "  Mean error = {:.6}  RMS error = {:.6}  Peak SNR = {:.3} dB",
                c.mean_error, c.rms_error, c.psnr
            )?;
            writeln!(
                f,
                "  Max error  = {} @ ({}, {}, {})",
                c.max_error,
                c.max_at.0,
                c.max_at.1,
                c.channels.get(c.max_at.2).map_or("?", String::as_str)
            )?;
            for (i, name) in c.channels.iter().enumerate() {
                writeln!(
                    f,
                    "  {name:>6}: mean {:.6}  rms {:.6}  max {:.6}",
                    c.per_channel_mean[i], c.per_channel_rms[i], c.per_channel_max[i]
                )?;
            }
            writeln!(
                f,
                "  {} pixels ({:.3}%) over {}",
                c.warnings,
                100.0 * c.warnings as f64 / c.pixels as f64,
                t.warn
            )?;
            writeln!(
                f,
                "  {} pixels ({:.3}%) over {}",
                c.failures,
                c.percent_failed(),
                t.fail
            )?;
        }
        for m in &r.missing_views {
            writeln!(f, "view '{m}' is in only one of the files")?;
        }
        write!(
            f,
            "{}",
            match r.verdict {
                Verdict::Pass => "PASS",
                Verdict::Warn => "WARNING",
                Verdict::Fail => "FAILURE",
            }
        )
    }
}

#[cfg(test)]
mod tests;
