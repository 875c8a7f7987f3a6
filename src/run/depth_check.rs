//! `check --depth`: every frame's rig and parallax from the depth probe alone (posed, its
//! acceleration structure brought up to date, one closest-hit ray per probe pixel), without
//! shading a pixel. The numbers are the ones a render logs in `frame-log.csv`.

use super::rig_plan::{DepthSummary, FrameRig};
use super::trace::FrameTracer;
use crate::error::{Error, Result};
use crate::pipeline::LoadedPipeline;
use std::fmt;

/// Each frame's rig and depth, and the run's summary.
pub struct DepthReport {
    pub frames: Vec<(u32, FrameRig)>,
    pub summary: DepthSummary,
}

/// Plans `frames` (default: the pipeline's `[frames]`) as a render would.
pub fn depth_check(p: &LoadedPipeline, frames: Option<(u32, u32)>) -> Result<DepthReport> {
    let (a, b) = frames.unwrap_or((p.spec.frames.start, p.spec.frames.end));
    let mut tracer = FrameTracer::new(p);
    let mut report = DepthReport {
        frames: Vec::new(),
        summary: DepthSummary::default(),
    };
    for frame in a..=b {
        let Some(rig) = tracer.plan(frame) else {
            return Err(Error::input(
                &p.file,
                "[stereo] rig = \"mono\" has no parallax: --depth needs a stereo rig",
            ));
        };
        report.summary.add(frame, &rig, tracer.budget());
        report.frames.push((frame, rig));
    }
    Ok(report)
}

impl fmt::Display for DepthReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{:>6} {:>11} {:>11} {:>8} {:>8} {:>16} {:>16} {:>6} {:>13}",
            "frame",
            "converge m",
            "interaxial",
            "near m",
            "far m",
            "near px (%)",
            "far px (%)",
            "budget",
            "window L/R px"
        )?;
        for (frame, r) in &self.frames {
            let (near, far, near_px, far_px) = match r.depth {
                Some(d) => (
                    format!("{:.3}", d.near),
                    format!("{:.3}", d.far),
                    format!("{:.1} ({:+.2})", d.near_pixels, r.percent(d.near_pixels)),
                    format!("{:.1} ({:+.2})", d.far_pixels, r.percent(d.far_pixels)),
                ),
                None => ("-".into(), "-".into(), "-".into(), "-".into()),
            };
            writeln!(
                f,
                "{frame:>6} {:>11.3} {:>11.4} {near:>8} {far:>8} {near_px:>16} {far_px:>16} {:>6} {:>13}",
                r.convergence,
                r.interaxial,
                if r.over_budget { "OVER" } else { "ok" },
                format!("{:.1}/{:.1}", r.window.0, r.window.1)
            )?;
        }
        write!(f, "{}", self.summary)
    }
}
