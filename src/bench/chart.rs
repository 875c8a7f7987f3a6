//! Speed-against-accuracy charts: one marker per measured combination on log-log axes, coloured
//! by series, with the Pareto front (no other point is both faster and better) drawn as a
//! staircase and its points labelled. Written as SVG and PNG, each atomically. Text uses the
//! embedded DejaVu Sans, so a chart looks the same on a machine without fonts.

use crate::error::{Error, Result};
use crate::output::write_atomic;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

/// One measured combination.
#[derive(Clone, Debug)]
pub struct Point {
    pub label: String,
    pub x: f64,
    pub y: f64,
}

#[derive(Clone, Debug)]
pub struct Series {
    pub name: String,
    pub points: Vec<Point>,
}

impl Series {
    /// Points grouped into series by name, in order of first appearance.
    pub fn group(named: impl IntoIterator<Item = (String, Point)>) -> Vec<Series> {
        let mut series: Vec<Series> = Vec::new();
        for (name, p) in named {
            match series.iter_mut().find(|s| s.name == name) {
                Some(s) => s.points.push(p),
                None => series.push(Series {
                    name,
                    points: vec![p],
                }),
            }
        }
        series
    }
}

/// Which points a Pareto front is taken over.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Front {
    /// One front over all series (the combinations of one sweep).
    Global,
    /// A front per series (per scene, when scenes are not comparable).
    PerSeries,
}

#[derive(Clone, Debug)]
pub struct Chart {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
    pub front: Front,
}

/// Indices of the points on the Pareto front when both coordinates are to be minimized, by
/// increasing x. A point is on the front when no other point is at most as large in both
/// coordinates and smaller in one. Non-finite points are never on it.
pub fn pareto_front(points: &[Point]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..points.len())
        .filter(|&i| points[i].x.is_finite() && points[i].y.is_finite())
        .collect();
    order.sort_by(|&a, &b| {
        (points[a].x, points[a].y)
            .partial_cmp(&(points[b].x, points[b].y))
            .expect("non-finite points were filtered out")
    });
    let mut front: Vec<usize> = Vec::new();
    let mut best_y = f64::INFINITY;
    for i in order {
        // An exact copy of the last front point dominates nothing and is not dominated.
        let copy = front
            .last()
            .is_some_and(|&j| (points[j].x, points[j].y) == (points[i].x, points[i].y));
        if points[i].y < best_y || copy {
            best_y = points[i].y;
            front.push(i);
        }
    }
    front
}

const WIDTH: u32 = 1000;
const HEIGHT: u32 = 640;
const FONT: &str = "sans-serif";

/// Writes `<stem>.svg` and `<stem>.png`.
pub fn write(chart: &Chart, stem: &Path) -> Result<()> {
    static FONT_ONCE: Once = Once::new();
    FONT_ONCE.call_once(|| {
        plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular())
            .unwrap_or_else(|_| unreachable!("the embedded DejaVu Sans is a valid font"));
    });
    let svg_path = stem.with_extension("svg");
    let png_path = stem.with_extension("png");
    let fail = |path: &Path, e: String| Error::input(path, format!("cannot draw the chart: {e}"));

    let mut svg = String::new();
    draw(
        SVGBackend::with_string(&mut svg, (WIDTH, HEIGHT)).into_drawing_area(),
        chart,
    )
    .map_err(|e| fail(&svg_path, e))?;
    write_atomic(&svg_path, |w| std::io::Write::write_all(w, svg.as_bytes()))?;

    let mut rgb = vec![255u8; (WIDTH * HEIGHT * 3) as usize];
    draw(
        BitMapBackend::with_buffer(&mut rgb, (WIDTH, HEIGHT)).into_drawing_area(),
        chart,
    )
    .map_err(|e| fail(&png_path, e))?;
    let img = image::RgbImage::from_raw(WIDTH, HEIGHT, rgb).expect("buffer sized to the chart");
    write_atomic(&png_path, |w| {
        img.write_to(w, image::ImageFormat::Png)
            .map_err(std::io::Error::other)
    })?;
    Ok(())
}

/// Axis range on a log scale around the finite positive values, padded by a fraction of a decade.
fn log_range(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (lo, hi) = values
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if lo > hi {
        return 0.1..10.0;
    }
    let pad = (hi / lo).powf(0.08).max(1.15);
    lo / pad..hi * pad
}

/// Tick values 1, 2 and 5 times powers of ten inside the range (at least its two ends when it
/// holds fewer than two of them), so that a log axis spanning less than a decade is labelled too.
fn log_ticks(r: &std::ops::Range<f64>) -> Vec<f64> {
    let mut ticks = Vec::new();
    let mut decade = 10f64.powf(r.start.log10().floor());
    // Many decades get a tick per decade; a few get 1, 2, 5 in each.
    let multiples: &[f64] = if (r.end / r.start).log10() > 3.0 {
        &[1.0]
    } else {
        &[1.0, 2.0, 5.0]
    };
    while decade <= r.end {
        for &m in multiples {
            let v = m * decade;
            if r.contains(&v) {
                ticks.push(v);
            }
        }
        decade *= 10.0;
    }
    if ticks.len() < 2 {
        let mid = (r.start * r.end).sqrt();
        ticks = vec![r.start * 1.05, mid, r.end / 1.05];
    }
    ticks
}

/// A number with three significant digits, without trailing zeros.
fn tick_label(v: &f64) -> String {
    if *v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    if v.abs() < 1e-3 || v.abs() >= 1e5 {
        // Three significant digits in scientific notation, trailing zeros dropped: 2e-5.
        let s = format!("{v:.2e}");
        let (mantissa, exponent) = s.split_once('e').expect("{:e} output has an exponent");
        let mantissa = mantissa.trim_end_matches('0').trim_end_matches('.');
        return format!("{mantissa}e{exponent}");
    }
    let digits = (2 - v.abs().log10().floor() as i32).max(0) as usize;
    let s = format!("{v:.digits$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

const LEGEND_WIDTH: u32 = 240;

fn draw<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, chart: &Chart) -> Result<(), String> {
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(err)?;
    let root = root.titled(&chart.title, (FONT, 22)).map_err(err)?;
    let (plot, legend) = root.split_horizontally(WIDTH - LEGEND_WIDTH);
    let all = || chart.series.iter().flat_map(|s| s.points.iter());
    let (xr, yr) = (log_range(all().map(|p| p.x)), log_range(all().map(|p| p.y)));
    let mut ctx = ChartBuilder::on(&plot)
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(80)
        .build_cartesian_2d(
            xr.clone().log_scale().with_key_points(log_ticks(&xr)),
            yr.clone().log_scale().with_key_points(log_ticks(&yr)),
        )
        .map_err(err)?;
    ctx.configure_mesh()
        .x_desc(&chart.x_label)
        .y_desc(&chart.y_label)
        .x_label_formatter(&tick_label)
        .y_label_formatter(&tick_label)
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(err)?;

    // A zero (an exact match) has no place on a log axis: it sits on the axis floor.
    let floor = |p: &Point| (p.x.max(xr.start), p.y.max(yr.start));
    let color = |k: usize| Palette99::pick(k).to_rgba();
    for (k, s) in chart.series.iter().enumerate() {
        let finite = s
            .points
            .iter()
            .filter(|p| p.x.is_finite() && p.y.is_finite());
        ctx.draw_series(finite.map(|p| Circle::new(floor(p), 5, color(k).filled())))
            .map_err(err)?;
    }

    let fronts: Vec<Vec<Point>> = match chart.front {
        Front::Global => {
            let pts: Vec<Point> = all().cloned().collect();
            vec![
                pareto_front(&pts)
                    .into_iter()
                    .map(|i| pts[i].clone())
                    .collect(),
            ]
        }
        Front::PerSeries => chart
            .series
            .iter()
            .map(|s| {
                pareto_front(&s.points)
                    .into_iter()
                    .map(|i| s.points[i].clone())
                    .collect()
            })
            .collect(),
    };
    for front in &fronts {
        let mut steps = Vec::new();
        for (i, p) in front.iter().enumerate() {
            let (x, y) = floor(p);
            if i > 0 {
                steps.push((x, floor(&front[i - 1]).1));
            }
            steps.push((x, y));
        }
        ctx.draw_series(LineSeries::new(steps, BLACK.stroke_width(2)))
            .map_err(err)?;
        ctx.draw_series(front.iter().map(|p| {
            EmptyElement::at(floor(p))
                + Circle::new((0, 0), 8, BLACK.stroke_width(1))
                + Text::new(p.label.clone(), (8, -16), (FONT, 13))
        }))
        .map_err(err)?;
    }

    // The legend beside the plot, where it can hide no point.
    let row = |i: usize| 40 + 22 * i as i32;
    for (k, s) in chart.series.iter().enumerate() {
        legend
            .draw(&Circle::new((16, row(k)), 5, color(k).filled()))
            .map_err(err)?;
        legend
            .draw(&Text::new(s.name.clone(), (30, row(k) - 8), (FONT, 14)))
            .map_err(err)?;
    }
    let y = row(chart.series.len());
    legend
        .draw(&PathElement::new(
            vec![(6, y), (26, y)],
            BLACK.stroke_width(2),
        ))
        .map_err(err)?;
    legend
        .draw(&Text::new("Pareto front", (30, y - 8), (FONT, 14)))
        .map_err(err)?;
    root.present().map_err(err)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pt(x: f64, y: f64) -> Point {
        Point {
            label: format!("{x},{y}"),
            x,
            y,
        }
    }

    #[test]
    fn pareto_front_keeps_exactly_the_undominated_points() {
        let pts = vec![
            pt(1.0, 5.0),
            pt(2.0, 3.0),
            pt(2.5, 4.0), // dominated by (2, 3)
            pt(3.0, 1.0),
            pt(4.0, 1.0), // as good in y, slower
            pt(0.5, f64::NAN),
            pt(1.0, 6.0), // dominated by (1, 5)
            pt(2.0, 3.0), // a copy of (2, 3): neither dominates the other
        ];
        assert_eq!(pareto_front(&pts), vec![0, 1, 7, 3]);
        // The oracle: a point is on the front iff nothing dominates it.
        for (i, p) in pts.iter().enumerate() {
            let dominated = pts
                .iter()
                .any(|q| q.x <= p.x && q.y <= p.y && (q.x < p.x || q.y < p.y));
            let on = pareto_front(&pts).contains(&i);
            assert_eq!(on, !dominated && p.y.is_finite(), "point {i}");
        }
    }

    #[test]
    fn tick_labels_keep_three_significant_digits() {
        assert_eq!(tick_label(&2e-5), "2e-5");
        assert_eq!(tick_label(&0.0015), "0.0015");
        assert_eq!(tick_label(&0.5), "0.5");
        assert_eq!(tick_label(&123.456), "123");
        assert_eq!(tick_label(&1.5e6), "1.5e6");
    }

    #[test]
    fn charts_are_written_as_svg_and_png() {
        let dir = std::env::temp_dir().join(format!("stereotrace-chart-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let chart = Chart {
            title: "t".into(),
            x_label: "x".into(),
            y_label: "y".into(),
            series: vec![Series {
                name: "s".into(),
                points: vec![pt(1.0, 2.0), pt(2.0, 1.0), pt(3.0, 3.0)],
            }],
            front: Front::Global,
        };
        write(&chart, &dir.join("c")).unwrap();
        let svg = std::fs::read_to_string(dir.join("c.svg")).unwrap();
        assert!(svg.contains("<svg") && svg.contains("Pareto front"));
        // The axes are labelled although the data spans less than a decade.
        assert!(
            svg.lines().any(|l| l.trim() == "2"),
            "no tick label 2 in the SVG"
        );
        let png = image::open(dir.join("c.png")).unwrap();
        assert_eq!((png.width(), png.height()), (WIDTH, HEIGHT));
        // Something other than the white background was drawn.
        assert!(png.to_rgb8().pixels().any(|p| p.0 != [255, 255, 255]));
        std::fs::remove_dir_all(dir).unwrap();
    }
}
