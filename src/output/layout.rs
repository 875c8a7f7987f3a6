//! Frame-compatible stereo layouts for viewers and 3D TVs: side-by-side (parallel or cross-eyed,
//! full or half width), top-bottom (full or half height) and row-interleaved.

use super::image::Image;
use glam::Vec3;
use serde::Deserialize;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Order {
    /// Left eye on the left (or top): parallel viewing.
    #[default]
    Parallel,
    /// Right eye on the left: cross-eyed viewing.
    Cross,
}

/// Halves the width (or height) by averaging pairs of pixels in linear light, as a box filter.
fn squeeze(img: &Image, horizontal: bool) -> Image {
    let (w, h) = if horizontal {
        (img.width.div_ceil(2), img.height)
    } else {
        (img.width, img.height.div_ceil(2))
    };
    let mut out = Image::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let (a, b) = if horizontal {
                (
                    img.get(2 * x, y),
                    img.get((2 * x + 1).min(img.width - 1), y),
                )
            } else {
                (
                    img.get(x, 2 * y),
                    img.get(x, (2 * y + 1).min(img.height - 1)),
                )
            };
            out.set(x, y, (a + b) * 0.5);
        }
    }
    out
}

fn ordered<'a>(left: &'a Image, right: &'a Image, order: Order) -> (&'a Image, &'a Image) {
    match order {
        Order::Parallel => (left, right),
        Order::Cross => (right, left),
    }
}

pub fn side_by_side(left: &Image, right: &Image, order: Order, half: bool) -> Image {
    let (a, b) = ordered(left, right, order);
    let (a, b) = if half {
        (squeeze(a, true), squeeze(b, true))
    } else {
        (a.clone(), b.clone())
    };
    let mut out = Image::new(a.width + b.width, a.height);
    for y in 0..a.height {
        for x in 0..a.width {
            out.set(x, y, a.get(x, y));
        }
        for x in 0..b.width {
            out.set(a.width + x, y, b.get(x, y));
        }
    }
    out
}

pub fn top_bottom(left: &Image, right: &Image, order: Order, half: bool) -> Image {
    let (a, b) = ordered(left, right, order);
    let (a, b) = if half {
        (squeeze(a, false), squeeze(b, false))
    } else {
        (a.clone(), b.clone())
    };
    let mut pixels: Vec<Vec3> = a.pixels.clone();
    pixels.extend_from_slice(&b.pixels);
    Image {
        width: a.width,
        height: a.height + b.height,
        pixels,
    }
}

/// Even rows (0, 2, ...) from the first eye, odd rows from the second, as line-interleaved
/// (passive polarized) displays expect.
pub fn interlaced(left: &Image, right: &Image, order: Order) -> Image {
    let (a, b) = ordered(left, right, order);
    let mut out = a.clone();
    for y in (1..a.height).step_by(2) {
        for x in 0..a.width {
            out.set(x, y, b.get(x, y));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flat(w: usize, h: usize, v: f32) -> Image {
        Image {
            width: w,
            height: h,
            pixels: vec![Vec3::splat(v); w * h],
        }
    }

    #[test]
    fn layouts_place_each_eye_where_viewers_expect_it() {
        let (l, r) = (flat(4, 2, 0.25), flat(4, 2, 0.75));
        let sbs = side_by_side(&l, &r, Order::Parallel, false);
        assert_eq!((sbs.width, sbs.height), (8, 2));
        assert_eq!((sbs.get(0, 0).x, sbs.get(7, 1).x), (0.25, 0.75));
        let cross = side_by_side(&l, &r, Order::Cross, true);
        assert_eq!(
            (cross.width, cross.get(0, 0).x, cross.get(3, 0).x),
            (4, 0.75, 0.25)
        );
        let tb = top_bottom(&l, &r, Order::Parallel, true);
        assert_eq!(
            (tb.width, tb.height, tb.get(0, 0).x, tb.get(0, 1).x),
            (4, 2, 0.25, 0.75)
        );
        let il = interlaced(&l, &r, Order::Parallel);
        assert_eq!((il.get(0, 0).x, il.get(0, 1).x), (0.25, 0.75));
    }

    #[test]
    fn half_width_averages_pixel_pairs_in_linear_light() {
        let mut img = flat(3, 1, 0.0);
        img.set(1, 0, Vec3::ONE);
        let s = squeeze(&img, true);
        assert_eq!(s.width, 2);
        assert_eq!((s.get(0, 0).x, s.get(1, 0).x), (0.5, 0.0));
    }
}
