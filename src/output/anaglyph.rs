//! Anaglyphs: each method is a 3x6 matrix `[M_L | M_R]` (rows: output R, G, B; columns: the left
//! eye's R, G, B, then the right eye's), applied either in linear light as Dubois designed his
//! projections (each eye's term clipped to [0, 1], summed, clipped, sRGB-encoded) or to 8-bit sRGB
//! values as FFmpeg's `stereo3d` filter does. Sources of every matrix are cited at its definition.

use super::color::{Display, linear_to_srgb, quantize, srgb_to_linear};
use super::image::Image;
use serde::Deserialize;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    RedCyan,
    Gray,
    Color,
    HalfColor,
    Optimized,
    DuboisRedCyan,
    DuboisGreenMagenta,
    DuboisAmberBlue,
    YellowBlue,
    GreenMagenta,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Space {
    /// Matrices on linear radiance, each eye's term clipped (Dubois).
    #[default]
    Linear,
    /// Matrices on 8-bit sRGB values (FFmpeg's stereo3d).
    Display,
}

/// `[row][col]`: rows are output R, G, B; columns L.R, L.G, L.B, R.R, R.G, R.B.
pub type Matrix = [[f32; 6]; 3];

/// ITU-R BT.601 luma weights, as FFmpeg's gray and half-colour tables use (19595, 38470, 7471 / 65536).
const LUMA: [f32; 3] = [0.299, 0.587, 0.114];

impl Method {
    pub fn matrix(self) -> Matrix {
        let [y0, y1, y2] = LUMA;
        match self {
            // Blender's red-cyan: red from the left eye, green and blue from the right; FFmpeg's
            // `arcc` ("colour") is the same matrix, so `red-cyan` and `color` coincide.
            Method::RedCyan | Method::Color => [
                [1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                [0.0, 0.0, 0.0, 0.0, 1.0, 0.0],
                [0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
            ],
            // Black-and-white: luminance of the left eye in red, of the right eye in green and blue
            // (FFmpeg `arcg`).
            Method::Gray => [
                [y0, y1, y2, 0.0, 0.0, 0.0],
                [0.0, 0.0, 0.0, y0, y1, y2],
                [0.0, 0.0, 0.0, y0, y1, y2],
            ],
            // Left luminance in red, right colour in green and blue (FFmpeg `arch`).
            Method::HalfColor => [
                [y0, y1, y2, 0.0, 0.0, 0.0],
                [0.0, 0.0, 0.0, 0.0, 1.0, 0.0],
                [0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
            ],
            // Wimmer's optimized anaglyph (3dtv.at comparison; AForge.NET): the left red channel is
            // rebuilt from the left green and blue, R = 0.7 G + 0.3 B, to reduce retinal rivalry.
            Method::Optimized => [
                [0.0, 0.7, 0.3, 0.0, 0.0, 0.0],
                [0.0, 0.0, 0.0, 0.0, 1.0, 0.0],
                [0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
            ],
            // Dubois red-cyan, the newer least-squares set used by FFmpeg `arcd`, Geeqie, three.js.
            Method::DuboisRedCyan => [
                [
                    0.4561,
                    0.500484,
                    0.176381,
                    -0.0434706,
                    -0.0879388,
                    -0.00155529,
                ],
                [
                    -0.0400822, -0.0378246, -0.0157589, 0.378476, 0.73364, -0.0184503,
                ],
                [
                    -0.0152161,
                    -0.0205971,
                    -0.00546856,
                    -0.0721527,
                    -0.112961,
                    1.2264,
                ],
            ],
            // Dubois green-magenta (Bino; FFmpeg `agmd`).
            Method::DuboisGreenMagenta => [
                [-0.062, -0.158, -0.039, 0.529, 0.705, 0.024],
                [0.284, 0.668, 0.143, -0.016, -0.015, -0.065],
                [-0.015, -0.027, 0.021, 0.009, 0.075, 0.937],
            ],
            // Dubois amber-blue (Bino; FFmpeg `aybd`): the left eye in amber.
            Method::DuboisAmberBlue => [
                [1.062, -0.205, 0.299, -0.016, -0.123, -0.017],
                [-0.026, 0.908, 0.068, 0.006, 0.062, -0.017],
                [-0.038, -0.173, 0.022, 0.094, 0.185, 0.911],
            ],
            // Blender's yellow-blue: red and green from the left eye, blue from the right.
            // (FFmpeg's `aybc` puts the right eye in yellow instead.)
            Method::YellowBlue => [
                [1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                [0.0, 1.0, 0.0, 0.0, 0.0, 0.0],
                [0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
            ],
            // Blender's green-magenta: green from the left eye, red and blue from the right
            // (FFmpeg `agmc`).
            Method::GreenMagenta => [
                [0.0, 0.0, 0.0, 1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0, 0.0, 0.0, 0.0],
                [0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
            ],
        }
    }
}

/// One output pixel from display-referred (or linear) left and right values, each eye's term
/// clipped to [0, 1] when `clip_terms` (Dubois), the sum always clipped.
#[inline]
fn apply(m: &Matrix, l: [f32; 3], r: [f32; 3], clip_terms: bool) -> [f32; 3] {
    std::array::from_fn(|row| {
        let tl: f32 = (0..3).map(|c| m[row][c] * l[c]).sum();
        let tr: f32 = (0..3).map(|c| m[row][c + 3] * r[c]).sum();
        let (tl, tr) = if clip_terms {
            (tl.clamp(0.0, 1.0), tr.clamp(0.0, 1.0))
        } else {
            (tl, tr)
        };
        (tl + tr).clamp(0.0, 1.0)
    })
}

/// The anaglyph of a stereo pair as 8-bit sRGB RGB bytes.
pub fn anaglyph(
    left: &Image,
    right: &Image,
    method: Method,
    swap: bool,
    space: Space,
    display: &Display,
) -> Vec<u8> {
    let (left, right) = if swap { (right, left) } else { (left, right) };
    let m = method.matrix();
    let mut out = Vec::with_capacity(left.pixels.len() * 3);
    for (pl, pr) in left.pixels.iter().zip(&right.pixels) {
        let (l, r) = (display.map_linear(*pl), display.map_linear(*pr));
        let px = match space {
            Space::Linear => {
                apply(&m, l.into(), r.into(), true).map(|v| quantize(linear_to_srgb(v)))
            }
            Space::Display => {
                // The 8-bit values an sRGB image would hold, then the matrix on them.
                let enc = |v: glam::Vec3| {
                    v.to_array()
                        .map(|c| quantize(linear_to_srgb(c)) as f32 / 255.0)
                };
                apply(&m, enc(l), enc(r), false).map(quantize)
            }
        };
        out.extend(px);
    }
    out
}

/// The display-space anaglyph of two 8-bit sRGB images (what FFmpeg computes), for tests and
/// for inputs that are already encoded.
pub fn anaglyph_srgb8(left: &[u8], right: &[u8], method: Method) -> Vec<u8> {
    let m = method.matrix();
    left.chunks_exact(3)
        .zip(right.chunks_exact(3))
        .flat_map(|(l, r)| {
            let f = |p: &[u8]| {
                [
                    p[0] as f32 / 255.0,
                    p[1] as f32 / 255.0,
                    p[2] as f32 / 255.0,
                ]
            };
            apply(&m, f(l), f(r), false).map(quantize)
        })
        .collect()
}

/// Linear value of an 8-bit sRGB code (for building test inputs).
pub fn srgb8_to_linear(c: u8) -> f32 {
    srgb_to_linear(c as f32 / 255.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn pair(l: Vec3, r: Vec3) -> (Image, Image) {
        let mut a = Image::new(1, 1);
        let mut b = Image::new(1, 1);
        a.set(0, 0, l);
        b.set(0, 0, r);
        (a, b)
    }

    fn ana(method: Method, l: Vec3, r: Vec3, space: Space, swap: bool) -> [u8; 3] {
        let (a, b) = pair(l, r);
        let v = anaglyph(&a, &b, method, swap, space, &Display::default());
        [v[0], v[1], v[2]]
    }

    #[test]
    fn channel_selection_methods_route_primaries_to_the_right_channels() {
        let (red, white, black) = (Vec3::X, Vec3::ONE, Vec3::ZERO);
        // Left white, right black: only the left eye's channels light up.
        assert_eq!(
            ana(Method::RedCyan, white, black, Space::Linear, false),
            [255, 0, 0]
        );
        assert_eq!(
            ana(Method::RedCyan, black, white, Space::Linear, false),
            [0, 255, 255]
        );
        assert_eq!(
            ana(Method::YellowBlue, white, black, Space::Linear, false),
            [255, 255, 0]
        );
        assert_eq!(
            ana(Method::GreenMagenta, white, black, Space::Linear, false),
            [0, 255, 0]
        );
        assert_eq!(
            ana(Method::GreenMagenta, black, white, Space::Linear, false),
            [255, 0, 255]
        );
        // Swap exchanges the eyes.
        assert_eq!(
            ana(Method::RedCyan, white, black, Space::Linear, true),
            [0, 255, 255]
        );
        // Optimized drops the left red: a pure red left eye gives no red.
        assert_eq!(
            ana(Method::Optimized, red, black, Space::Linear, false),
            [0, 0, 0]
        );
    }

    #[test]
    fn gray_and_half_color_use_bt601_luma() {
        // Mid-gray in display space: code 128 everywhere gives luma 128.
        let g = Vec3::splat(srgb8_to_linear(128));
        assert_eq!(
            ana(Method::Gray, g, g, Space::Display, false),
            [128, 128, 128]
        );
        // Pure green left eye in display space: 0.587 * 255 = 149.7.
        assert_eq!(
            ana(Method::Gray, Vec3::Y, Vec3::ZERO, Space::Display, false),
            [150, 0, 0]
        );
        assert_eq!(
            ana(Method::HalfColor, Vec3::Y, Vec3::Z, Space::Display, false),
            [150, 0, 255]
        );
    }

    /// Each method written out as scalar formulas from its published definition, independent of
    /// the matrix table: (r, g, b) of the display-space result for display-space inputs.
    fn scalar(method: Method, l: [f32; 3], r: [f32; 3]) -> [f32; 3] {
        let luma = |p: [f32; 3]| 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2];
        match method {
            Method::RedCyan | Method::Color => [l[0], r[1], r[2]],
            Method::Gray => [luma(l), luma(r), luma(r)],
            Method::HalfColor => [luma(l), r[1], r[2]],
            Method::Optimized => [0.7 * l[1] + 0.3 * l[2], r[1], r[2]],
            Method::YellowBlue => [l[0], l[1], r[2]],
            Method::GreenMagenta => [r[0], l[1], r[2]],
            Method::DuboisRedCyan => [
                0.4561 * l[0] + 0.500484 * l[1] + 0.176381 * l[2]
                    - 0.0434706 * r[0]
                    - 0.0879388 * r[1]
                    - 0.00155529 * r[2],
                -0.0400822 * l[0] - 0.0378246 * l[1] - 0.0157589 * l[2]
                    + 0.378476 * r[0]
                    + 0.73364 * r[1]
                    - 0.0184503 * r[2],
                -0.0152161 * l[0]
                    - 0.0205971 * l[1]
                    - 0.00546856 * l[2]
                    - 0.0721527 * r[0]
                    - 0.112961 * r[1]
                    + 1.2264 * r[2],
            ],
            Method::DuboisGreenMagenta => [
                -0.062 * l[0] - 0.158 * l[1] - 0.039 * l[2]
                    + 0.529 * r[0]
                    + 0.705 * r[1]
                    + 0.024 * r[2],
                0.284 * l[0] + 0.668 * l[1] + 0.143 * l[2]
                    - 0.016 * r[0]
                    - 0.015 * r[1]
                    - 0.065 * r[2],
                -0.015 * l[0] - 0.027 * l[1]
                    + 0.021 * l[2]
                    + 0.009 * r[0]
                    + 0.075 * r[1]
                    + 0.937 * r[2],
            ],
            Method::DuboisAmberBlue => [
                1.062 * l[0] - 0.205 * l[1] + 0.299 * l[2]
                    - 0.016 * r[0]
                    - 0.123 * r[1]
                    - 0.017 * r[2],
                -0.026 * l[0] + 0.908 * l[1] + 0.068 * l[2] + 0.006 * r[0] + 0.062 * r[1]
                    - 0.017 * r[2],
                -0.038 * l[0] - 0.173 * l[1]
                    + 0.022 * l[2]
                    + 0.094 * r[0]
                    + 0.185 * r[1]
                    + 0.911 * r[2],
            ],
        }
    }

    #[test]
    fn every_method_equals_its_scalar_formula_on_primaries_and_grays() {
        let codes: [[u8; 3]; 8] = [
            [0, 0, 0],
            [255, 255, 255],
            [255, 0, 0],
            [0, 255, 0],
            [0, 0, 255],
            [128, 128, 128],
            [64, 64, 64],
            [200, 100, 50],
        ];
        let methods = [
            Method::RedCyan,
            Method::Gray,
            Method::Color,
            Method::HalfColor,
            Method::Optimized,
            Method::DuboisRedCyan,
            Method::DuboisGreenMagenta,
            Method::DuboisAmberBlue,
            Method::YellowBlue,
            Method::GreenMagenta,
        ];
        let left: Vec<u8> = codes
            .iter()
            .flat_map(|a| codes.iter().flat_map(move |_| *a))
            .collect();
        let right: Vec<u8> = codes
            .iter()
            .flat_map(|_| codes.iter().flat_map(|b| *b))
            .collect();
        for method in methods {
            let got = anaglyph_srgb8(&left, &right, method);
            for (i, px) in got.chunks_exact(3).enumerate() {
                let f = |c: &[u8]| {
                    [
                        c[0] as f32 / 255.0,
                        c[1] as f32 / 255.0,
                        c[2] as f32 / 255.0,
                    ]
                };
                let want = scalar(
                    method,
                    f(&left[3 * i..3 * i + 3]),
                    f(&right[3 * i..3 * i + 3]),
                )
                .map(|v| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8);
                assert_eq!(px, want, "{method:?} pixel {i}");
            }
        }
    }

    #[test]
    fn dubois_matches_a_scalar_evaluation_of_the_published_matrix() {
        let (l, r) = (Vec3::new(0.2, 0.5, 0.8), Vec3::new(0.6, 0.1, 0.3));
        for method in [
            Method::DuboisRedCyan,
            Method::DuboisGreenMagenta,
            Method::DuboisAmberBlue,
        ] {
            let m = method.matrix();
            let got = ana(method, l, r, Space::Linear, false);
            for row in 0..3 {
                let tl = (m[row][0] * l.x + m[row][1] * l.y + m[row][2] * l.z).clamp(0.0, 1.0);
                let tr = (m[row][3] * r.x + m[row][4] * r.y + m[row][5] * r.z).clamp(0.0, 1.0);
                let want = quantize(linear_to_srgb((tl + tr).min(1.0)));
                assert_eq!(got[row], want, "{method:?} row {row}");
            }
        }
        // White in both eyes: Dubois red-cyan keeps white near white.
        let w = ana(
            Method::DuboisRedCyan,
            Vec3::ONE,
            Vec3::ONE,
            Space::Linear,
            false,
        );
        assert!(w.iter().all(|&c| c > 200), "{w:?}");
    }
}
