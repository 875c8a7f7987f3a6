//! The reuse rules on grids of cells filled by hand, without cameras.

use super::band::{Landing, plan_row};
use super::cell::Cell;
use super::source::SourcePixel;
use super::window::{RowWindow, row_windows};
use super::*;
use crate::accel::Hit;

#[test]
fn the_edge_strip_sits_on_the_side_near_points_move_to() {
    assert_eq!(edge_strips(-3.2, 100), 0..96);
    assert_eq!(edge_strips(2.0, 100), 2..100);
    assert_eq!(edge_strips(0.0, 100), 0..100);
    assert_eq!(edge_strips(-500.0, 100), 0..0);
    assert_eq!(edge_strips(f32::NAN, 100), 0..0);
}

/// A source pixel with one hit on `prim`, lit by light 0, of radiance 1.
fn hit_pixel(prim: u32) -> SourcePixel {
    let mut p = SourcePixel::default();
    let record = crate::render::integrator::PrimaryRecord {
        hit: Some(Hit {
            t: 1.0,
            prim,
            b1: 0.0,
            b2: 0.0,
        }),
        lit: 1,
        lobe: 1.0,
        ..crate::render::integrator::PrimaryRecord::NONE
    };
    let sample = source::Sample {
        film_x: 0.5,
        film_y: 0.5,
        depth: 1.0,
        distance: 1.0,
    };
    p.add(sample, &record);
    p.radiance = Vec3::ONE;
    p
}

/// As `hit_pixel`, with enough hits for a plane of centre value `value` and bound `bound`.
fn plane_pixel(prim: u32, value: Vec3, bound: f32) -> SourcePixel {
    let mut p = hit_pixel(prim);
    p.hits = plane::PLANE_SAMPLES as u16;
    (p.radiance, p.radiance_bound) = (value, bound);
    assert!(p.plane());
    p
}

/// The strip a pixel's samples may leave unseen in these grids: that of 16 samples a pixel.
const UNSEEN: f32 = 0.25;

/// Cells filled directly (no cameras): one source pixel per cell, covering it whole, at
/// parallax `parallax(x, y)`, having hit triangle `x / 4`.
struct Grid {
    width: usize,
    height: usize,
    cells: Vec<Cell>,
}

impl Grid {
    fn new(width: usize, height: usize, parallax: impl Fn(usize, usize) -> f32) -> Grid {
        let mut cells = vec![Cell::default(); width * height];
        for y in 0..height {
            for x in 0..width {
                let p = parallax(x, y);
                cells[y * width + x].add_hits(&hit_pixel((x / 4) as u32), [p, p], 1.0, true);
            }
        }
        Grid {
            width,
            height,
            cells,
        }
    }

    fn cell(&mut self, x: usize, y: usize) -> &mut Cell {
        &mut self.cells[y * self.width + x]
    }

    /// Rules 1-4 over the whole grid.
    fn plan(&self, radiance: bool) -> Reprojection {
        let (w, h) = (self.width, self.height);
        let mut windows = vec![RowWindow::default(); w * h];
        for (row, out) in self.cells.chunks(w).zip(windows.chunks_mut(w)) {
            row_windows(row, radiance.then_some(UNSEEN), out);
        }
        let mut band = BandPlan {
            plans: Vec::new(),
            candidates: Vec::new(),
        };
        for y in 0..h {
            let rows = (self.cells.as_slice(), windows.as_slice());
            plan_row(rows, &|y, x| y * w + x, (y, (w, h)), &(0..w), &mut band);
        }
        assert!(h <= BAND_ROWS, "one band");
        Reprojection {
            width: w,
            bands: vec![band],
        }
    }
}

#[test]
fn a_step_in_parallax_refuses_reuse_around_it_and_only_there() {
    let g = Grid::new(20, 5, |x, _| if x < 10 { 0.0 } else { -3.0 }).plan(false);
    for x in 0..20 {
        let near_step = (8..=11).contains(&x);
        assert_eq!(g.pixel(x, 2).is_none(), near_step, "x={x}");
    }
    // The film's border cuts the windows: its pixels reuse.
    assert!(g.pixel(0, 2).is_some() && g.pixel(5, 0).is_some() && g.pixel(5, 4).is_some());
}

#[test]
fn pixels_in_the_edge_strip_trace_and_those_beside_it_reuse() {
    let g = Grid::new(20, 5, |_, _| 0.0);
    let mut windows = vec![RowWindow::default(); 20 * 5];
    for (row, out) in g.cells.chunks(20).zip(windows.chunks_mut(20)) {
        row_windows(row, None, out);
    }
    let mut band = BandPlan {
        plans: Vec::new(),
        candidates: Vec::new(),
    };
    let rows = (g.cells.as_slice(), windows.as_slice());
    plan_row(rows, &|y, x| y * 20 + x, (2, (20, 5)), &(3..20), &mut band);
    let traced: Vec<bool> = band.plans.iter().map(|p| *p == Plan::Trace).collect();
    // The strip (0..3) traces; the pixels beside it, whose windows reach into it, and the
    // film's right border do not.
    assert_eq!(traced[..6], [true, true, true, false, false, false]);
    assert!(!traced[19]);
}

#[test]
fn a_parallax_that_changes_from_row_to_row_still_reuses() {
    // A receding floor: one pixel more parallax per row, constant along each row.
    let g = Grid::new(20, 6, |_, y| y as f32).plan(false);
    assert!((1..5).all(|y| g.pixel(8, y).is_some()));
    // Along a row the same change is a step.
    let g = Grid::new(20, 6, |x, _| x as f32).plan(false);
    assert!(g.pixel(8, 2).is_none());
}

#[test]
fn an_uncovered_pixel_refuses_its_window() {
    let mut g = Grid::new(20, 5, |_, _| 0.0);
    for x in 9..=11 {
        *g.cell(x, 2) = Cell::default();
    }
    let g = g.plan(false);
    assert!(g.pixel(8, 2).is_none() && g.pixel(12, 1).is_none());
    assert!(g.pixel(7, 2).is_some() && g.pixel(13, 2).is_some());
}

#[test]
fn candidates_come_from_the_neighbouring_pixels_and_shadow_answers_must_agree() {
    fn hits(g: &Reprojection) -> (Vec<u32>, u32, u32) {
        match g.pixel(8, 2) {
            Some(PixelReuse::Hits(h)) => (h.candidates.to_vec(), h.lit, h.shadowed),
            _ => panic!("a flat window reuses hits"),
        }
    }
    let mut g = Grid::new(20, 5, |_, _| 0.0);
    // Pixels 7..=9 saw triangles 1 and 2 (x / 4).
    assert_eq!(hits(&g.plan(false)), (vec![1, 2], 1, 0));
    g.cell(10, 3).shadowed = 1;
    assert_eq!(
        hits(&g.plan(false)),
        (vec![1, 2], 0, 0),
        "a disagreeing light is traced"
    );
}

#[test]
fn a_pixel_whose_candidates_overflowed_traces() {
    let mut g = Grid::new(20, 5, |_, _| 0.0);
    g.cell(9, 1).overflow = true;
    let p = g.plan(false);
    assert!(p.pixel(8, 2).is_none() && p.pixel(10, 2).is_none());
    assert!(p.pixel(11, 2).is_some() && p.pixel(7, 2).is_some());
}

#[test]
fn a_flat_rough_pixel_takes_its_samples_mean_radiance_and_an_edge_does_not() {
    let mut g = Grid::new(20, 5, |_, _| 0.0);
    assert!(matches!(g.plan(true).pixel(8, 2), Some(PixelReuse::Radiance(v)) if v == Vec3::ONE));
    // A pixel whose samples spread by more than the bound: every window that holds it is
    // refused, and it traces its own samples on the reused hits. Its neighbours lend from the
    // windows on their other side.
    g.cell(9, 2).radiance_hi = Vec3::splat(1.5);
    let plans = g.plan(true);
    assert!(matches!(plans.pixel(9, 2), Some(PixelReuse::Hits(_))));
    for x in [8, 10] {
        assert!(matches!(plans.pixel(x, 2), Some(PixelReuse::Radiance(v)) if v == Vec3::ONE));
    }
}

/// A 20 x 5 grid whose cells each hold one plane pixel of value `value(x, y)` and bound
/// `bound(x)`: the radiance each pixel of row 2 takes, if any.
fn plane_grid(
    value: impl Fn(usize, usize) -> Vec3,
    bound: impl Fn(usize) -> f32,
) -> Vec<Option<Vec3>> {
    let mut g = Grid::new(20, 5, |_, _| 0.0);
    for y in 0..5 {
        for x in 0..20 {
            *g.cell(x, y) = Cell::default();
            g.cell(x, y)
                .add_hits(&plane_pixel(1, value(x, y), bound(x)), [0.0; 2], 1.0, true);
        }
    }
    let plans = g.plan(true);
    (0..20)
        .map(|x| match plans.pixel(x, 2) {
            Some(PixelReuse::Radiance(v)) => Some(v),
            _ => None,
        })
        .collect()
}

/// `plane_grid` with the same values in every row.
fn plane_row(value: impl Fn(usize) -> Vec3, bound: impl Fn(usize) -> f32) -> Vec<Option<Vec3>> {
    plane_grid(|x, _| value(x), bound)
}

/// The pixels of a row that take no radiance.
fn refused(row: &[Option<Vec3>]) -> Vec<usize> {
    (0..row.len()).filter(|&x| row[x].is_none()).collect()
}

#[test]
fn a_smooth_gradient_of_planes_takes_the_radiance_a_flat_rule_would_refuse() {
    // 0.05 a pixel: neighbours differ by more than the bound, but the row is a line.
    let ramp = |x: usize| Vec3::splat(0.1 + 0.05 * x as f32);
    let row = plane_row(ramp, |_| 0.005);
    for (x, v) in row.iter().enumerate() {
        assert!(
            v.is_some_and(|v| (v - ramp(x)).abs().max_element() < 1e-6),
            "{x}: {v:?}"
        );
    }
    // The planes' own bound counts in full.
    assert!(plane_row(ramp, |_| 0.03).iter().all(Option::is_none));
}

#[test]
fn a_pixel_is_judged_on_its_side_of_an_edge() {
    // An edge inside pixel 10 (its plane's bound is large) refuses it; its neighbours take
    // their radiance from the windows on their own side.
    let flat = |_| Vec3::splat(0.3);
    assert_eq!(
        refused(&plane_row(flat, |x| if x == 10 { 0.1 } else { 0.0 })),
        [10]
    );
}

#[test]
fn a_step_beside_a_pixel_counts_for_the_strip_its_samples_may_not_have_seen() {
    // A step of 0.4 between pixels 9 and 10: a quarter pixel of each side may hide the other
    // colour (0.1 > 0.02), so both refuse; a step of 0.04 (0.01) does not.
    let step = |d: f32| move |x: usize| Vec3::splat(if x < 10 { 0.1 } else { 0.1 + d });
    assert_eq!(refused(&plane_row(step(0.4), |_| 0.0)), [9, 10]);
    assert!(refused(&plane_row(step(0.04), |_| 0.0)).is_empty());
    // The same across rows, on a gradient along them: row 2 under a step at its top edge
    // refuses, and under one a row further away does not.
    let step_at = |row: usize| {
        move |x: usize, y: usize| Vec3::splat(if y < row { 0.5 } else { 0.1 + 0.01 * x as f32 })
    };
    assert_eq!(refused(&plane_grid(step_at(2), |_| 0.0)).len(), 20);
    assert!(refused(&plane_grid(step_at(1), |_| 0.0)).is_empty());
}

#[test]
fn a_pixel_among_planes_and_means_traces() {
    let mut g = Grid::new(20, 5, |_, _| 0.0);
    assert!(matches!(
        g.plan(true).pixel(8, 2),
        Some(PixelReuse::Radiance(_))
    ));
    *g.cell(9, 2) = Cell::default();
    g.cell(9, 2)
        .add_hits(&plane_pixel(2, Vec3::ONE, 0.0), [0.0; 2], 1.0, true);
    let plans = g.plan(true);
    assert!(matches!(plans.pixel(9, 2), Some(PixelReuse::Hits(_))));
    for x in [8, 10] {
        assert!(
            matches!(plans.pixel(x, 2), Some(PixelReuse::Radiance(_))),
            "{x}"
        );
    }
}

#[test]
fn a_window_of_misses_is_the_background() {
    let mut g = Grid::new(20, 5, |_, _| 0.0);
    for c in &mut g.cells {
        *c = Cell::default();
        c.add_miss(0.0);
    }
    assert!(matches!(g.plan(false).pixel(8, 2), Some(PixelReuse::Miss)));
}

#[test]
fn a_source_pixel_lands_on_the_cells_its_span_overlaps_weighted_by_the_overlap() {
    // Two source pixels at inverse depth 1 that move 0.25 px (a = 0, b = 0.25): pixel 3 lands
    // on cells 3 (0.75 of it) and 4 (0.25).
    let mut a = hit_pixel(7);
    a.radiance = Vec3::splat(0.4);
    let landing = Landing {
        a: 0.0,
        b: 0.25,
        misses: true,
        baseline: Some(0.0),
        unseen: UNSEEN,
    };
    let mut row = vec![Cell::default(); 8];
    let land = |x: f32, p: &SourcePixel, row: &mut [Cell]| {
        let q = landing.a + landing.b * p.inv_depth[0];
        band::splat(row, x + q, x + 1.0 + q, |c, w| {
            c.add_hits(p, [q, q], w, true)
        });
    };
    land(3.0, &a, &mut row);
    land(4.0, &hit_pixel(8), &mut row);
    assert!((row[3].weight - 0.75).abs() < 1e-6 && (row[4].weight - 1.0).abs() < 1e-6);
    assert!((row[4].radiance.x - (0.25 * 0.4 + 0.75)).abs() < 1e-6);
    assert_eq!(&row[4].prims[..row[4].distinct as usize], &[7, 8]);
    assert!(!row[2].covered() && row[5].covered() && !row[6].covered());
}

#[test]
fn films_narrower_or_lower_than_a_window_plan_every_pixel() {
    // The film's border cuts the windows to what is left of them: a flat surface reuses
    // everywhere, with or without radiance, however small the film.
    for (w, h) in [(1, 1), (2, 1), (1, 2), (3, 1), (2, 3), (4, 2)] {
        let g = Grid::new(w, h, |_, _| 0.0);
        for radiance in [false, true] {
            let plans = g.plan(radiance);
            for y in 0..h {
                for x in 0..w {
                    assert!(
                        plans.pixel(x, y).is_some(),
                        "{w}x{h} at ({x}, {y}), {radiance}"
                    );
                }
            }
        }
    }
}
