//! `bench sweep`: renders a pipeline's frames for every combination of swept keys, times each
//! combination and measures its error against a high-quality render of the same frames.
//!
//! Keys are pipeline keys by path (`accel.split`, `render.spp`), set through
//! `LoadedPipeline::with_overrides`, so any method switch the pipeline has can be swept and every
//! value is validated as in a file. The high-quality render of a combination is the same pipeline
//! with a fresh SAH build every frame, `reference_spp` samples and `reference_depth` bounces; the
//! combinations that differ only in those keys share it (one per shading model, say).
//!
//! Outputs: `results.csv` (one row per combination and frame), `summary.csv` (one row per
//! combination: the chart's table) and `chart.svg` / `chart.png`.

mod results;

pub use results::{CombinationResult, EyeError, FrameRow, RESULTS_COLUMNS, SUMMARY_COLUMNS, Table};

use super::{median, memory};
use crate::compare::{Planes, Thresholds, compare};
use crate::error::{Error, Result};
use crate::output::Image;
use crate::pipeline::{LoadedPipeline, parse_frame_range};
use crate::render::{EyeReuse, View};
use crate::run::{FrameStats, FrameTracer};
use results::write_files;
use std::path::PathBuf;

/// Keys set by path, with their values.
type Overrides = Vec<(String, String)>;
/// The views of one frame.
type FrameViews = Vec<(View, Planes)>;

/// Keys the high-quality render sets itself; every other swept key is part of what it renders.
const SPP: &str = "render.spp";
const DEPTH: &str = "render.max_depth";
const SPLIT: &str = "accel.split";
const UPDATE: &str = "accel.update";
const EYE_REUSE: &str = "render.eye_reuse";

/// `--threshold`: a finite, non-negative per-channel error.
fn parse_threshold(s: &str) -> std::result::Result<f32, String> {
    match s.parse::<f32>() {
        Ok(t) if t.is_finite() && t >= 0.0 => Ok(t),
        _ => Err(format!("'{s}' is not a finite number >= 0")),
    }
}

#[derive(Clone, Debug, clap::Args)]
pub struct SweepOptions {
    /// Pipeline file (TOML).
    pub pipeline: PathBuf,
    /// KEY=V1,V2,...: a pipeline key by path and the values to try (repeatable), e.g.
    /// accel.split=center,sah  render.spp=1,4,16  render.shading=phong,cook-torrance. The
    /// first varies slowest.
    #[arg(long = "sweep", value_parser = parse_sweep)]
    pub sweeps: Vec<(String, Vec<String>)>,
    /// Runs per combination; times are medians with the fastest and slowest run.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub repeat: u32,
    /// Folder for the results.
    #[arg(long = "out", value_name = "OUT", default_value = "out/sweep")]
    pub out_dir: PathBuf,
    /// Frame range A..B (inclusive), overriding the pipeline's [frames].
    #[arg(long, value_parser = parse_frame_range)]
    pub frames: Option<(u32, u32)>,
    /// Samples per pixel of the high-quality render [default: 4x the most swept, at least 64].
    #[arg(long)]
    pub reference_spp: Option<u32>,
    /// Recursion depth of the high-quality render [default: the deepest swept].
    #[arg(long)]
    pub reference_depth: Option<u32>,
    /// Per-channel error above which a pixel counts as wrong (`compare --fail`).
    #[arg(long, default_value_t = 0.02, value_parser = parse_threshold)]
    pub threshold: f32,
}

/// Every combination of the swept values, the first key varying slowest.
pub fn combinations(sweeps: &[(String, Vec<String>)]) -> Vec<Vec<(String, String)>> {
    let mut out = vec![Vec::new()];
    for (key, values) in sweeps {
        out = out
            .into_iter()
            .flat_map(|prefix: Vec<(String, String)>| {
                values.iter().map(move |v| {
                    let mut c = prefix.clone();
                    c.push((key.clone(), v.clone()));
                    c
                })
            })
            .collect();
    }
    out
}

/// Parses `KEY=V1,V2,...`.
pub fn parse_sweep(arg: &str) -> Result<(String, Vec<String>), String> {
    let (key, values) = arg
        .split_once('=')
        .ok_or_else(|| format!("'{arg}' is not KEY=V1,V2,..."))?;
    let key = key.trim();
    let values: Vec<String> = values.split(',').map(|v| v.trim().to_string()).collect();
    if key.is_empty() || values.iter().any(|v| v.is_empty()) {
        return Err(format!("'{arg}' is not KEY=V1,V2,... (empty key or value)"));
    }
    Ok((key.to_string(), values))
}

/// The overrides of the high-quality render that goes with a combination.
fn reference_overrides(combo: &[(String, String)], spp: u32, depth: u32) -> Vec<(String, String)> {
    let mut r: Vec<(String, String)> = combo
        .iter()
        .filter(|(k, _)| ![SPP, DEPTH, SPLIT, UPDATE, EYE_REUSE].contains(&k.as_str()))
        .cloned()
        .collect();
    r.push((SPP.into(), spp.to_string()));
    r.push((DEPTH.into(), depth.to_string()));
    r.push((SPLIT.into(), "sah".into()));
    r.push((UPDATE.into(), "rebuild".into()));
    r.push((EYE_REUSE.into(), "off".into()));
    r
}

/// The overrides of a combination's full trace: the same with every view traced in full.
fn full_trace_overrides(combo: &[(String, String)]) -> Vec<(String, String)> {
    let mut r: Vec<(String, String)> = combo
        .iter()
        .filter(|(k, _)| k != EYE_REUSE)
        .cloned()
        .collect();
    r.push((EYE_REUSE.into(), "off".into()));
    r
}

/// Traces the frames of a range in order, handing each frame's views and statistics to
/// `on_frame` as soon as it is traced (nothing of a frame is kept after it).
fn trace_frames(
    p: &LoadedPipeline,
    frames: (u32, u32),
    mut on_frame: impl FnMut(usize, Vec<(View, Image)>, FrameStats),
) -> Result<()> {
    let views = p.rig_views();
    let mut tracer = FrameTracer::new(p);
    for (k, f) in (frames.0..=frames.1).enumerate() {
        let (traced, stats) = tracer.trace(f, &views, &|_| {})?;
        on_frame(k, traced.views, stats);
    }
    Ok(())
}

/// Runs the sweep and writes its files; `progress` hears each combination as it finishes.
pub fn sweep(
    opts: &SweepOptions,
    mut progress: impl FnMut(&str),
) -> Result<Vec<CombinationResult>> {
    let base = LoadedPipeline::load(&opts.pipeline)?;
    for (key, _) in &opts.sweeps {
        if opts.sweeps.iter().filter(|(k, _)| k == key).count() > 1 {
            return Err(Error::input(
                &opts.pipeline,
                format!("--sweep {key} is given twice"),
            ));
        }
    }
    let frames = opts
        .frames
        .unwrap_or((base.spec.frames.start, base.spec.frames.end));
    if frames.1 < frames.0 {
        return Err(Error::input(
            &opts.pipeline,
            format!("frame range {}..{} is empty", frames.0, frames.1),
        ));
    }
    // Every combination is validated before anything is traced.
    let combos = combinations(&opts.sweeps);
    let pipelines: Vec<LoadedPipeline> = combos
        .iter()
        .map(|c| base.with_overrides(c))
        .collect::<Result<_>>()?;
    let ref_spp = opts.reference_spp.unwrap_or_else(|| {
        let most = pipelines
            .iter()
            .map(|p| p.spec.render.spp)
            .max()
            .unwrap_or(1);
        most.saturating_mul(4).clamp(64, 65536)
    });
    let ref_depth = opts.reference_depth.unwrap_or_else(|| {
        pipelines
            .iter()
            .map(|p| p.spec.render.max_depth)
            .max()
            .unwrap_or(8)
    });

    // One high-quality render per distinct reference, kept for every combination that uses it;
    // likewise one full trace (`eye_reuse = "off"`) per combination that reuses eyes.
    let mut renders: Vec<(Overrides, Vec<FrameViews>)> = Vec::new();
    let mut render_once = |key: Overrides, what: String| -> Result<usize> {
        if let Some(i) = renders.iter().position(|(k, _)| *k == key) {
            return Ok(i);
        }
        let rp = base.with_overrides(&key)?;
        progress(&format!("{what} {}", describe(&key)));
        let mut planes = Vec::new();
        trace_frames(&rp, frames, |_, views, _| {
            planes.push(
                views
                    .iter()
                    .map(|(v, img)| (*v, Planes::from_image(img)))
                    .collect(),
            )
        })?;
        renders.push((key, planes));
        Ok(renders.len() - 1)
    };
    // Per combination, the index of its reference and of its full trace (`None`: itself).
    let mut reference_of = Vec::with_capacity(combos.len());
    let mut full_of = Vec::with_capacity(combos.len());
    for (c, p) in combos.iter().zip(&pipelines) {
        reference_of.push(render_once(
            reference_overrides(c, ref_spp, ref_depth),
            format!("reference ({ref_spp} spp, depth {ref_depth})"),
        )?);
        full_of.push(if p.spec.render.eye_reuse == EyeReuse::Off {
            None
        } else {
            Some(render_once(full_trace_overrides(c), "full trace".into())?)
        });
    }
    let references = renders;

    let thresholds = Thresholds {
        fail: opts.threshold,
        warn: opts.threshold,
        ..Thresholds::default()
    };
    // Repeats go round all combinations, so that a slow spell of a shared machine spreads over
    // every combination instead of landing on one.
    let n = (frames.1 - frames.0 + 1) as usize;
    let mut samples: Vec<Samples> = (0..combos.len()).map(|_| Samples::new(n)).collect();
    for r in 0..opts.repeat.max(1) {
        for (ci, (c, p)) in combos.iter().zip(&pipelines).enumerate() {
            let reference = &references[reference_of[ci]].1;
            let full = full_of[ci].map(|i| &references[i].1);
            let s = &mut samples[ci];
            let pixels = f64::from(p.spec.render.width) * f64::from(p.spec.render.height);
            memory::reset_peak();
            trace_frames(p, frames, |k, views, stats| {
                s.update_s[k].push(stats.update_seconds());
                s.trace_s[k].push(stats.trace_seconds());
                s.frame_s[k]
                    .push(stats.pose_seconds + stats.update_seconds() + stats.trace_seconds());
                s.rays[k] = stats.rays.total();
                for (view, secs) in &stats.view_seconds {
                    match *view {
                        View::LEFT => s.left_s[k].push(*secs),
                        View::RIGHT => s.right_s[k].push(*secs),
                        _ => {}
                    }
                }
                let right: u64 = (stats.view_rays.iter())
                    .filter(|(view, _)| *view == View::RIGHT)
                    .map(|(_, rays)| rays.total())
                    .sum();
                s.right_rays_per_pixel[k] = right as f64 / pixels;
                if r == 0 {
                    s.eyes[k] = views
                        .iter()
                        .map(|(view, img)| {
                            let ours = Planes::from_image(img);
                            let c = compare(&ours, view_of(&reference[k], view), &thresholds);
                            let f = full
                                .map(|full| compare(&ours, view_of(&full[k], view), &thresholds));
                            (view.name(), EyeError::from(&c, f.as_ref()))
                        })
                        .collect();
                }
            })?;
            s.peak = memory::peak_bytes().map(|b| b.max(s.peak.unwrap_or(0)));
            let last: f64 = s.frame_s.iter().filter_map(|v| v.last()).sum();
            progress(&format!(
                "[repeat {}/{}] {}: {:.3} s/frame",
                r + 1,
                opts.repeat.max(1),
                describe(c),
                last / n as f64
            ));
        }
    }
    let results: Vec<CombinationResult> = combos
        .into_iter()
        .zip(samples)
        .map(|(values, s)| s.result(values, frames.0))
        .collect();
    write_files(opts, &results, ref_spp, ref_depth)?;
    Ok(results)
}

/// What the repeats of one combination measured, per frame.
struct Samples {
    update_s: Vec<Vec<f64>>,
    trace_s: Vec<Vec<f64>>,
    frame_s: Vec<Vec<f64>>,
    left_s: Vec<Vec<f64>>,
    right_s: Vec<Vec<f64>>,
    rays: Vec<u64>,
    right_rays_per_pixel: Vec<f64>,
    eyes: Vec<Vec<(String, EyeError)>>,
    peak: Option<usize>,
}

impl Samples {
    fn new(frames: usize) -> Samples {
        Samples {
            update_s: vec![Vec::new(); frames],
            trace_s: vec![Vec::new(); frames],
            frame_s: vec![Vec::new(); frames],
            left_s: vec![Vec::new(); frames],
            right_s: vec![Vec::new(); frames],
            rays: vec![0; frames],
            right_rays_per_pixel: vec![0.0; frames],
            eyes: vec![Vec::new(); frames],
            peak: None,
        }
    }

    fn result(self, values: Vec<(String, String)>, first_frame: u32) -> CombinationResult {
        let frames = (self.eyes.into_iter().enumerate())
            .map(|(k, eyes)| FrameRow {
                frame: first_frame + k as u32,
                update_s: median(&self.update_s[k]),
                trace_s: median(&self.trace_s[k]),
                frame_s: median(&self.frame_s[k]),
                frame_s_min: self.frame_s[k]
                    .iter()
                    .copied()
                    .fold(f64::INFINITY, f64::min),
                frame_s_max: self.frame_s[k].iter().copied().fold(0.0, f64::max),
                rays: self.rays[k],
                left_s: median_or_zero(&self.left_s[k]),
                right_s: median_or_zero(&self.right_s[k]),
                right_rays_per_pixel: self.right_rays_per_pixel[k],
                eyes,
            })
            .collect();
        CombinationResult {
            values,
            frames,
            peak_bytes: self.peak,
        }
    }
}

/// One view of a frame another render traced.
fn view_of<'a>(frame: &'a FrameViews, view: &View) -> &'a Planes {
    frame
        .iter()
        .find(|(v, _)| v == view)
        .map(|(_, planes)| planes)
        .expect("a combination traces the views of its reference")
}

fn median_or_zero(v: &[f64]) -> f64 {
    if v.is_empty() { 0.0 } else { median(v) }
}

fn describe(overrides: &[(String, String)]) -> String {
    overrides
        .iter()
        .map(|(k, v)| format!("{k}={v}"))
        .collect::<Vec<_>>()
        .join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn combinations_vary_the_first_key_slowest() {
        let s = vec![
            ("a".to_string(), vec!["1".to_string(), "2".to_string()]),
            (
                "b".to_string(),
                vec!["x".to_string(), "y".to_string(), "z".to_string()],
            ),
        ];
        let c = combinations(&s);
        assert_eq!(c.len(), 6);
        assert_eq!(
            c[0],
            vec![("a".into(), "1".into()), ("b".into(), "x".into())]
        );
        assert_eq!(
            c[3],
            vec![("a".into(), "2".into()), ("b".into(), "x".into())]
        );
        assert_eq!(combinations(&[]), vec![Vec::new()]);
    }

    #[test]
    fn sweep_arguments_need_a_key_and_values() {
        assert_eq!(
            parse_sweep("render.spp=1, 4,16").unwrap(),
            (
                "render.spp".into(),
                vec!["1".into(), "4".into(), "16".into()]
            )
        );
        assert!(parse_sweep("render.spp").is_err());
        assert!(parse_sweep("render.spp=1,,4").is_err());
        assert!(parse_sweep("=1").is_err());
    }

    #[test]
    fn a_reuse_mode_is_timed_against_the_left_eye_of_its_off_sibling() {
        let combination =
            |reuse: &str, spp: &str, (left_s, right_s): (f64, f64)| CombinationResult {
                values: vec![
                    ("render.eye_reuse".into(), reuse.into()),
                    ("render.spp".into(), spp.into()),
                ],
                frames: vec![FrameRow {
                    frame: 0,
                    update_s: 0.0,
                    trace_s: left_s + right_s,
                    frame_s: left_s + right_s,
                    frame_s_min: 0.0,
                    frame_s_max: 0.0,
                    rays: 1,
                    left_s,
                    right_s,
                    right_rays_per_pixel: 0.0,
                    eyes: Vec::new(),
                }],
                peak_bytes: None,
            };
        let results = [
            combination("off", "4", (2.0, 2.0)),
            combination("reproject", "4", (2.5, 0.5)),
            combination("off", "16", (8.0, 8.0)),
            combination("reproject", "16", (9.0, 1.0)),
        ];
        let off = results::off_sibling(&results, &results[3]).unwrap();
        assert_eq!(off.values[1].1, "16");
        assert_eq!(results[3].right_over_off_left(off), 1.0 / 8.0);
        assert_eq!(results[3].right_over_left(), 1.0 / 9.0);
        assert!(std::ptr::eq(
            results::off_sibling(&results, &results[0]).unwrap(),
            &results[0]
        ));
        // Without `eye_reuse` among the swept keys there is no sibling to name.
        let unswept = CombinationResult {
            values: vec![("render.spp".into(), "4".into())],
            ..results[1].clone()
        };
        assert!(results::off_sibling(std::slice::from_ref(&unswept), &unswept).is_none());
    }

    #[test]
    fn the_reference_replaces_speed_keys_and_keeps_the_others() {
        let c = vec![
            ("render.shading".to_string(), "phong".to_string()),
            ("render.spp".to_string(), "4".to_string()),
            ("accel.update".to_string(), "refit".to_string()),
        ];
        let r = reference_overrides(&c, 256, 12);
        assert!(r.contains(&("render.shading".into(), "phong".into())));
        assert!(r.contains(&("render.spp".into(), "256".into())));
        assert!(r.contains(&("render.max_depth".into(), "12".into())));
        assert!(r.contains(&("accel.update".into(), "rebuild".into())));
        assert!(r.contains(&("render.eye_reuse".into(), "off".into())));
        assert_eq!(r.len(), 6);
        let with_reuse = vec![
            ("render.eye_reuse".to_string(), "reproject".to_string()),
            ("render.spp".to_string(), "4".to_string()),
        ];
        let full = full_trace_overrides(&with_reuse);
        assert_eq!(
            full,
            vec![
                ("render.spp".to_string(), "4".to_string()),
                ("render.eye_reuse".to_string(), "off".to_string())
            ]
        );
    }
}
