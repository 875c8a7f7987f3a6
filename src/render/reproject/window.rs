//! A row's windows: what each target pixel's row of landed cells says to the rules of
//! `mod.rs`, decided once per row so that a pixel reads three of these (the rows above, at and
//! below it) instead of its whole window of cells.

use super::cell::Cell;
use super::{MAX_PARALLAX_SPREAD, RADIANCE_BOUND};
use glam::Vec3;
use std::cell::RefCell;

/// Half-widths of rules 1-2's window (5x3) and of rule 4's candidate window (3x3).
pub(super) const WINDOW_X: usize = 2;
pub(super) const WINDOW_Y: usize = 1;
pub(super) const CANDIDATE_X: usize = 1;

/// What one pixel's row contributes to the rules: whether the five pixels centred on it are all
/// covered (rule 1) and keep their parallax within the bound (rule 2), the union of their
/// shadow answers, whether the three candidate pixels hold a triangle or overflowed, and under
/// `"reproject-radiance"` the pixel's value where its row allows one (`row_radiance`).
/// Deciding these row by row lets a target pixel read three of these instead of its window.
#[derive(Clone, Copy, Default)]
pub(super) struct RowWindow {
    pub ok: bool,
    pub hits: bool,
    pub overflow: bool,
    pub lit: u32,
    pub shadowed: u32,
    pub radiance: Option<Vec3>,
    /// The largest bend of the radiance above, at and below the pixel that its bound leaves
    /// room for (`window_error`).
    pub vertical_room: f32,
}

/// `RowWindow` for every pixel of `row`; `radiance` under `"reproject-radiance"`.
pub(super) fn row_windows(row: &[Cell], radiance: Option<f32>, out: &mut [RowWindow]) {
    let width = row.len();
    SUMMARIES.with_borrow_mut(|summaries| {
        // What every window reads of a cell, once per cell, packed: the windows then read
        // 36 bytes a cell instead of the 100-byte cell. The row is padded with `WINDOW_X`
        // cells on each side that change no window (the film's border cuts the windows), so
        // that every window is the same five summaries, with no range checks in its loop.
        summaries.clear();
        summaries.resize(width + 2 * WINDOW_X, CellSummary::BEYOND);
        let cells = &mut summaries[WINDOW_X..WINDOW_X + width];
        for (s, c) in cells.iter_mut().zip(row) {
            *s = CellSummary {
                near: c.covered(),
                holds: c.distinct > 0,
                overflow: c.overflow,
                parallax: c.parallax,
                lit: c.lit,
                shadowed: c.shadowed,
                value: c.lent_radiance(),
            };
        }
        // Rule 1: the pixel or a horizontal neighbour holds a sample. `near` still says
        // whether the pixel itself and the next are covered when the pixel is reached.
        let mut covered_before = false;
        for x in 0..width {
            let covered = cells[x].near;
            let covered_after = cells.get(x + 1).is_some_and(|s| s.near);
            cells[x].near = covered_before || covered || covered_after;
            covered_before = covered;
        }
        // Radiance windows' errors centred on the pixel before, this one and the next.
        let unseen = radiance.unwrap_or(f32::INFINITY);
        let padded = &summaries[..];
        let unpadded = &padded[WINDOW_X..WINDOW_X + width];
        let error = |k: usize| match radiance.is_some() && k < width {
            true => window_error(row, unpadded, k),
            false => WindowError::NONE,
        };
        let (mut before, mut here) = (WindowError::NONE, error(0));
        let windows = padded.windows(2 * WINDOW_X + 1);
        for ((x, out), window) in out.iter_mut().enumerate().zip(windows) {
            let window: &[CellSummary; 2 * WINDOW_X + 1] = window.try_into().expect("5 cells");
            let after = error(x + 1);
            let interpolation = before.total.min(here.total).min(after.total);
            let slack = RADIANCE_BOUND - interpolation - unseen * here.bend;
            let lend = slack >= 0.0;
            (before, here) = (here, after);
            let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
            let (mut lit, mut shadowed, mut near) = (0, 0, true);
            for s in window {
                lo = lo.min(s.parallax[0]);
                hi = hi.max(s.parallax[1]);
                lit |= s.lit;
                shadowed |= s.shadowed;
                near &= s.near;
            }
            let spread = hi - lo;
            let ok = near && !(spread > MAX_PARALLAX_SPREAD || spread.is_nan());
            let (mut hits, mut overflow) = (false, false);
            for s in &window[WINDOW_X - CANDIDATE_X..=WINDOW_X + CANDIDATE_X] {
                hits |= s.holds;
                overflow |= s.overflow;
            }
            *out = RowWindow {
                ok,
                hits,
                overflow,
                lit,
                shadowed,
                radiance: window[WINDOW_X].value.filter(|_| ok && lend),
                vertical_room: slack / unseen,
            };
        }
    });
}

/// What the row windows read of one cell.
#[derive(Clone, Copy)]
struct CellSummary {
    /// Something landed in it or in a row neighbour (rule 1).
    near: bool,
    /// It holds a triangle, and it overflowed (`Cell`).
    holds: bool,
    overflow: bool,
    parallax: [f32; 2],
    lit: u32,
    shadowed: u32,
    /// `Cell::lent_radiance`.
    value: Option<Vec3>,
}

impl CellSummary {
    /// Beyond the film's border: a summary that changes no window it joins.
    const BEYOND: CellSummary = CellSummary {
        near: true,
        holds: false,
        overflow: false,
        parallax: [f32::INFINITY, f32::NEG_INFINITY],
        lit: 0,
        shadowed: 0,
        value: None,
    };
}

thread_local! {
    /// A row's cell summaries, reused from row to row.
    static SUMMARIES: RefCell<Vec<CellSummary>> = const { RefCell::new(Vec::new()) };
}

/// `"reproject-radiance"`: the bound on the error of the radiance landed in three pixels,
/// and how far their values bend away from a line.
#[derive(Clone, Copy)]
struct WindowError {
    total: f32,
    bend: f32,
}

impl WindowError {
    /// A window that cannot lend.
    const NONE: WindowError = WindowError {
        total: f32::INFINITY,
        bend: 0.0,
    };
}

/// `"reproject-radiance"`: the error of the radiance landed in the three pixels centred on `k`
/// (at the film's border, the three nearest it); `WindowError::NONE` where one of them holds a
/// hit whose radiance cannot stand for the target's, a miss, or no radiance.
///
/// A pixel takes its landed radiance where its own window passes rules 1-3 and the error is
/// within `RADIANCE_BOUND`, the error being the sum of:
/// - **The interpolation**: the least of the three windows that hold the pixel (centred on it
///   or on a neighbour), so that a pixel beside a texture edge is judged on its side of the
///   edge. Where every pixel landed in a window has a plane (`plane.rs`), the landed values are
///   the planes' centre values interpolated along the row (the landing's overlap weights), so
///   the error is the planes' largest bound plus how far the three values bend away from a line
///   (their second difference, about eight times the interpolation's error on a smooth curve).
///   Where none has (too few samples a pixel), the samples must agree: the window's bounds of
///   their radiance (a flat patch). Where both kinds landed, there is no bound.
/// - **What the samples did not see**: a step in the radiance beside the pixel (the bend of the
///   window centred on it, and that of the pixels above and below it) may reach into it along a
///   strip its samples left unseen (`Landing::unseen`): each bend times the strip's thickness.
fn window_error(row: &[Cell], summaries: &[CellSummary], k: usize) -> WindowError {
    let first = k.saturating_sub(1).min(row.len().saturating_sub(3));
    let cells = first..(first + 3).min(row.len());
    // Three cells, or two in a film two pixels wide; as arrays, so that the loops below unroll.
    let value = |s: &CellSummary| s.value;
    match (&summaries[cells.clone()], &row[cells]) {
        ([a, b, c], [ca, cb, cc]) => match (value(a), value(b), value(c)) {
            (Some(a), Some(b), Some(c)) => bounded_error(a - 2.0 * b + c, [ca, cb, cc]),
            _ => WindowError::NONE,
        },
        ([a, b], [ca, cb]) => match (value(a), value(b)) {
            (Some(a), Some(b)) => bounded_error(a - b, [ca, cb]),
            _ => WindowError::NONE,
        },
        _ => WindowError::NONE,
    }
}

/// `window_error` of the cells of `window`, whose landed values bend by `bend`.
fn bounded_error<const N: usize>(bend: Vec3, window: [&Cell; N]) -> WindowError {
    let bend = bend.abs().max_element();
    let total = if window.iter().all(|c| !c.means) {
        let bound = window.iter().map(|c| c.plane_bound).fold(0.0, f32::max);
        bound + bend
    } else if window.iter().all(|c| !c.planes) {
        let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for c in window {
            lo = lo.min(c.radiance_lo);
            hi = hi.max(c.radiance_hi);
        }
        (hi - lo).max_element()
    } else {
        f32::INFINITY
    };
    // NaN never lends.
    match total.is_nan() || bend.is_nan() {
        true => WindowError::NONE,
        false => WindowError { total, bend },
    }
}
