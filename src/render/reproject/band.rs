//! One band of target rows: the source pixels that land in it, gathered into cells, and from
//! the cells each target pixel's plan (the rules of `mod.rs`). A band reads the rows it covers
//! and one more on each side (the rules' windows are three rows high), so bands are planned
//! independently, and the plans do not depend on the thread count.

use super::source::{SourcePixel, SourcePixels};
use super::{LOBE_FRACTION, MAX_PARALLAX_SPREAD, RADIANCE_BOUND};
use crate::accel::prefetch;
use glam::Vec3;
use std::cell::RefCell;
use std::ops::Range;

/// Half-widths of rules 1-2's window (5x3) and of rule 4's candidate window (3x3).
pub(super) const WINDOW_X: usize = 2;
pub(super) const WINDOW_Y: usize = 1;
const CANDIDATE_X: usize = 1;
/// Distinct triangles a target cell holds, and candidates a target pixel tests. Where there
/// are more, the pixel traces: its candidates would be incomplete.
const SLOTS: usize = 8;
const MAX_CANDIDATES: usize = 24;

/// How source pixels land in the target film, and which may lend their radiance.
#[derive(Clone, Copy)]
pub(super) struct Landing {
    /// A point at inverse depth `u` moves `a + b u` pixels along its row
    /// (`EyeCamera::parallax_line`).
    pub a: f32,
    pub b: f32,
    /// Misses land too, at infinity (no far plane: a miss is a miss at every distance).
    pub misses: bool,
    /// `"reproject-radiance"`: the distance between the eyes, metres.
    pub baseline: Option<f32>,
    /// How thick a strip along a pixel's side its samples may leave unseen, pixels
    /// (`sampling::unseen_strip`).
    pub unseen: f32,
}

/// What a target pixel does.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Plan {
    Trace,
    /// Every source pixel around it missed.
    Miss,
    Radiance(Vec3),
    /// Its samples verify `candidates[first..first + len]` of the band, with the window's
    /// shadow answers.
    Hits {
        lit: u32,
        shadowed: u32,
        first: u32,
        len: u8,
    },
}

/// One band's plans, row-major, and the candidate triangles they index.
pub(super) struct BandPlan {
    pub plans: Vec<Plan>,
    pub candidates: Vec<u32>,
}

/// The source pixels that landed (in part) on one target pixel.
#[derive(Clone, Copy)]
pub(super) struct Cell {
    /// The smallest and largest parallax landed; empty (`[inf, -inf]`) where nothing did.
    pub parallax: [f32; 2],
    pub prims: [u32; SLOTS],
    pub distinct: u8,
    /// A source pixel hit more triangles than it kept, or this cell more than `SLOTS`.
    pub overflow: bool,
    /// A miss landed.
    pub miss: bool,
    /// A hit landed whose radiance cannot stand for the target's.
    pub indirect: bool,
    pub lit: u32,
    pub shadowed: u32,
    /// The landed radiance, each source pixel's value weighted by the part of it that landed
    /// here, and the weights' sum.
    pub weight: f32,
    pub radiance: Vec3,
    /// Pixels whose radiance is a plane landed (`plane.rs`), and the largest of their bounds.
    pub planes: bool,
    pub plane_bound: f32,
    /// Pixels with too few hits for a plane landed, and bounds of their samples' radiance per
    /// channel (each pixel's mean give or take its spread).
    pub means: bool,
    pub radiance_lo: Vec3,
    pub radiance_hi: Vec3,
}

impl Default for Cell {
    fn default() -> Cell {
        Cell {
            parallax: [f32::INFINITY, f32::NEG_INFINITY],
            prims: [0; SLOTS],
            distinct: 0,
            overflow: false,
            miss: false,
            indirect: false,
            lit: 0,
            shadowed: 0,
            weight: 0.0,
            radiance: Vec3::ZERO,
            planes: false,
            plane_bound: 0.0,
            means: false,
            radiance_lo: Vec3::INFINITY,
            radiance_hi: Vec3::NEG_INFINITY,
        }
    }
}

impl Cell {
    pub fn covered(&self) -> bool {
        self.parallax[0] <= self.parallax[1]
    }

    /// The landed radiance, where every hit that landed may lend it and no miss landed.
    fn lent_radiance(&self) -> Option<Vec3> {
        (self.weight > 0.0 && !self.indirect && !self.miss).then(|| self.radiance / self.weight)
    }

    fn land(&mut self, parallax: [f32; 2]) {
        self.parallax = [
            self.parallax[0].min(parallax[0]),
            self.parallax[1].max(parallax[1]),
        ];
    }

    /// Adds the hits of source pixel `p`, of which the part `share` lands here; `direct` where
    /// their radiance may stand for the target's.
    pub fn add_hits(&mut self, p: &SourcePixel, parallax: [f32; 2], share: f32, direct: bool) {
        self.land(parallax);
        self.lit |= p.lit;
        self.shadowed |= p.shadowed;
        self.overflow |= p.overflow;
        for &prim in &p.prims[..p.distinct as usize] {
            self.add_prim(prim);
        }
        self.add_radiance(p, share, direct);
    }

    /// Adds the radiance of source pixel `p`, of which the part `share` lands here, where it
    /// may stand for the target's (`direct`).
    pub fn add_radiance(&mut self, p: &SourcePixel, share: f32, direct: bool) {
        if !direct {
            self.indirect = true;
            return;
        }
        self.weight += share;
        self.radiance += share * p.radiance;
        if p.plane() {
            self.planes = true;
            self.plane_bound = self.plane_bound.max(p.radiance_bound);
        } else {
            self.means = true;
            self.radiance_lo = self.radiance_lo.min(p.radiance - p.radiance_bound);
            self.radiance_hi = self.radiance_hi.max(p.radiance + p.radiance_bound);
        }
    }

    /// Adds one hit on `prim` of source pixel `p` (a pixel that keeps its samples) at
    /// `parallax`: the pixel's shadow answers, and no radiance.
    pub fn add_hit(&mut self, prim: u32, p: &SourcePixel, parallax: f32) {
        self.land([parallax, parallax]);
        self.lit |= p.lit;
        self.shadowed |= p.shadowed;
        self.add_prim(prim);
    }

    fn add_prim(&mut self, prim: u32) {
        let n = self.distinct as usize;
        if self.prims[..n].contains(&prim) {
            return;
        }
        if n < SLOTS {
            self.prims[n] = prim;
            self.distinct += 1;
        } else {
            self.overflow = true;
        }
    }

    pub fn add_miss(&mut self, parallax: f32) {
        self.land([parallax, parallax]);
        self.miss = true;
    }
}

/// Calls `add(cell, share)` for each cell of `row` that the span `[from, to]` (film x,
/// pixels) meets, `share` being the part of the span over it (1 for a point). A NaN span lands
/// nowhere.
pub(super) fn splat(row: &mut [Cell], from: f32, to: f32, mut add: impl FnMut(&mut Cell, f32)) {
    // Written so that NaN (and an empty span) fails.
    if !(from <= to && to >= 0.0 && from < row.len() as f32) {
        return;
    }
    // Truncation is the floor of the non-negative values left (and, unlike `floor`, no call
    // into libm on the baseline x86-64 target).
    let first = if from > 0.0 { from as usize } else { 0 };
    let last = (to as usize + 1).min(row.len());
    let length = to - from;
    for (k, cell) in row[first..last].iter_mut().enumerate() {
        let x = (first + k) as f32;
        let share = if length > 0.0 {
            (to.min(x + 1.0) - from.max(x)) / length
        } else {
            1.0
        };
        if share > 0.0 {
            add(cell, share);
        }
    }
}

/// Lands source row `y` on `row`, the target's row `y` (the rigs reprojection runs on keep a
/// point's row). A source pixel's samples lie on a span of its width, and its hits move by
/// their parallax range: they land on that span of the target row, widened by the range.
pub(super) fn land_row(source: &SourcePixels, y: usize, landing: &Landing, row: &mut [Cell]) {
    let mut segments = source.row(y).peekable();
    while let Some((x0, pixels, edges)) = segments.next() {
        // The row's next tile lies elsewhere in memory: ask for it while this one lands (the
        // loads of the records were a fifth of the landing's time).
        if let Some((_, next, _)) = segments.peek() {
            next.iter().for_each(prefetch);
        }
        for (i, p) in pixels.iter().enumerate() {
            let x = (x0 + i) as f32;
            let direct = landing
                .baseline
                .is_some_and(|b| p.reach >= 0.0 && b <= LOBE_FRACTION * p.reach);
            // Where the pixel's hits lie in the target row: its samples' span, moved by their
            // parallax range.
            let (from, to) = p.film_span();
            let (from, to) = (x + from, x + to);
            let (p0, p1) = (
                landing.a + landing.b * p.inv_depth[0],
                landing.a + landing.b * p.inv_depth[1],
            );
            let parallax = [p0.min(p1), p0.max(p1)];
            let (hits_from, hits_to) = (from + parallax[0], to + parallax[1]);
            if let Some((first, n)) = p.edge_samples() {
                // Across a depth edge (or over more triangles than it holds): each sample lands
                // where it moves to, and what lies between them is a hole.
                for e in &edges[first..first + n] {
                    let q = landing.a + landing.b * e.inv_depth;
                    let at = x + e.film_x + q;
                    match e.inv_depth > 0.0 {
                        true => splat(row, at, at, |c, _| c.add_hit(e.prim, p, q)),
                        false if landing.misses => splat(row, at, at, |c, _| c.add_miss(q)),
                        false => {}
                    }
                }
                // Their radiance mixes both sides of a depth edge. A pixel that only hit more
                // triangles than it holds (a finely tessellated surface) lands its radiance as
                // any pixel does.
                let spread = parallax[1] - parallax[0];
                let depth_edge = p.misses > 0 || spread > MAX_PARALLAX_SPREAD || spread.is_nan();
                splat(row, hits_from, hits_to, |c, w| {
                    c.add_radiance(p, w, direct && !depth_edge)
                });
                continue;
            }
            if p.hits > 0 {
                splat(row, hits_from, hits_to, |c, w| {
                    c.add_hits(p, parallax, w, direct)
                });
            }
            if p.misses > 0 && landing.misses {
                splat(row, from + landing.a, to + landing.a, |c, _| {
                    c.add_miss(landing.a)
                });
            }
        }
    }
}

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
        // 40 bytes a cell instead of a whole cell, with no range checks in their loops.
        summaries.clear();
        summaries.extend(row.iter().enumerate().map(|(x, c)| {
            CellSummary {
                // Rule 1: the pixel or a horizontal neighbour holds a sample.
                near: row[x.saturating_sub(1)..(x + 2).min(width)]
                    .iter()
                    .any(Cell::covered),
                holds: c.distinct > 0,
                overflow: c.overflow,
                parallax: c.parallax,
                lit: c.lit,
                shadowed: c.shadowed,
                value: c.lent_radiance(),
            }
        }));
        // Radiance windows' errors centred on the pixel before, this one and the next.
        let unseen = radiance.unwrap_or(f32::INFINITY);
        let error = |k: usize| match radiance.is_some() && k < width {
            true => window_error(row, summaries, k),
            false => WindowError::NONE,
        };
        let (mut before, mut here) = (WindowError::NONE, error(0));
        for x in 0..width {
            let after = error(x + 1);
            let interpolation = before.total.min(here.total).min(after.total);
            let slack = RADIANCE_BOUND - interpolation - unseen * here.bend;
            let lend = slack >= 0.0;
            (before, here) = (here, after);
            let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
            let (mut lit, mut shadowed, mut near) = (0, 0, true);
            for s in &summaries[x.saturating_sub(WINDOW_X)..(x + WINDOW_X + 1).min(width)] {
                lo = lo.min(s.parallax[0]);
                hi = hi.max(s.parallax[1]);
                lit |= s.lit;
                shadowed |= s.shadowed;
                near &= s.near;
            }
            let spread = hi - lo;
            let ok = near && !(spread > MAX_PARALLAX_SPREAD || spread.is_nan());
            let (mut hits, mut overflow) = (false, false);
            for s in &summaries[x.saturating_sub(CANDIDATE_X)..(x + CANDIDATE_X + 1).min(width)] {
                hits |= s.holds;
                overflow |= s.overflow;
            }
            out[x] = RowWindow {
                ok,
                hits,
                overflow,
                lit,
                shadowed,
                radiance: summaries[x].value.filter(|_| ok && lend),
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
    let bend = match summaries[cells.clone()] {
        [
            CellSummary { value: Some(a), .. },
            CellSummary { value: Some(b), .. },
            CellSummary { value: Some(c), .. },
        ] => a - 2.0 * b + c,
        [
            CellSummary { value: Some(a), .. },
            CellSummary { value: Some(b), .. },
        ] => a - b,
        _ => return WindowError::NONE,
    };
    let window = &row[cells];
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

/// How far the radiance `value` of target pixel (x, y) and that landed above and below it
/// bend away from a line, per channel at most (0 where a row beside it holds no radiance).
fn vertical_bend(
    cells: &[Cell],
    (x, y): (usize, usize),
    height: usize,
    at: &impl Fn(usize, usize) -> usize,
    value: Vec3,
) -> f32 {
    if y == 0 || y + 1 >= height {
        return 0.0;
    }
    match (
        cells[at(y - 1, x)].lent_radiance(),
        cells[at(y + 1, x)].lent_radiance(),
    ) {
        (Some(above), Some(below)) => (above - 2.0 * value + below).abs().max_element(),
        _ => 0.0,
    }
}

/// The rows of cells and row windows a band works on: three, the rules' window, reused row
/// after row so that they stay in the cache (a band's whole cells would not).
#[derive(Default)]
pub(super) struct Ring {
    cells: Vec<Cell>,
    windows: Vec<RowWindow>,
}

/// Row `y`'s place in a ring of three rows of `width`.
fn ring_at(width: usize) -> impl Fn(usize, usize) -> usize {
    move |y, x| (y % 3) * width + x
}

/// The plans of target rows `rows` of a film of `width` x `height`, of which only columns
/// `columns` may reuse (rule 3): each row is planned from the source rows landed on it and on
/// its neighbours.
pub(super) fn plan_band(
    source: &SourcePixels,
    landing: &Landing,
    rows: Range<usize>,
    columns: Range<usize>,
    ring: &mut Ring,
) -> BandPlan {
    let (width, height) = source.size();
    let mut band = BandPlan {
        plans: Vec::with_capacity(rows.len() * width),
        candidates: Vec::new(),
    };
    ring.cells.resize(3 * width, Cell::default());
    ring.windows.resize(3 * width, RowWindow::default());
    let at = ring_at(width);
    let radiance = landing.baseline.is_some();
    let mut landed = rows.start.saturating_sub(WINDOW_Y)..rows.start.saturating_sub(WINDOW_Y);
    for y in rows {
        // Land the rows up to the one below this row.
        while landed.end < (y + WINDOW_Y + 1).min(height) {
            let k = at(landed.end, 0);
            let row = &mut ring.cells[k..k + width];
            row.fill(Cell::default());
            land_row(source, landed.end, landing, row);
            let radiance = radiance.then_some(landing.unseen);
            row_windows(row, radiance, &mut ring.windows[k..k + width]);
            landed.end += 1;
        }
        let ring_rows = (ring.cells.as_slice(), ring.windows.as_slice());
        plan_row(ring_rows, &at, (y, (width, height)), &columns, &mut band);
    }
    band
}

/// Positions `x - half..=x + half`, cut by `0..len`: the film's border cuts the rules'
/// windows, since nothing lies beyond it in either view (rule 3's strip holds what lies beyond
/// the source's edge on the side where points move in).
fn around(x: usize, half: usize, len: usize) -> std::ops::RangeInclusive<usize> {
    x.saturating_sub(half)..=(x + half).min(len - 1)
}

/// Appends the plans of row `y` of a film of `width` x `height` to `band`, from the cells and
/// row windows of rows `y - 1..=y + 1` (placed by `at`); only columns `columns` may reuse, and
/// pixels as close to a strip of rule 3 as their window is wide trace.
pub(super) fn plan_row(
    (cells, windows): (&[Cell], &[RowWindow]),
    at: &impl Fn(usize, usize) -> usize,
    (y, (width, height)): (usize, (usize, usize)),
    columns: &Range<usize>,
    band: &mut BandPlan,
) {
    let margin = |strip: bool| if strip { WINDOW_X } else { 0 };
    let first = columns.start + margin(columns.start > 0);
    let end = columns.end.saturating_sub(margin(columns.end < width));
    for x in 0..width {
        let plan = if (first..end).contains(&x) {
            plan_pixel(
                cells,
                windows,
                (x, y),
                (width, height),
                at,
                &mut band.candidates,
            )
        } else {
            Plan::Trace
        };
        band.plans.push(plan);
    }
}

/// Rules 1-4 for target pixel (x, y) of a film of `width` x `height`, outside rule 3's strips.
fn plan_pixel(
    cells: &[Cell],
    windows: &[RowWindow],
    (x, y): (usize, usize),
    (width, height): (usize, usize),
    at: &impl Fn(usize, usize) -> usize,
    candidates: &mut Vec<u32>,
) -> Plan {
    let (mut lit, mut shadowed, mut hits, mut overflow) = (0u32, 0u32, false, false);
    for cy in around(y, WINDOW_Y, height) {
        let r = &windows[at(cy, x)];
        if !r.ok {
            return Plan::Trace;
        }
        lit |= r.lit;
        shadowed |= r.shadowed;
        hits |= r.hits;
        overflow |= r.overflow;
    }
    // The radiance's bound covers shadow edges among the samples as it does texture edges, so
    // the window's shadows need not agree (their bits are only reused on the hits below).
    if let Some(v) = windows[at(y, x)].radiance
        && vertical_bend(cells, (x, y), height, at, v) <= windows[at(y, x)].vertical_room
    {
        return Plan::Radiance(v);
    }
    // Rule 1 holds, so the candidate pixels hold samples: with no triangle among them, they
    // all missed.
    if !hits {
        return Plan::Miss;
    }
    if overflow {
        return Plan::Trace;
    }
    let first = candidates.len();
    let xs = around(x, CANDIDATE_X, width);
    for cy in around(y, WINDOW_Y, height) {
        for c in &cells[at(cy, *xs.start())..=at(cy, *xs.end())] {
            for &prim in &c.prims[..c.distinct as usize] {
                if !candidates[first..].contains(&prim) {
                    candidates.push(prim);
                }
            }
        }
    }
    let len = candidates.len() - first;
    if len > MAX_CANDIDATES {
        candidates.truncate(first);
        return Plan::Trace;
    }
    Plan::Hits {
        lit: lit & !shadowed,
        shadowed: shadowed & !lit,
        first: first as u32,
        len: len as u8,
    }
}
