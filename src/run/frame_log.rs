//! `frame-log.csv`: one row per frame and object, what the acceleration update did and why, and
//! where the frame's time went. A plain run writes it at the end; a farm's shards keep their rows
//! in the manifest and `assemble` merges them.

use super::rig_plan::FrameRig;
use super::trace::FrameStats;
use crate::render::{RayCounts, View};

/// The frame log every run writes beside the outputs.
pub const FRAME_LOG: &str = "frame-log.csv";

/// Columns of `frame-log.csv`: one row per frame and object, what the acceleration update did
/// and why, and where the time went (`update_s` per object; `left_s`, `right_s`, `other_s`: the
/// frame's tracing per view, repeated on each of its rows; `sah_cost` when a tree was built;
/// `reused_samples`: camera samples that took another view's hit under `eye_reuse =
/// "reproject"`, `traced_samples`: those that traced their camera ray, `reused_shadow_rays`:
/// shadow answers taken with the reused hits, `reused_radiance_samples`: reused samples that
/// took the radiance too under `"reproject-radiance"`; all per frame; then the rays traced for
/// the right eye, in every mode: `right_camera_rays` (under reuse, the samples that traced:
/// holes and unverified hits), `right_secondary_rays` (mirror, glass and BLEND rays: under reuse,
/// the view-dependent part) and `right_shadow_rays`). Then the frame's rig and
/// depth budget (stereo rigs; empty for mono): `convergence_m` and `interaxial_m` as traced,
/// the nearest and farthest visible point (`near_m`, `far_m`) with their parallax in pixels and
/// in percent of the width (negative in front of the screen), `over_budget` (1 when the frame
/// leaves `[stereo]`'s depth budget), and the floating-window borders in pixels.
pub const FRAME_LOG_COLUMNS: [&str; 28] = [
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
    "right_camera_rays",
    "right_secondary_rays",
    "right_shadow_rays",
    "convergence_m",
    "interaxial_m",
    "near_m",
    "far_m",
    "near_parallax_px",
    "far_parallax_px",
    "near_parallax_pct",
    "far_parallax_pct",
    "over_budget",
    "window_left_px",
    "window_right_px",
];

/// The frame's rows of `frame-log.csv`: one per object the acceleration update touched.
pub fn rows(frame: u32, stats: &FrameStats) -> Vec<Vec<String>> {
    let mut view_seconds = [0f64; 3];
    for (view, secs) in &stats.view_seconds {
        view_seconds[match *view {
            View::LEFT => 0,
            View::RIGHT => 1,
            _ => 2,
        }] += secs;
    }
    let rig = rig_columns(stats.rig.as_ref());
    let right = stats
        .view_rays
        .iter()
        .filter(|(v, _)| *v == View::RIGHT)
        .fold(RayCounts::default(), |mut sum, (_, rays)| {
            sum.add(rays);
            sum
        });
    stats
        .update
        .iter()
        .map(|row| {
            let mut columns = vec![
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
                right.primary.to_string(),
                right.secondary.to_string(),
                right.shadow.to_string(),
            ];
            columns.extend(rig.iter().cloned());
            columns
        })
        .collect()
}

/// The rig and depth-budget columns of a frame (empty without a stereo rig, and the depth
/// columns empty when nothing was hit).
fn rig_columns(rig: Option<&FrameRig>) -> Vec<String> {
    let Some(r) = rig else {
        return vec![String::new(); 11];
    };
    let depth = r.depth.map_or(vec![String::new(); 6], |d| {
        vec![
            format!("{:.4}", d.near),
            format!("{:.4}", d.far),
            format!("{:.3}", d.near_pixels),
            format!("{:.3}", d.far_pixels),
            format!("{:.3}", r.percent(d.near_pixels)),
            format!("{:.3}", r.percent(d.far_pixels)),
        ]
    });
    let mut columns = vec![
        format!("{:.4}", r.convergence),
        format!("{:.5}", r.interaxial),
    ];
    columns.extend(depth);
    columns.push((r.over_budget as u8).to_string());
    columns.push(format!("{:.2}", r.window.0));
    columns.push(format!("{:.2}", r.window.1));
    columns
}
