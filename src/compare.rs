//! Image difference metrics in the spirit of OpenImageIO's `idiff`: per-channel mean absolute
//! error, RMS, maximum (with its pixel), PSNR, and the share of pixels whose largest channel error
//! exceeds a threshold.

use crate::output::image::Image;
use serde::Serialize;

#[derive(Clone, Debug, Serialize)]
pub struct Difference {
    pub width: usize,
    pub height: usize,
    /// Per channel R, G, B.
    pub mean_abs: [f64; 3],
    pub rms: [f64; 3],
    pub max: [f64; 3],
    /// Pixel (x, y) of the largest error over all channels.
    pub max_pixel: (usize, usize),
    /// PSNR over all channels with a peak of 1.0 (linear radiance), in dB.
    pub psnr: f64,
    /// Pixels where any channel differs by more than the threshold, and the threshold.
    pub over_threshold: usize,
    pub threshold: f64,
    /// Pixels where either image is NaN or infinite.
    pub non_finite: usize,
}

impl Difference {
    pub fn mean_abs_all(&self) -> f64 {
        self.mean_abs.iter().sum::<f64>() / 3.0
    }

    pub fn percent_over(&self) -> f64 {
        100.0 * self.over_threshold as f64 / (self.width * self.height).max(1) as f64
    }
}

/// Compares two images of equal size; `None` when the sizes differ.
pub fn difference(a: &Image, b: &Image, threshold: f64) -> Option<Difference> {
    if a.width != b.width || a.height != b.height {
        return None;
    }
    let n = (a.width * a.height).max(1) as f64;
    let mut sum = [0f64; 3];
    let mut sq = [0f64; 3];
    let mut max = [0f64; 3];
    let mut max_all = -1f64;
    let mut max_pixel = (0, 0);
    let mut over = 0;
    let mut non_finite = 0;
    for (i, (pa, pb)) in a.pixels.iter().zip(&b.pixels).enumerate() {
        if !pa.is_finite() || !pb.is_finite() {
            non_finite += 1;
            over += 1;
            continue;
        }
        let mut worst = 0f64;
        for c in 0..3 {
            let d = (pa[c] as f64 - pb[c] as f64).abs();
            sum[c] += d;
            sq[c] += d * d;
            max[c] = max[c].max(d);
            worst = worst.max(d);
        }
        if worst > threshold {
            over += 1;
        }
        if worst > max_all {
            max_all = worst;
            max_pixel = (i % a.width, i / a.width);
        }
    }
    let mse = sq.iter().sum::<f64>() / (3.0 * n);
    Some(Difference {
        width: a.width,
        height: a.height,
        mean_abs: sum.map(|s| s / n),
        rms: sq.map(|s| (s / n).sqrt()),
        max,
        max_pixel,
        psnr: if mse > 0.0 {
            -10.0 * mse.log10()
        } else {
            f64::INFINITY
        },
        over_threshold: over,
        threshold,
        non_finite,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn identical_images_have_no_error_and_infinite_psnr() {
        let a = Image::new(4, 3);
        let d = difference(&a, &a, 0.02).unwrap();
        assert_eq!(d.over_threshold, 0);
        assert!(d.psnr.is_infinite());
    }

    #[test]
    fn one_hot_pixel_is_counted_and_located() {
        let a = Image::new(10, 10);
        let mut b = a.clone();
        b.set(3, 7, Vec3::new(0.0, 0.5, 0.0));
        let d = difference(&a, &b, 0.02).unwrap();
        assert_eq!(d.over_threshold, 1);
        assert_eq!(d.max_pixel, (3, 7));
        assert_eq!(d.max, [0.0, 0.5, 0.0]);
        assert!((d.mean_abs[1] - 0.005).abs() < 1e-12);
        assert!((d.psnr - (-10.0 * (0.25f64 / 300.0).log10())).abs() < 1e-9);
        assert!(difference(&a, &Image::new(9, 10), 0.02).is_none());
    }
}
