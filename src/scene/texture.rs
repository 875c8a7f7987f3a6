//! Decoded textures and how they are sampled: bilinear or nearest lookups with glTF's wrap
//! modes (the sampler's), on linear RGBA texels; and the sRGB transfer function colour
//! textures are decoded through.

use glam::{Vec2, Vec4};

/// How a slot's stored values become linear ones (the glTF specification per slot).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Encoding {
    /// RGB through the sRGB EOTF, alpha linear: base colour and emissive textures.
    Srgb,
    /// Every channel as stored: metallic-roughness and normal textures.
    Linear,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wrap {
    Repeat,
    MirroredRepeat,
    ClampToEdge,
}

/// A decoded texture: linear RGBA texels, top row first, and its sampler.
#[derive(Clone, Debug)]
pub struct Texture {
    /// The glTF texture it was decoded from.
    pub source: usize,
    pub encoding: Encoding,
    pub width: usize,
    pub height: usize,
    pub texels: Vec<Vec4>,
    pub wrap: [Wrap; 2],
    pub nearest: bool,
}

impl Texture {
    /// Bilinear (or nearest) lookup with the sampler's wrap modes; glTF UV (0,0) is the top-left.
    pub fn sample(&self, uv: Vec2) -> Vec4 {
        let (w, h) = (self.width as f32, self.height as f32);
        let x = uv.x * w - 0.5;
        let y = uv.y * h - 0.5;
        if self.nearest {
            return self.texel(floor(x + 0.5) as i64, floor(y + 0.5) as i64);
        }
        let (x0, y0) = (floor(x), floor(y));
        let (fx, fy) = (x - x0, y - y0);
        // Each column and row wrapped once (four wraps, not eight: a wrap divides).
        let [c0, c1] = self.wrapped(x0 as i64, 0);
        let [r0, r1] = self.wrapped(y0 as i64, 1);
        let texel = |r: usize, c: usize| self.texels[r * self.width + c];
        let top = texel(r0, c0).lerp(texel(r0, c1), fx);
        let bottom = texel(r1, c0).lerp(texel(r1, c1), fx);
        top.lerp(bottom, fy)
    }

    /// Texel columns (`axis` 0) or rows (1) `i` and `i + 1` under the sampler's wrap mode.
    fn wrapped(&self, i: i64, axis: usize) -> [usize; 2] {
        let n = [self.width, self.height][axis] as i64;
        let wrap = self.wrap[axis];
        [
            wrap_index(i, n, wrap),
            wrap_index(i.saturating_add(1), n, wrap),
        ]
    }

    fn texel(&self, x: i64, y: i64) -> Vec4 {
        let x = wrap_index(x, self.width as i64, self.wrap[0]);
        let y = wrap_index(y, self.height as i64, self.wrap[1]);
        self.texels[y * self.width + x]
    }
}

/// `x.floor()`, inline: on the baseline x86-64 target `floor` is a call into libm (1.2% of a
/// diffuse frame's profile; with the wraps halved, DamagedHelmet's frame is 6% faster). Every
/// `f32` of magnitude 2^23 or more is an integer (or not finite) and is its own floor; below,
/// truncation towards zero is the floor except for negative non-integers, one less. The sign
/// is `x`'s, as `floor(-0.0)` is -0.0.
#[inline]
fn floor(x: f32) -> f32 {
    const INTEGRAL: f32 = 8_388_608.0; // 2^23
    if x.abs() < INTEGRAL {
        let t = x as i32 as f32;
        (if t > x { t - 1.0 } else { t }).copysign(x)
    } else {
        x
    }
}

fn wrap_index(i: i64, n: i64, wrap: Wrap) -> usize {
    let r = match wrap {
        Wrap::ClampToEdge => i.clamp(0, n - 1),
        Wrap::Repeat => euclid_rem(i, n),
        Wrap::MirroredRepeat => {
            let period = euclid_rem(i, 2 * n);
            if period < n {
                period
            } else {
                2 * n - 1 - period
            }
        }
    };
    r as usize
}

/// `i.rem_euclid(n)` for `n > 0`; for a power of two (most textures' sides) the low bits of
/// `i` in two's complement, which are that remainder, without a 64-bit division (two to four
/// of them a texture lookup).
#[inline]
fn euclid_rem(i: i64, n: i64) -> i64 {
    if n & (n - 1) == 0 {
        i & (n - 1)
    } else {
        i.rem_euclid(n)
    }
}

/// sRGB electro-optical transfer function (IEC 61966-2-1), for colour textures.
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_inline_floor_is_floor_bit_for_bit() {
        let mut values = vec![
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            -1.5,
            8_388_607.5,
            -8_388_607.5,
            8_388_608.0,
            -8_388_609.0,
            3e9,
            -3e9,
            f32::MAX,
            f32::MIN,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        // A spread of magnitudes and fractions, both signs.
        let mut v = 1e-6f32;
        while v < 1e10 {
            values.extend([v, -v, v + 0.5, -v - 0.5]);
            v *= 1.37;
        }
        for x in values {
            assert_eq!(floor(x).to_bits(), x.floor().to_bits(), "{x}");
        }
    }

    #[test]
    fn the_power_of_two_remainder_is_rem_euclid() {
        let mut values = vec![i64::MIN, i64::MIN + 1, i64::MAX, i64::MAX - 1];
        values.extend(-300..300);
        values.extend((0..62).flat_map(|b| [1i64 << b, -(1i64 << b), (1i64 << b) + 7]));
        for n in [1, 2, 3, 4, 6, 8, 64, 100, 1 << 20, (1 << 20) + 1] {
            for &i in &values {
                assert_eq!(euclid_rem(i, n), i.rem_euclid(n), "{i} mod {n}");
            }
        }
    }

    #[test]
    fn wrap_modes_follow_the_opengl_definitions() {
        assert_eq!(wrap_index(-1, 4, Wrap::Repeat), 3);
        assert_eq!(wrap_index(5, 4, Wrap::Repeat), 1);
        assert_eq!(wrap_index(-1, 4, Wrap::ClampToEdge), 0);
        assert_eq!(wrap_index(9, 4, Wrap::ClampToEdge), 3);
        assert_eq!(wrap_index(4, 4, Wrap::MirroredRepeat), 3);
        assert_eq!(wrap_index(-1, 4, Wrap::MirroredRepeat), 0);
    }

    #[test]
    fn srgb_decode_matches_the_standard_at_its_knee_and_ends() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
        assert!((srgb_to_linear(0.5) - 0.214_041).abs() < 1e-5);
    }
}
