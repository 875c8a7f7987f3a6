//! The rig each frame is traced with, chosen from depth probes (`[stereo]`): convergence and
//! interaxial fixed or automatic, the floating window, and the frame's depth budget for the log.
//!
//! Automatic choices are smoothed over `smoothing` frames on either side, clamped to the
//! pipeline's `[frames]` range (not a shard's or `--frames`' part of it), so a frame gets the
//! same rig whichever run renders it:
//! - convergence: the mean over the window of each frame's own choice (the subject's depth, or
//!   the median depth at the centre of the frame);
//! - interaxial: the mean over the window of each frame's minimum over its own window of the
//!   largest interaxial the budget allows. Every term is at most the frame's own limit, so the
//!   smoothed value never breaks the budget where the raw one kept it;
//! - floating window: likewise the mean of maxima, so a border is never narrower than the frame
//!   needs.

use crate::pipeline::{Metres, StereoSection};
use crate::render::{
    Budget, DepthProbe, DepthRange, FloatingWindow, ParallaxModel, ProbeCamera, VIEWER_EYES,
    auto_interaxial, window_need,
};
use std::collections::BTreeMap;

/// Convergence when a frame and its whole window offer nothing to converge on (every probe ray
/// missed and no subject is in front of the camera): the pipeline's default convergence.
const FALLBACK_CONVERGENCE: f32 = 3.0;

/// What a probe of one frame found.
#[derive(Clone, Debug)]
pub struct FrameProbe {
    pub depth: DepthProbe,
    /// The subject's depth, when a subject is named and in front of the camera.
    pub subject: Option<f32>,
    pub camera: ProbeCamera,
}

impl FrameProbe {
    fn tan_x(&self) -> f32 {
        (self.camera.yfov * 0.5).tan() * self.camera.width as f32 / self.camera.height as f32
    }
}

/// The rig of one frame and what its depth looks like through it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameRig {
    pub interaxial: f32,
    pub convergence: f32,
    /// Floating-window borders in pixels: the left eye's left edge, the right eye's right edge.
    pub window: (f32, f32),
    /// The nearest and farthest visible point and their parallax; `None` when nothing was hit.
    pub depth: Option<DepthRange>,
    pub over_budget: bool,
    /// Film width, pixels (for parallax as a percentage).
    pub width: f32,
}

impl FrameRig {
    pub fn percent(&self, pixels: f32) -> f32 {
        100.0 * pixels / self.width
    }
}

/// A run's depth over its frames: the extreme parallax and the frames that left the budget.
#[derive(Clone, Debug, Default)]
pub struct DepthSummary {
    budget: Option<Budget>,
    /// The most crossed and most uncrossed parallax, percent of the width.
    front: Option<f32>,
    behind: Option<f32>,
    /// Frames over the budget, as runs of consecutive frames.
    over: Vec<(u32, u32)>,
}

impl DepthSummary {
    pub fn add(&mut self, frame: u32, rig: &FrameRig, budget: Budget) {
        self.budget = Some(budget);
        if let Some(d) = rig.depth {
            let (lo, hi) = (
                rig.percent(d.near_pixels.min(d.far_pixels)),
                rig.percent(d.near_pixels.max(d.far_pixels)),
            );
            self.front = Some(self.front.map_or(lo, |f| f.min(lo)));
            self.behind = Some(self.behind.map_or(hi, |b| b.max(hi)));
        }
        if rig.over_budget {
            match self.over.last_mut() {
                Some((_, last)) if *last + 1 == frame => *last = frame,
                _ => self.over.push((frame, frame)),
            }
        }
    }

    /// The warning a run ends with when frames left the budget.
    pub fn warning(&self) -> Option<String> {
        let b = self.budget?;
        let count: u32 = self.over.iter().map(|(a, z)| z - a + 1).sum();
        if count == 0 {
            return None;
        }
        let mut runs: Vec<String> = self
            .over
            .iter()
            .take(8)
            .map(|&(a, z)| {
                if a == z {
                    a.to_string()
                } else {
                    format!("{a}..{z}")
                }
            })
            .collect();
        if self.over.len() > 8 {
            runs.push("...".into());
        }
        Some(format!(
            "{count} frame(s) leave the depth budget of -{:.2}% .. +{:.2}% of the width (frames {}); \
             frame-log.csv has each frame's parallax. Lower the interaxial, move the convergence, \
             or set interaxial = \"auto\"",
            b.front,
            b.behind,
            runs.join(", ")
        ))
    }
}

impl std::fmt::Display for DepthSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match (self.budget, self.front, self.behind) {
            (Some(b), Some(front), Some(behind)) => write!(
                f,
                "depth: parallax {front:+.2}% .. {behind:+.2}% of the width (budget -{:.2}% .. +{:.2}%)",
                b.front, b.behind
            ),
            (Some(_), _, _) => write!(f, "depth: nothing but background was seen"),
            _ => Ok(()),
        }
    }
}

/// The probes a source gives for frames; the planner asks each frame at most once while it is
/// within reach of the frames being planned.
pub type ProbeSource<'a> = dyn FnMut(u32) -> FrameProbe + 'a;

pub struct RigPlanner {
    stereo: StereoSection,
    budget: Budget,
    /// The pipeline's `[frames]` range.
    range: (u32, u32),
    radius: u32,
    probes: BTreeMap<u32, FrameProbe>,
    convergence: BTreeMap<u32, f32>,
    interaxial_floor: BTreeMap<u32, Option<f32>>,
    interaxial: BTreeMap<u32, f32>,
    window_ceiling: BTreeMap<u32, (f32, f32)>,
}

impl RigPlanner {
    pub fn new(stereo: &StereoSection, range: (u32, u32)) -> RigPlanner {
        RigPlanner {
            stereo: stereo.clone(),
            budget: Budget::new(
                stereo.budget_front,
                stereo.budget_behind,
                stereo.screen_width,
            ),
            range,
            radius: stereo.smoothing,
            probes: BTreeMap::new(),
            convergence: BTreeMap::new(),
            interaxial_floor: BTreeMap::new(),
            interaxial: BTreeMap::new(),
            window_ceiling: BTreeMap::new(),
        }
    }

    pub fn budget(&self) -> Budget {
        self.budget
    }

    /// Whether a frame's rig depends on other frames' probes (an automatic choice, smoothed).
    pub fn needs_neighbours(&self) -> bool {
        self.radius > 0
            && (self.stereo.convergence == Metres::Auto
                || self.stereo.interaxial == Metres::Auto
                || self.stereo.floating_window == FloatingWindow::Auto)
    }

    /// The rig of `frame`, probing the frames it depends on through `source`.
    pub fn rig(&mut self, frame: u32, source: &mut ProbeSource) -> FrameRig {
        // Nothing before the reach of this frame's chain of windows (border, interaxial, its
        // floor, convergence, probes: five windows deep) is asked again when frames come in order.
        let reach = 5 * self.radius + 1;
        let keep = frame.saturating_sub(reach);
        for map in [&mut self.convergence, &mut self.interaxial] {
            map.retain(|&f, _| f >= keep);
        }
        self.probes.retain(|&f, _| f >= keep);
        self.interaxial_floor.retain(|&f, _| f >= keep);
        self.window_ceiling.retain(|&f, _| f >= keep);

        let convergence = self.convergence(frame, source);
        let interaxial = self.interaxial(frame, source);
        let window = match self.stereo.floating_window {
            FloatingWindow::Off => (0.0, 0.0),
            FloatingWindow::Auto => {
                let ceilings: Vec<(f32, f32)> = self
                    .window(frame)
                    .map(|f| self.window_ceiling(f, source))
                    .collect();
                let n = ceilings.len() as f64;
                let (l, r) = ceilings
                    .iter()
                    .fold((0f64, 0f64), |(l, r), c| (l + c.0 as f64, r + c.1 as f64));
                ((l / n) as f32, (r / n) as f32)
            }
        };
        let model = self.model(frame, source, convergence, interaxial);
        let probe = self.probe(frame, source);
        let depth = DepthRange::of(&probe.depth, &model);
        FrameRig {
            interaxial,
            convergence,
            window,
            depth,
            over_budget: depth.is_some_and(|d| d.exceeds(&self.budget, model.width)),
            width: model.width,
        }
    }

    /// The frames whose values smooth `frame`'s: within `radius`, inside the range.
    fn window(&self, frame: u32) -> std::ops::RangeInclusive<u32> {
        let lo = frame.saturating_sub(self.radius).max(self.range.0);
        let hi = frame.saturating_add(self.radius).min(self.range.1);
        lo.min(frame)..=hi.max(frame)
    }

    fn probe(&mut self, frame: u32, source: &mut ProbeSource) -> &FrameProbe {
        self.probes.entry(frame).or_insert_with(|| source(frame))
    }

    fn model(
        &mut self,
        frame: u32,
        source: &mut ProbeSource,
        convergence: f32,
        interaxial: f32,
    ) -> ParallaxModel {
        let tan_x = self.probe(frame, source).tan_x();
        let width = self.probe(frame, source).camera.width as f32;
        ParallaxModel {
            rig: self.stereo.rig,
            interaxial,
            convergence,
            width,
            tan_x,
        }
    }

    /// The frame's own choice of convergence, before smoothing.
    fn own_convergence(&mut self, frame: u32, source: &mut ProbeSource) -> Option<f32> {
        let probe = self.probe(frame, source);
        let near_plane = probe.camera.znear;
        probe
            .subject
            .filter(|&d| d > near_plane)
            .or(probe.depth.centre)
    }

    fn convergence(&mut self, frame: u32, source: &mut ProbeSource) -> f32 {
        if let Some(c) = self.stereo.convergence.fixed() {
            return c;
        }
        if let Some(&c) = self.convergence.get(&frame) {
            return c;
        }
        let own: Vec<f32> = self
            .window(frame)
            .filter_map(|f| self.own_convergence(f, source))
            .collect();
        let c = mean(&own).unwrap_or(FALLBACK_CONVERGENCE);
        self.convergence.insert(frame, c);
        c
    }

    /// The smallest of the largest interaxials the budget allows over `frame`'s window.
    fn interaxial_floor(&mut self, frame: u32, source: &mut ProbeSource) -> Option<f32> {
        if let Some(&v) = self.interaxial_floor.get(&frame) {
            return v;
        }
        let mut floor: Option<f32> = None;
        for f in self.window(frame) {
            let convergence = self.convergence(f, source);
            let model = self.model(f, source, convergence, 0.0);
            let budget = self.budget;
            if let Some(ia) = auto_interaxial(&self.probe(f, source).depth, &model, &budget) {
                floor = Some(floor.map_or(ia, |m| m.min(ia)));
            }
        }
        self.interaxial_floor.insert(frame, floor);
        floor
    }

    fn interaxial(&mut self, frame: u32, source: &mut ProbeSource) -> f32 {
        if let Some(ia) = self.stereo.interaxial.fixed() {
            return ia;
        }
        if let Some(&ia) = self.interaxial.get(&frame) {
            return ia;
        }
        let floors: Vec<f32> = self
            .window(frame)
            .filter_map(|f| self.interaxial_floor(f, source))
            .collect();
        // Nothing limits the rig anywhere near: a human's eye separation.
        let ia = mean(&floors).unwrap_or(VIEWER_EYES);
        self.interaxial.insert(frame, ia);
        ia
    }

    /// The widest border any frame in `frame`'s window needs, per edge.
    fn window_ceiling(&mut self, frame: u32, source: &mut ProbeSource) -> (f32, f32) {
        if let Some(&v) = self.window_ceiling.get(&frame) {
            return v;
        }
        let mut ceiling = (0.0f32, 0.0f32);
        for f in self.window(frame) {
            let convergence = self.convergence(f, source);
            let interaxial = self.interaxial(f, source);
            let model = self.model(f, source, convergence, interaxial);
            let need = window_need(&self.probe(f, source).depth, &model);
            ceiling = (ceiling.0.max(need.0), ceiling.1.max(need.1));
        }
        self.window_ceiling.insert(frame, ceiling);
        ceiling
    }
}

/// The mean in f64, summed in order (the same on every run).
fn mean(values: &[f32]) -> Option<f32> {
    (!values.is_empty())
        .then(|| (values.iter().map(|&v| v as f64).sum::<f64>() / values.len() as f64) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::Rig;
    use glam::Mat4;

    fn probe(near: f32, far: f32) -> FrameProbe {
        FrameProbe {
            depth: DepthProbe {
                near: Some(near),
                far: Some(far),
                centre: Some(0.5 * (near + far)),
                near_most: None,
                columns: vec![(0.5, near), (99.5, far)],
            },
            subject: None,
            camera: ProbeCamera {
                world: Mat4::IDENTITY,
                yfov: 0.8,
                znear: 0.1,
                zfar: None,
                width: 100,
                height: 50,
            },
        }
    }

    /// A scene whose nearest point jumps from 4 m to 1 m at frame 10.
    fn jumping(f: u32) -> FrameProbe {
        if f < 10 {
            probe(4.0, 8.0)
        } else {
            probe(1.0, 8.0)
        }
    }

    fn stereo(smoothing: u32) -> StereoSection {
        StereoSection {
            rig: Rig::OffAxis,
            interaxial: Metres::Auto,
            convergence: Metres::Auto,
            floating_window: FloatingWindow::Auto,
            smoothing,
            ..StereoSection::default()
        }
    }

    #[test]
    fn smoothed_choices_stay_within_the_budget_and_change_gradually() {
        let mut planner = RigPlanner::new(&stereo(3), (0, 19));
        let rigs: Vec<FrameRig> = (0..20).map(|f| planner.rig(f, &mut jumping)).collect();
        for (f, r) in rigs.iter().enumerate() {
            assert!(!r.over_budget, "frame {f}: {r:?}");
        }
        for pair in rigs.windows(2) {
            let step = (pair[1].convergence - pair[0].convergence).abs();
            assert!(step < 1.0, "convergence jumps by {step}");
        }
        assert!(rigs[0].convergence > rigs[19].convergence);
    }

    #[test]
    fn a_frame_gets_the_same_rig_whichever_frame_a_run_starts_at() {
        let mut whole = RigPlanner::new(&stereo(4), (0, 29));
        let all: Vec<FrameRig> = (0..30).map(|f| whole.rig(f, &mut jumping)).collect();
        let mut shard = RigPlanner::new(&stereo(4), (0, 29));
        for f in 12..20 {
            assert_eq!(shard.rig(f, &mut jumping), all[f as usize], "frame {f}");
        }
    }

    #[test]
    fn the_window_is_never_narrower_than_the_frame_needs() {
        let mut planner = RigPlanner::new(&stereo(2), (0, 19));
        for f in 0..20 {
            let rig = planner.rig(f, &mut jumping);
            let p = jumping(f);
            let model = ParallaxModel {
                rig: Rig::OffAxis,
                interaxial: rig.interaxial,
                convergence: rig.convergence,
                width: 100.0,
                tan_x: p.tan_x(),
            };
            let need = window_need(&p.depth, &model);
            assert!(rig.window.0 >= need.0 - 1e-4, "frame {f}: {rig:?} {need:?}");
        }
    }
}
