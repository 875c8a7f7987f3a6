//! Stereo comfort: screen parallax from depth, the depth budget a frame is held to, the rig the
//! budget allows, and floating windows. Pure arithmetic over a `DepthProbe`; which frames feed a
//! smoothed choice is `run/rig_plan.rs`.
//!
//! Parallax is right-eye x minus left-eye x in pixels (WHITTED.md section 2): a point at depth Z
//! has `W/2 * interaxial * (1/c - 1/Z) / tan_x`, positive (uncrossed, behind the screen) past the
//! convergence distance c, negative (crossed, in front of the screen) before it. A parallel rig
//! converges at infinity (1/c = 0). For a toe-in rig the same formula is the parallax on the
//! viewing axis; away from it keystone changes it, so toe-in values are approximate.

use super::camera::Rig;
use super::depth::DepthProbe;
use serde::Deserialize;

/// The viewer's eye separation, metres: uncrossed parallax wider than this on the screen makes
/// the eyes diverge (65 mm, the mean adult value stereography's divergence rule uses, and the
/// default interaxial of this tool and of Blender's stereo camera).
pub const VIEWER_EYES: f32 = 0.065;

/// Floating windows (`[stereo] floating_window`): a black border on the outer edge of one eye
/// where a near object crosses that frame edge in front of the screen (Mendiburu).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FloatingWindow {
    #[default]
    Off,
    Auto,
}

/// The rig's horizontal geometry: everything parallax depends on.
#[derive(Clone, Copy, Debug)]
pub struct ParallaxModel {
    pub rig: Rig,
    pub interaxial: f32,
    pub convergence: f32,
    /// Film width, pixels.
    pub width: f32,
    /// Tangent of half the horizontal field of view.
    pub tan_x: f32,
}

impl ParallaxModel {
    /// Parallax in pixels of a point at `depth` metres per metre of interaxial.
    fn per_interaxial(&self, depth: f32) -> f32 {
        let inv_c = match self.rig {
            Rig::Parallel => 0.0,
            Rig::Mono => return 0.0,
            Rig::OffAxis | Rig::ToeIn => 1.0 / self.convergence,
        };
        0.5 * self.width * (inv_c - 1.0 / depth) / self.tan_x
    }

    /// Parallax in pixels of a point at `depth` metres (the WHITTED.md formula).
    pub fn pixels(&self, depth: f32) -> f32 {
        self.interaxial * self.per_interaxial(depth)
    }

    /// Parallax as a percentage of the film width.
    pub fn percent(&self, pixels: f32) -> f32 {
        100.0 * pixels / self.width
    }
}

/// How much parallax a frame may have, as percentages of the image width (both positive).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Budget {
    /// Crossed parallax allowed (points in front of the screen).
    pub front: f32,
    /// Uncrossed parallax allowed (points behind the screen), capped by the divergence limit
    /// when the screen width is known.
    pub behind: f32,
}

impl Budget {
    /// The budget from `[stereo]`: `behind` is capped at the divergence limit of a screen
    /// `screen_width` metres wide (`VIEWER_EYES` on that screen, as a percentage of its width).
    pub fn new(front: f32, behind: f32, screen_width: Option<f32>) -> Budget {
        Budget {
            front,
            behind: screen_width.map_or(behind, |s| behind.min(divergence_limit(s))),
        }
    }
}

/// The uncrossed parallax, as a percentage of the image width, at which the eyes looking at a
/// screen `screen_width` metres wide turn parallel.
pub fn divergence_limit(screen_width: f32) -> f32 {
    100.0 * VIEWER_EYES / screen_width
}

/// A frame's depth as parallax: the nearest and farthest visible point under the frame's rig.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthRange {
    pub near: f32,
    pub far: f32,
    pub near_pixels: f32,
    pub far_pixels: f32,
}

impl DepthRange {
    /// `None` when the probe hit nothing (only background: no parallax to judge).
    pub fn of(probe: &DepthProbe, model: &ParallaxModel) -> Option<DepthRange> {
        let (near, far) = (probe.near?, probe.far?);
        Some(DepthRange {
            near,
            far,
            near_pixels: model.pixels(near),
            far_pixels: model.pixels(far),
        })
    }

    /// Whether the range leaves the budget: crossed parallax past `front` or uncrossed past
    /// `behind`, as percentages of `width` pixels.
    pub fn exceeds(&self, budget: &Budget, width: f32) -> bool {
        let pct = |px: f32| 100.0 * px / width;
        pct(self.near_pixels.min(self.far_pixels)) < -budget.front
            || pct(self.far_pixels.max(self.near_pixels)) > budget.behind
    }
}

/// The largest interaxial (metres) that keeps the probed depths within `budget` under `model`'s
/// convergence; `None` when nothing limits it (nothing was hit). Parallax is linear in the
/// interaxial, so each bound is one division.
pub fn auto_interaxial(probe: &DepthProbe, model: &ParallaxModel, budget: &Budget) -> Option<f32> {
    let (near, far) = (probe.near?, probe.far?);
    let allowed_front = budget.front / 100.0 * model.width;
    let allowed_behind = budget.behind / 100.0 * model.width;
    let mut best = f32::INFINITY;
    for depth in [near, far] {
        let k = model.per_interaxial(depth);
        if k < 0.0 {
            best = best.min(allowed_front / -k);
        } else if k > 0.0 {
            best = best.min(allowed_behind / k);
        }
    }
    // Everything on the convergence plane: the background at infinity bounds it instead.
    if best.is_infinite() {
        let k = model.per_interaxial(f32::INFINITY);
        if k > 0.0 {
            best = allowed_behind / k;
        }
    }
    best.is_finite().then_some(best)
}

/// The floating window a frame needs, in pixels of border: (left edge of the left eye, right
/// edge of the right eye). A point in front of the screen at the left edge is seen by the left
/// eye further right than by the right eye, which loses it past the frame edge: a border as
/// wide as its crossed parallax on the left eye's left edge hides that strip from the left eye
/// too, and puts the window's left edge at the point's depth. The right edge mirrors it.
pub fn window_need(probe: &DepthProbe, model: &ParallaxModel) -> (f32, f32) {
    let (mut left, mut right) = (0.0f32, 0.0f32);
    for &(x, depth) in &probe.columns {
        if !depth.is_finite() {
            continue;
        }
        let p = model.pixels(depth);
        if p >= 0.0 {
            continue;
        }
        // The eyes see the column's nearest point at x -+ p/2 (p < 0: the left eye further right).
        if x + 0.5 * p < 0.0 {
            left = left.max(-p);
        }
        if x - 0.5 * p > model.width {
            right = right.max(-p);
        }
    }
    (left, right)
}

/// The floating-window border of a view at `offset` along the baseline (-1/2 the left eye, +1/2
/// the right), given the eyes' borders: the left edge's border shrinks linearly to nothing at the
/// right eye, the right edge's at the left eye, so intermediate views keep the window's depth.
pub fn view_window(offset: f32, (left, right): (f32, f32)) -> (f32, f32) {
    ((0.5 - offset) * left, (offset + 0.5) * right)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model(rig: Rig) -> ParallaxModel {
        ParallaxModel {
            rig,
            interaxial: 0.065,
            convergence: 3.0,
            width: 640.0,
            tan_x: 0.5,
        }
    }

    fn probe(near: f32, far: f32) -> DepthProbe {
        DepthProbe {
            near: Some(near),
            far: Some(far),
            centre: Some(far),
            near_most: None,
            columns: vec![(0.5, near), (639.5, far)],
        }
    }

    #[test]
    fn parallax_follows_the_whitted_formula() {
        let m = model(Rig::OffAxis);
        assert_eq!(m.pixels(3.0), 0.0);
        let expected = 320.0 * 0.065 * (1.0 / 3.0 - 1.0 / 6.0) / 0.5;
        assert!((m.pixels(6.0) - expected).abs() < 1e-4);
        assert!(m.pixels(1.0) < 0.0);
        assert!(model(Rig::Parallel).pixels(6.0) < 0.0);
        assert_eq!(model(Rig::Mono).pixels(6.0), 0.0);
    }

    #[test]
    fn auto_interaxial_meets_the_tighter_bound_exactly() {
        let m = model(Rig::OffAxis);
        let budget = Budget::new(1.0, 2.0, None);
        let p = probe(1.5, 30.0);
        let ia = auto_interaxial(&p, &m, &budget).unwrap();
        let chosen = ParallaxModel {
            interaxial: ia,
            ..m
        };
        let near = chosen.percent(chosen.pixels(1.5));
        let far = chosen.percent(chosen.pixels(30.0));
        assert!(near >= -1.0 - 1e-4 && far <= 2.0 + 1e-4, "{near} {far}");
        assert!((near + 1.0).abs() < 1e-4 || (far - 2.0).abs() < 1e-4);
    }

    #[test]
    fn a_screen_width_caps_the_budget_behind_at_divergence() {
        // 65 mm on a 10 m screen: 0.65% of its width.
        assert!((Budget::new(1.0, 2.0, Some(10.0)).behind - 0.65).abs() < 1e-6);
        assert_eq!(Budget::new(1.0, 2.0, Some(1.0)).behind, 2.0);
    }

    #[test]
    fn a_near_point_at_the_left_edge_needs_a_border_on_the_left_eye_only() {
        let m = model(Rig::OffAxis);
        let (left, right) = window_need(&probe(1.0, 6.0), &m);
        assert!((left + m.pixels(1.0)).abs() < 1e-4 && left > 0.0);
        assert_eq!(right, 0.0);
        assert_eq!(view_window(-0.5, (left, right)), (left, 0.0));
        assert_eq!(view_window(0.5, (left, right)), (0.0, 0.0));
    }
}
