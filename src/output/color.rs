//! From linear radiance to 8-bit display values, in one place for every 8-bit output (PNG, GIF,
//! video): exposure in stops, an optional tone map, the sRGB transfer function, rounding.

use glam::Vec3;
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum ToneMap {
    /// Clip to [0, 1].
    #[default]
    None,
    /// Reinhard's `x / (1 + x)` on each channel: never clips, compresses highlights.
    Reinhard,
}

#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Display {
    /// Exposure in photographic stops: radiance is multiplied by 2^exposure.
    pub exposure: f32,
    pub tone_map: ToneMap,
}

/// sRGB opto-electronic transfer function (IEC 61966-2-1) on a value in [0, 1].
#[inline]
pub fn linear_to_srgb(c: f32) -> f32 {
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// Inverse of [`linear_to_srgb`].
#[inline]
pub fn srgb_to_linear(c: f32) -> f32 {
    crate::scene::texture::srgb_to_linear(c)
}

/// Rounds a display value in [0, 1] to 8 bits; NaN becomes 0 so no output ever carries it.
#[inline]
pub fn quantize(v: f32) -> u8 {
    if v.is_nan() {
        return 0;
    }
    (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

impl Display {
    /// Linear radiance to display-referred values in [0, 1] (before the sRGB encoding).
    #[inline]
    pub fn map_linear(&self, radiance: Vec3) -> Vec3 {
        let v = radiance * self.exposure.exp2();
        let v = Vec3::new(finite(v.x), finite(v.y), finite(v.z)).max(Vec3::ZERO);
        match self.tone_map {
            ToneMap::None => v.min(Vec3::ONE),
            ToneMap::Reinhard => v / (Vec3::ONE + v),
        }
    }

    /// Linear radiance to 8-bit sRGB.
    #[inline]
    pub fn to_srgb8(&self, radiance: Vec3) -> [u8; 3] {
        let v = self.map_linear(radiance);
        [
            quantize(linear_to_srgb(v.x)),
            quantize(linear_to_srgb(v.y)),
            quantize(linear_to_srgb(v.z)),
        ]
    }
}

/// NaN and -inf become 0, +inf becomes a large finite value (clipped later).
#[inline]
fn finite(x: f32) -> f32 {
    if x.is_nan() || x == f32::NEG_INFINITY {
        0.0
    } else {
        x.min(f32::MAX)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trips_and_hits_the_known_midpoint() {
        for i in 0..=100 {
            let x = i as f32 / 100.0;
            assert!((srgb_to_linear(linear_to_srgb(x)) - x).abs() < 1e-5);
        }
        // Linear 0.214041 is sRGB 0.5; every code value survives decode + encode.
        assert!((linear_to_srgb(0.214_041) - 0.5).abs() < 1e-5);
        for code in 0..=255u8 {
            assert_eq!(
                quantize(linear_to_srgb(srgb_to_linear(code as f32 / 255.0))),
                code
            );
        }
    }

    #[test]
    fn exposure_doubles_per_stop_and_non_finite_values_are_safe() {
        let d = Display {
            exposure: 1.0,
            tone_map: ToneMap::None,
        };
        assert_eq!(d.map_linear(Vec3::splat(0.25)), Vec3::splat(0.5));
        assert_eq!(
            d.to_srgb8(Vec3::new(f32::NAN, f32::INFINITY, -1.0)),
            [0, 255, 0]
        );
        let r = Display {
            exposure: 0.0,
            tone_map: ToneMap::Reinhard,
        };
        assert_eq!(r.map_linear(Vec3::ONE), Vec3::splat(0.5));
    }
}
