//! Decoded textures and how they are sampled: bilinear or nearest lookups with glTF's wrap
//! modes (the sampler's), on linear RGBA texels; and the sRGB transfer function colour
//! textures are decoded through. 8-bit images keep their bytes and decode a texel as it is
//! read (`Texels`): the same linear values in a quarter of the memory.

use glam::{Vec2, Vec4};
use image::DynamicImage;

/// How a slot's stored values become linear ones (the glTF specification per slot).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Encoding {
    /// RGB through the sRGB EOTF, alpha linear: base colour and emissive textures.
    Srgb,
    /// Every channel as stored: metallic-roughness and normal textures.
    Linear,
}

impl Encoding {
    /// The transfer function of a slot's RGB channels (alpha is always linear).
    fn eotf(self) -> fn(f32) -> f32 {
        match self {
            Encoding::Srgb => srgb_to_linear,
            Encoding::Linear => |x| x,
        }
    }
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
    pub texels: Texels,
    pub wrap: [Wrap; 2],
    pub nearest: bool,
}

/// A texture's texels as stored. Almost every glTF asset's images are 8-bit PNG or JPEG: as
/// linear `f32` RGBA they take 16 bytes a texel (64 MB for 2048x2048), and a textured frame's
/// lookups wait on memory (`Texture::sample` was 21% of DamagedHelmet's profile). As bytes they
/// take 4, and a texel read decodes each channel through a 256-entry table that holds what the
/// image crate's conversion and the slot's transfer function give for that byte: the values, and
/// so every image, stay bit for bit those of the float texels. Deeper images keep floats.
#[derive(Clone, Debug)]
pub enum Texels {
    /// RGBA bytes, four a texel: the decoder's own buffer where the image is RGBA already.
    Bytes {
        rgba: Vec<u8>,
        decode: Box<ByteDecode>,
    },
    Floats(Vec<Vec4>),
}

/// The linear value of each stored byte: `rgb` through the slot's transfer function, `alpha`
/// as stored.
#[derive(Clone, Debug)]
pub struct ByteDecode {
    rgb: [f32; 256],
    alpha: [f32; 256],
}

impl ByteDecode {
    /// The table for an 8-bit image of `image`'s colour type. The image crate's conversion to
    /// floats is read off a ramp of every byte value in that same type (it does not convert
    /// grey the way it converts colour: 1 / 255 differs in the last bits), so the table
    /// cannot drift from what `to_rgba32f` gives the whole image.
    fn new(image: &DynamicImage, encoding: Encoding) -> ByteDecode {
        let v = |x: u32| x as u8;
        let ramp = match image {
            DynamicImage::ImageLuma8(_) => {
                DynamicImage::ImageLuma8(image::GrayImage::from_fn(256, 1, |x, _| {
                    image::Luma([v(x)])
                }))
            }
            DynamicImage::ImageLumaA8(_) => {
                DynamicImage::ImageLumaA8(image::GrayAlphaImage::from_fn(256, 1, |x, _| {
                    image::LumaA([v(x); 2])
                }))
            }
            DynamicImage::ImageRgb8(_) => {
                DynamicImage::ImageRgb8(image::RgbImage::from_fn(256, 1, |x, _| {
                    image::Rgb([v(x); 3])
                }))
            }
            _ => DynamicImage::ImageRgba8(image::RgbaImage::from_fn(256, 1, |x, _| {
                image::Rgba([v(x); 4])
            })),
        };
        let stored = ramp.to_rgba32f();
        let eotf = encoding.eotf();
        // An image without alpha stores 255 for every texel's: its ramp's alpha (the opaque
        // value) is that byte's entry.
        let has_alpha = image.color().has_alpha();
        ByteDecode {
            rgb: std::array::from_fn(|x| eotf(stored.get_pixel(x as u32, 0)[0])),
            alpha: std::array::from_fn(|x| {
                let column = if has_alpha { x as u32 } else { 255 };
                stored.get_pixel(column, 0)[3]
            }),
        }
    }

    #[inline]
    fn texel(&self, [r, g, b, a]: [u8; 4]) -> Vec4 {
        Vec4::new(
            self.rgb[r as usize],
            self.rgb[g as usize],
            self.rgb[b as usize],
            self.alpha[a as usize],
        )
    }
}

impl Texels {
    /// An image's texels in linear values for a slot of `encoding`: RGB through the slot's
    /// transfer function, alpha as stored (an image without alpha is opaque).
    pub fn decode(image: DynamicImage, encoding: Encoding) -> Texels {
        match image {
            DynamicImage::ImageLuma8(_)
            | DynamicImage::ImageLumaA8(_)
            | DynamicImage::ImageRgb8(_)
            | DynamicImage::ImageRgba8(_) => Texels::Bytes {
                decode: Box::new(ByteDecode::new(&image, encoding)),
                // Taken, not copied: each copy of a 2048x2048 map is 16 MB of fresh pages.
                rgba: image.into_rgba8().into_raw(),
            },
            _ => Texels::Floats(float_texels(&image, encoding)),
        }
    }

    /// Texel `i` (row-major, top row first), linear.
    #[inline]
    pub fn get(&self, i: usize) -> Vec4 {
        match self {
            Texels::Bytes { rgba, decode } => decode.texel(rgba.as_chunks::<4>().0[i]),
            Texels::Floats(texels) => texels[i],
        }
    }

    pub fn len(&self) -> usize {
        match self {
            Texels::Bytes { rgba, .. } => rgba.len() / 4,
            Texels::Floats(texels) => texels.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Every texel, linear, in order (what the GPU backend uploads).
    pub fn iter(&self) -> impl Iterator<Item = Vec4> + '_ {
        (0..self.len()).map(|i| self.get(i))
    }
}

/// Every texel of `image` as linear floats: the image crate's conversion to [0, 1], then the
/// slot's transfer function on RGB.
fn float_texels(image: &DynamicImage, encoding: Encoding) -> Vec<Vec4> {
    let eotf = encoding.eotf();
    image
        .to_rgba32f()
        .pixels()
        .map(|p| Vec4::new(eotf(p[0]), eotf(p[1]), eotf(p[2]), p[3]))
        .collect()
}

impl Texture {
    /// Bilinear (or nearest) lookup with the sampler's wrap modes; glTF UV (0,0) is the top-left.
    #[inline]
    pub fn sample(&self, uv: Vec2) -> Vec4 {
        // One match a lookup, not one a texel.
        match &self.texels {
            Texels::Bytes { rgba, decode } => {
                let texels = rgba.as_chunks::<4>().0;
                self.sample_with(uv, |i| decode.texel(texels[i]))
            }
            Texels::Floats(texels) => self.sample_with(uv, |i| texels[i]),
        }
    }

    #[inline(always)]
    fn sample_with(&self, uv: Vec2, texel: impl Fn(usize) -> Vec4) -> Vec4 {
        let (w, h) = (self.width as f32, self.height as f32);
        let x = uv.x * w - 0.5;
        let y = uv.y * h - 0.5;
        if self.nearest {
            let col = wrap_index(floor(x + 0.5) as i64, self.width as i64, self.wrap[0]);
            let row = wrap_index(floor(y + 0.5) as i64, self.height as i64, self.wrap[1]);
            return texel(row * self.width + col);
        }
        let (x0, y0) = (floor(x), floor(y));
        let (fx, fy) = (x - x0, y - y0);
        // Each column and row wrapped once (four wraps, not eight: a wrap divides).
        let [c0, c1] = self.wrapped(x0 as i64, 0);
        let [r0, r1] = self.wrapped(y0 as i64, 1);
        let at = |r: usize, c: usize| texel(r * self.width + c);
        let top = at(r0, c0).lerp(at(r0, c1), fx);
        let bottom = at(r1, c0).lerp(at(r1, c1), fx);
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

    /// An 8-bit image of every kind glTF's PNG and JPEG decode to, filled from a hash.
    fn eight_bit_images(width: u32, height: u32) -> Vec<DynamicImage> {
        let byte = |x: u32, y: u32, c: u32| {
            ((x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663) ^ c.wrapping_mul(83_492_791))
                >> 7) as u8
        };
        vec![
            DynamicImage::ImageLuma8(image::GrayImage::from_fn(width, height, |x, y| {
                image::Luma([byte(x, y, 0)])
            })),
            DynamicImage::ImageLumaA8(image::GrayAlphaImage::from_fn(width, height, |x, y| {
                image::LumaA([byte(x, y, 0), byte(x, y, 3)])
            })),
            DynamicImage::ImageRgb8(image::RgbImage::from_fn(width, height, |x, y| {
                image::Rgb([byte(x, y, 0), byte(x, y, 1), byte(x, y, 2)])
            })),
            DynamicImage::ImageRgba8(image::RgbaImage::from_fn(width, height, |x, y| {
                image::Rgba([0, 1, 2, 3].map(|c| byte(x, y, c)))
            })),
        ]
    }

    #[test]
    fn byte_texels_sample_as_the_float_texels_bit_for_bit() {
        let wraps = [Wrap::Repeat, Wrap::MirroredRepeat, Wrap::ClampToEdge];
        for (width, height) in [(16, 8), (13, 7)] {
            for image in eight_bit_images(width, height) {
                for encoding in [Encoding::Srgb, Encoding::Linear] {
                    let bytes = Texels::decode(image.clone(), encoding);
                    assert!(
                        matches!(bytes, Texels::Bytes { .. }),
                        "{image:?} stays bytes"
                    );
                    let floats = Texels::Floats(float_texels(&image, encoding));
                    assert_eq!(bytes.len(), floats.len());
                    for i in 0..bytes.len() {
                        let (b, f) = (bytes.get(i).to_array(), floats.get(i).to_array());
                        assert_eq!(b.map(f32::to_bits), f.map(f32::to_bits), "texel {i}");
                    }
                    for (wrap, nearest) in wraps.iter().flat_map(|&w| [(w, false), (w, true)]) {
                        let texture = |texels: &Texels| Texture {
                            source: 0,
                            encoding,
                            width: width as usize,
                            height: height as usize,
                            texels: texels.clone(),
                            wrap: [wrap, Wrap::Repeat],
                            nearest,
                        };
                        let (tb, tf) = (texture(&bytes), texture(&floats));
                        for k in 0..500 {
                            // UVs over three periods either side of the texture, off the grid.
                            let uv = Vec2::new(k as f32 * 0.0123 - 3.0, k as f32 * 0.0371 - 9.0);
                            let (b, f) = (tb.sample(uv).to_array(), tf.sample(uv).to_array());
                            assert_eq!(b.map(f32::to_bits), f.map(f32::to_bits), "uv {uv}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn sixteen_bit_images_keep_float_texels() {
        let image = DynamicImage::ImageRgba16(image::ImageBuffer::from_fn(4, 4, |x, y| {
            image::Rgba([x as u16 * 9000, y as u16 * 9000, 40_000, 65_535])
        }));
        let texels = Texels::decode(image.clone(), Encoding::Srgb);
        let Texels::Floats(values) = texels else {
            panic!("a 16-bit image decoded to bytes");
        };
        assert_eq!(values, float_texels(&image, Encoding::Srgb));
        // 9000 / 65535 is between two bytes' values: bytes would have lost it.
        assert!((values[1].x - srgb_to_linear(9000.0 / 65535.0)).abs() < 1e-6);
    }

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
