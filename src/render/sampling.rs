//! Sample positions inside a pixel, as a pure function of (pixel, sample index, eye, frame):
//! images are bit-identical whatever the thread count or tile order.
//!
//! `spp` that is a perfect square gets an n x n stratified jittered grid (what the reference images
//! use); any other count gets a Hammersley set with a per-pixel Cranley-Patterson rotation, which is
//! stratified in x for every count.

use glam::Vec2;

/// A 32-bit integer hash with good avalanche (the "lowbias32" constants of Chris Wellons'
/// hash-prospector, a public-domain finding).
#[inline]
pub fn hash32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// Uniform float in [0, 1) from a chain of integer keys.
#[inline]
pub fn uniform(keys: &[u32]) -> f32 {
    let h = keys.iter().fold(0x9e37_79b9u32, |h, &k| hash32(h ^ k));
    (h >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// Van der Corput radical inverse in base 2.
#[inline]
fn radical_inverse(i: u32) -> f32 {
    (i.reverse_bits() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// Offset within the pixel, in [0,1)^2, of sample `s` of `spp`; `seed` identifies pixel, eye and frame.
pub fn pixel_sample(s: u32, spp: u32, seed: [u32; 3]) -> Vec2 {
    let n = (spp as f64).sqrt() as u32;
    if n * n == spp {
        let (sx, sy) = (s % n, s / n);
        let jx = uniform(&[seed[0], seed[1], seed[2], s, 0]);
        let jy = uniform(&[seed[0], seed[1], seed[2], s, 1]);
        Vec2::new((sx as f32 + jx) / n as f32, (sy as f32 + jy) / n as f32)
    } else {
        let rx = uniform(&[seed[0], seed[1], seed[2], 0xffff_fff0]);
        let ry = uniform(&[seed[0], seed[1], seed[2], 0xffff_fff1]);
        let x = (s as f32 + 0.5) / spp as f32 + rx;
        let y = radical_inverse(s) + ry;
        Vec2::new(x.fract(), y.fract())
    }
}

/// How far, per axis, the mean of a pixel's `spp` sample positions may lie from the pixel's
/// centre, in pixels. An n x n grid jitters each sample within its column's 1/n, so the mean
/// lies within 1/(2n). The Hammersley sets' y coordinates are stratified only for powers of
/// two: other counts are given half a pixel, as if unstratified.
pub fn centroid_bound(spp: usize) -> f32 {
    let n = (spp as f64).sqrt() as usize;
    if n * n == spp && n > 0 {
        0.5 / n as f32
    } else {
        0.5
    }
}

/// How thick a strip along a pixel's side its `spp` samples may leave without a sample, in
/// pixels: an n x n grid puts a sample in every 1/n of each row and column. The Hammersley sets
/// are given the whole pixel (their y coordinates are stratified only for powers of two).
pub fn unseen_strip(spp: usize) -> f32 {
    2.0 * centroid_bound(spp)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sample_means_stay_within_the_centroid_bound() {
        for spp in [1u32, 2, 3, 4, 5, 9, 16, 64] {
            let bound = centroid_bound(spp as usize);
            for pixel in 0..200 {
                let mean = (0..spp)
                    .map(|s| pixel_sample(s, spp, [pixel, 3, 1]))
                    .sum::<Vec2>()
                    / spp as f32;
                let off = (mean - Vec2::splat(0.5)).abs().max_element();
                assert!(
                    off <= bound + 1e-6,
                    "{spp} spp, pixel {pixel}: {off} > {bound}"
                );
            }
        }
    }

    #[test]
    fn square_counts_put_one_sample_in_each_stratum() {
        let mut seen = [false; 16];
        for s in 0..16 {
            let p = pixel_sample(s, 16, [3, 4, 5]);
            assert!((0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y));
            seen[(p.y * 4.0) as usize * 4 + (p.x * 4.0) as usize] = true;
        }
        assert!(seen.iter().all(|&b| b));
    }

    #[test]
    fn other_counts_stay_in_the_pixel_and_are_deterministic() {
        for s in 0..7 {
            let p = pixel_sample(s, 7, [1, 2, 3]);
            assert!((0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y));
            assert_eq!(p, pixel_sample(s, 7, [1, 2, 3]));
        }
        assert_ne!(pixel_sample(0, 7, [1, 2, 3]), pixel_sample(0, 7, [1, 2, 4]));
    }
}
