//! `"reproject-radiance"`: a source pixel's radiance as a plane over the film. Its hit samples'
//! radiance is fitted by least squares to `c + gx u + gy v` (u, v: the sample's offset from the
//! pixel's centre, pixels), which gives the value at the centre, free of where the samples
//! happened to fall, and a bound on how far a target pixel's own samples may lie from the plane:
//! the fit's largest residual, plus the gradient times how far a pixel's sample positions may
//! be centred off the pixel's centre (`sampling::centroid_bound`).

use super::super::sampling::centroid_bound;
use glam::Vec3;

/// Samples a plane needs before its residual tests it: three fix its three unknowns, a
/// fourth is the first that can disagree with it.
pub const PLANE_SAMPLES: usize = 4;

/// A hit sample's place in its pixel (0..1 on each axis) and its radiance.
#[derive(Clone, Copy, Debug, Default)]
pub struct ShadedSample {
    pub x: f32,
    pub y: f32,
    pub radiance: Vec3,
}

/// What a pixel's samples say of its radiance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelRadiance {
    /// The plane's value at the pixel's centre, or the samples' mean where there is no plane.
    pub value: Vec3,
    /// With a plane: the largest distance, in any channel, between the mean of a pixel's
    /// samples (at `spp` samples a pixel) anywhere on the plane's patch and the plane's value at
    /// that pixel's centre. Without one: the largest distance of a sample from the mean.
    pub bound: f32,
    pub plane: bool,
}

/// Fits `samples` (at least one), taken `spp` to a pixel.
pub fn fit(samples: &[ShadedSample], spp: usize) -> PixelRadiance {
    // One pass for the moments (about the pixel's centre, where the values are small), one for
    // the residual: the fit runs for every pixel of the source view.
    let n = samples.len() as f32;
    let (mut su, mut sv, mut suu, mut suv, mut svv) = (0.0f32, 0.0f32, 0.0f32, 0.0f32, 0.0f32);
    let (mut sl, mut sul, mut svl) = (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
    for s in samples {
        let (u, v) = (s.x - 0.5, s.y - 0.5);
        (su, sv) = (su + u, sv + v);
        (suu, suv, svv) = (suu + u * u, suv + u * v, svv + v * v);
        sl += s.radiance;
        sul += u * s.radiance;
        svl += v * s.radiance;
    }
    let mean = sl / n;
    if samples.len() < PLANE_SAMPLES {
        return flat(samples, mean);
    }
    // The normal equations of [1, u, v] about the samples' centroid, where the constant
    // decouples and leaves a 2x2 system for the gradient.
    let (cu, cv) = (su / n, sv / n);
    let (suu, suv, svv) = (suu - su * cu, suv - su * cv, svv - sv * cv);
    let (sul, svl) = (sul - cu * sl, svl - cv * sl);
    let det = suu * svv - suv * suv;
    // Samples on one line (or all at one place) leave the gradient across it unknown.
    if det.is_nan() || det <= 1e-6 * suu.max(svv).powi(2) {
        return flat(samples, mean);
    }
    let gx = (sul * svv - svl * suv) / det;
    let gy = (svl * suu - sul * suv) / det;
    // The plane's value at the pixel's centre (u = v = 0).
    let centre = mean - gx * cu - gy * cv;
    let residual = samples
        .iter()
        .map(|s| {
            let plane = centre + gx * (s.x - 0.5) + gy * (s.y - 0.5);
            (s.radiance - plane).abs().max_element()
        })
        .fold(0.0, f32::max);
    let slope = (gx.abs() + gy.abs()).max_element();
    checked(centre, residual + slope * centroid_bound(spp), true)
}

/// The samples' mean, and how far the farthest lies from it.
fn flat(samples: &[ShadedSample], mean: Vec3) -> PixelRadiance {
    let spread = samples
        .iter()
        .map(|s| (s.radiance - mean).abs().max_element())
        .fold(0.0, f32::max);
    checked(mean, spread, false)
}

/// A value that is not finite (a NaN or infinite sample) gets an infinite bound: no rule takes
/// it. (`f32::max` skips NaN, so the bound alone would not show one.)
fn checked(value: Vec3, bound: f32, plane: bool) -> PixelRadiance {
    let bound = if value.is_finite() && !bound.is_nan() {
        bound
    } else {
        f32::INFINITY
    };
    PixelRadiance {
        value,
        bound,
        plane,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::sampling::pixel_sample;

    fn samples(spp: u32, radiance: impl Fn(f32, f32) -> Vec3) -> Vec<ShadedSample> {
        (0..spp)
            .map(|s| {
                let p = pixel_sample(s, spp, [7, 1, 2]);
                ShadedSample {
                    x: p.x,
                    y: p.y,
                    radiance: radiance(p.x, p.y),
                }
            })
            .collect()
    }

    #[test]
    fn a_linear_patch_gives_its_centre_value_and_only_the_sampling_term() {
        let f = |x: f32, y: f32| Vec3::new(0.2 + 0.1 * x, 0.5 - 0.04 * y, 0.3);
        let p = fit(&samples(16, f), 16);
        assert!(p.plane);
        assert!((p.value - f(0.5, 0.5)).abs().max_element() < 1e-5, "{p:?}");
        // The steepest channel, red, rises 0.1 a pixel, times 1/8 px, the most a 4x4 grid's
        // mean can sit off the centre.
        let sampling = 0.1 * 0.125;
        assert!((p.bound - sampling).abs() < 1e-4, "{p:?}");
    }

    #[test]
    fn a_step_inside_the_pixel_leaves_a_residual_the_flat_mean_would_not_show() {
        let step = |x: f32, _| Vec3::splat(if x < 0.4 { 0.0 } else { 0.1 });
        let p = fit(&samples(16, step), 16);
        assert!(p.plane && p.bound > 0.02, "{p:?}");
    }

    #[test]
    fn too_few_samples_or_samples_on_a_line_keep_the_mean_and_its_spread() {
        let two = [0.1, 0.3].map(|r| ShadedSample {
            x: r,
            y: r,
            radiance: Vec3::splat(r),
        });
        let p = fit(&two, 2);
        assert!(!p.plane && p.value == Vec3::splat(0.2) && (p.bound - 0.1).abs() < 1e-6);
        let line: Vec<ShadedSample> = (0..5)
            .map(|k| ShadedSample {
                x: 0.1 * k as f32,
                y: 0.5,
                radiance: Vec3::splat(k as f32),
            })
            .collect();
        assert!(!fit(&line, 5).plane);
    }

    #[test]
    fn nan_radiance_gives_no_finite_bound() {
        for n in [2, 4] {
            let mut s = samples(n, |_, _| Vec3::ONE);
            s[1].radiance.x = f32::NAN;
            assert_eq!(fit(&s, n as usize).bound, f32::INFINITY);
        }
    }
}
