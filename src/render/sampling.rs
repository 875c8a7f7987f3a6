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

/// `hash32` chained over `keys`, from `start`.
#[inline]
fn chain(start: u32, keys: &[u32]) -> u32 {
    keys.iter().fold(start, |h, &k| hash32(h ^ k))
}

/// The first link of every chain.
const CHAIN_START: u32 = 0x9e37_79b9;

/// Uniform float in [0, 1) from a hash: its top 24 bits.
#[inline]
fn unit(h: u32) -> f32 {
    (h >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// Van der Corput radical inverse in base 2.
#[inline]
fn radical_inverse(i: u32) -> f32 {
    (i.reverse_bits() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// The sample positions of one pixel: what its samples share (the grid's size, the seed's
/// part of each hash chain, a Hammersley set's rotation) is computed once, not per sample. The
/// renderer takes millions of samples a frame, and this was a twentieth of a diffuse frame's
/// time.
#[derive(Clone, Copy, Debug)]
pub struct PixelSamples {
    spp: u32,
    /// The grid's side where `spp` is a square, else 0 (a Hammersley set).
    n: u32,
    /// The hash chain over the seed.
    seeded: u32,
    /// The Hammersley set's Cranley-Patterson rotation (unused by a grid).
    rotation: Vec2,
}

impl PixelSamples {
    /// `seed` identifies pixel, eye and frame.
    #[inline]
    pub fn new(spp: u32, seed: [u32; 3]) -> PixelSamples {
        let n = (spp as f64).sqrt() as u32;
        let seeded = chain(CHAIN_START, &seed);
        let square = n * n == spp;
        PixelSamples {
            spp,
            n: if square { n } else { 0 },
            seeded,
            rotation: match square {
                true => Vec2::ZERO,
                false => Vec2::new(
                    unit(hash32(seeded ^ 0xffff_fff0)),
                    unit(hash32(seeded ^ 0xffff_fff1)),
                ),
            },
        }
    }

    /// Offset within the pixel, in [0,1)^2, of sample `s`.
    #[inline]
    pub fn get(&self, s: u32) -> Vec2 {
        let n = self.n;
        if n > 0 {
            let (sx, sy) = (s % n, s / n);
            let sample = hash32(self.seeded ^ s);
            let jx = unit(hash32(sample));
            let jy = unit(hash32(sample ^ 1));
            Vec2::new((sx as f32 + jx) / n as f32, (sy as f32 + jy) / n as f32)
        } else {
            let x = (s as f32 + 0.5) / self.spp as f32 + self.rotation.x;
            let y = radical_inverse(s) + self.rotation.y;
            Vec2::new(x.fract(), y.fract())
        }
    }
}

/// Offset within the pixel, in [0,1)^2, of sample `s` of `spp`; `seed` identifies pixel, eye and frame.
pub fn pixel_sample(s: u32, spp: u32, seed: [u32; 3]) -> Vec2 {
    PixelSamples::new(spp, seed).get(s)
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

    /// The positions as first defined: each coordinate the top 24 bits of one hash chain over
    /// the seed, the sample and the axis (the grid), or over the seed and a constant per axis
    /// (the Hammersley set's rotation). Images made before `PixelSamples` stay the same.
    fn chained(s: u32, spp: u32, seed: [u32; 3]) -> Vec2 {
        let uniform = |keys: &[u32]| unit(chain(CHAIN_START, keys));
        let n = (spp as f64).sqrt() as u32;
        if n * n == spp {
            let jx = uniform(&[seed[0], seed[1], seed[2], s, 0]);
            let jy = uniform(&[seed[0], seed[1], seed[2], s, 1]);
            let (sx, sy) = (s % n, s / n);
            Vec2::new((sx as f32 + jx) / n as f32, (sy as f32 + jy) / n as f32)
        } else {
            let rx = uniform(&[seed[0], seed[1], seed[2], 0xffff_fff0]);
            let ry = uniform(&[seed[0], seed[1], seed[2], 0xffff_fff1]);
            let x = (s as f32 + 0.5) / spp as f32 + rx;
            Vec2::new(x.fract(), (radical_inverse(s) + ry).fract())
        }
    }

    #[test]
    fn pixel_samples_are_the_chained_hashes() {
        for spp in [1u32, 2, 3, 4, 7, 9, 16, 64] {
            for pixel in 0..50 {
                let seed = [pixel * 7919, 3, 0xdead];
                let samples = PixelSamples::new(spp, seed);
                for s in 0..spp {
                    assert_eq!(
                        samples.get(s),
                        chained(s, spp, seed),
                        "{spp} spp, sample {s}"
                    );
                }
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
