//! The reuse rules on grids filled by hand, without cameras.

use super::*;

#[test]
fn the_edge_strip_sits_on_the_side_near_points_move_to() {
    assert_eq!(edge_strips(-3.2, 100), (0, 96));
    assert_eq!(edge_strips(2.0, 100), (2, 100));
    assert_eq!(edge_strips(0.0, 100), (0, 100));
    assert_eq!(edge_strips(-500.0, 100), (0, 0));
    assert_eq!(edge_strips(f32::NAN, 100), (0, 0));
}

/// A grid filled directly (no cameras): one sample per pixel at parallax `parallax(x)`.
fn grid(width: usize, height: usize, parallax: impl Fn(usize, usize) -> f32) -> Reprojection {
    let mut cells = vec![Cell::default(); width * height];
    for y in 0..height {
        for x in 0..width {
            let s = SourceSample {
                film: Vec2::ZERO,
                point: Vec3::ZERO,
                prim: (x / 4) as u32,
                lit: 1,
                shadowed: 0,
                lobe: 1.0,
                radiance: Vec3::ONE,
            };
            cells[y * width + x].add(&s, parallax(x, y), true);
        }
    }
    Reprojection {
        width,
        height,
        band_rows: height,
        bands: vec![Band {
            rows: row_windows(&cells, width, false),
            cells,
        }],
        x_lo: 0,
        x_hi: width,
    }
}

impl Reprojection {
    fn cell(&mut self, x: usize, y: usize) -> &mut Cell {
        &mut self.bands[0].cells[y * self.width + x]
    }

    /// Rules 1 and 2 again after cells changed.
    fn refresh(&mut self, radiance: bool) {
        let band = &mut self.bands[0];
        band.rows = row_windows(&band.cells, self.width, radiance);
    }
}

#[test]
fn a_step_in_parallax_refuses_reuse_around_it_and_only_there() {
    let g = grid(20, 5, |x, _| if x < 10 { 0.0 } else { -3.0 });
    for x in 2..18 {
        let near_step = (8..=11).contains(&x);
        assert_eq!(g.pixel(x, 2).is_none(), near_step, "x={x}");
    }
    // The frame border is traced.
    assert!(g.pixel(1, 2).is_none() && g.pixel(5, 0).is_none() && g.pixel(5, 4).is_none());
}

#[test]
fn a_parallax_that_changes_from_row_to_row_still_reuses() {
    // A receding floor: one pixel more parallax per row, constant along each row.
    let g = grid(20, 6, |_, y| y as f32);
    assert!((1..5).all(|y| g.pixel(8, y).is_some()));
    // Along a row the same change is a step.
    let g = grid(20, 6, |x, _| x as f32);
    assert!(g.pixel(8, 2).is_none());
}

#[test]
fn an_uncovered_pixel_refuses_its_window() {
    let mut g = grid(20, 5, |_, _| 0.0);
    for x in 9..=11 {
        *g.cell(x, 2) = Cell::default();
    }
    g.refresh(false);
    assert!(g.pixel(8, 2).is_none() && g.pixel(12, 1).is_none());
    assert!(g.pixel(7, 2).is_some() && g.pixel(13, 2).is_some());
}

#[test]
fn candidates_come_from_the_neighbouring_pixels_and_shadow_answers_must_agree() {
    let hits = |g: &Reprojection| match g.pixel(8, 2) {
        Some(PixelReuse::Hits(h)) => h,
        _ => panic!("a flat window reuses hits"),
    };
    let mut g = grid(20, 5, |_, _| 0.0);
    let r = hits(&g);
    // Pixels 7..=9 saw triangles 1 and 2 (x / 4).
    assert_eq!(r.candidates.as_slice(), &[1, 2]);
    assert_eq!((r.lit, r.shadowed), (1, 0));
    g.cell(10, 3).shadowed = 1;
    g.refresh(false);
    let r = hits(&g);
    assert_eq!((r.lit, r.shadowed), (0, 0), "a disagreeing light is traced");
}

#[test]
fn a_flat_rough_pixel_takes_its_samples_mean_radiance_and_an_edge_does_not() {
    let mut g = grid(20, 5, |_, _| 0.0);
    g.refresh(true);
    assert!(matches!(g.pixel(8, 2), Some(PixelReuse::Radiance(v)) if v == Vec3::ONE));
    // A neighbour in the row that differs by more than the spread: the pixel traces its
    // own samples on the reused hits.
    g.cell(9, 2).radiance_max = Vec3::splat(1.5);
    g.refresh(true);
    assert!(matches!(g.pixel(8, 2), Some(PixelReuse::Hits(_))));
}

#[test]
fn a_window_of_misses_is_the_background() {
    let mut g = grid(20, 5, |_, _| 0.0);
    for c in &mut g.bands[0].cells {
        *c = Cell::default();
        let miss = SourceSample {
            film: Vec2::ZERO,
            point: Vec3::Z,
            prim: MISS,
            lit: 0,
            shadowed: 0,
            lobe: -1.0,
            radiance: Vec3::ZERO,
        };
        c.add(&miss, 0.0, false);
    }
    g.refresh(false);
    assert!(matches!(g.pixel(8, 2), Some(PixelReuse::Miss)));
}
