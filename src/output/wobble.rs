//! Wobble (wiggle) GIFs: views shown one after another so that motion parallax alone conveys
//! depth. The palette is one global 256-colour palette from NeuQuant (the `color_quant` crate the
//! gif crate itself uses) over all frames, optionally with Floyd-Steinberg dithering.

use super::{Image, write_atomic};
use crate::error::{Error, Result};
use serde::Deserialize;
use std::path::Path;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Mode {
    /// 0, 1, ..., n-1, 0, 1, ...
    Loop,
    /// 0, 1, ..., n-1, n-2, ..., 1, 0, ... (no view shown twice in a row)
    #[default]
    Bounce,
}

/// The order views are shown in one cycle.
pub fn schedule(views: usize, mode: Mode) -> Vec<usize> {
    let mut s: Vec<usize> = (0..views).collect();
    if mode == Mode::Bounce && views > 2 {
        s.extend((1..views - 1).rev());
    }
    s
}

/// The image moved `dx` whole pixels to the right (left when negative), the columns it uncovers
/// black: a wobble view shifted so that a chosen point lands where it does in the other views.
pub fn pivot_shift(img: &Image, dx: i64) -> Image {
    let mut out = Image::new(img.width, img.height);
    let w = img.width as i64;
    for y in 0..img.height {
        for x in 0..w {
            let from = x - dx;
            if (0..w).contains(&from) {
                out.set(x as usize, y, img.get(from as usize, y));
            }
        }
    }
    out
}

/// NeuQuant sampling factor: 1 is best and slowest, 30 fastest; 10 is the customary default.
const NEUQUANT_SAMPLE: i32 = 10;

/// Encodes RGB frames of equal size as an animated GIF with one global palette.
pub fn write_gif(
    path: &Path,
    width: usize,
    height: usize,
    frames: &[Vec<u8>],
    delay_ms: u32,
    loop_count: u16,
    dither: bool,
) -> Result<()> {
    if width > u16::MAX as usize || height > u16::MAX as usize {
        return Err(Error::input(
            path,
            "GIF frames are limited to 65535 pixels per side",
        ));
    }
    let mut rgba = Vec::with_capacity(frames.iter().map(Vec::len).sum::<usize>() / 3 * 4);
    for f in frames {
        for p in f.chunks_exact(3) {
            rgba.extend_from_slice(&[p[0], p[1], p[2], 255]);
        }
    }
    let nq = color_quant::NeuQuant::new(NEUQUANT_SAMPLE, 256, &rgba);
    let palette = nq.color_map_rgb();
    // GIF delays are in hundredths of a second.
    let delay = ((delay_ms + 5) / 10).max(1) as u16;
    let indexed: Vec<Vec<u8>> = frames
        .iter()
        .map(|f| index_frame(&nq, f, width, height, dither))
        .collect();
    write_atomic(path, |w| {
        let mut enc = gif::Encoder::new(w, width as u16, height as u16, &palette)
            .map_err(std::io::Error::other)?;
        let repeat = if loop_count == 0 {
            gif::Repeat::Infinite
        } else {
            gif::Repeat::Finite(loop_count)
        };
        enc.set_repeat(repeat).map_err(std::io::Error::other)?;
        for px in indexed {
            let mut frame = gif::Frame::from_indexed_pixels(width as u16, height as u16, px, None);
            frame.delay = delay;
            enc.write_frame(&frame).map_err(std::io::Error::other)?;
        }
        Ok(())
    })
}

fn index_frame(
    nq: &color_quant::NeuQuant,
    rgb: &[u8],
    w: usize,
    h: usize,
    dither: bool,
) -> Vec<u8> {
    if !dither {
        return rgb
            .chunks_exact(3)
            .map(|p| nq.index_of(&[p[0], p[1], p[2], 255]) as u8)
            .collect();
    }
    // Floyd-Steinberg error diffusion in 8-bit sRGB values.
    let mut work: Vec<[f32; 3]> = rgb
        .chunks_exact(3)
        .map(|p| [p[0] as f32, p[1] as f32, p[2] as f32])
        .collect();
    let mut out = vec![0u8; w * h];
    let map = nq.color_map_rgb();
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let v = work[i].map(|c| c.clamp(0.0, 255.0) as u8);
            let idx = nq.index_of(&[v[0], v[1], v[2], 255]);
            out[i] = idx as u8;
            let err: [f32; 3] = std::array::from_fn(|c| work[i][c] - map[idx * 3 + c] as f32);
            let mut spread = |dx: isize, dy: usize, k: f32| {
                let (nx, ny) = (x as isize + dx, y + dy);
                if nx >= 0 && (nx as usize) < w && ny < h {
                    let j = ny * w + nx as usize;
                    for c in 0..3 {
                        work[j][c] += err[c] * k;
                    }
                }
            };
            spread(1, 0, 7.0 / 16.0);
            spread(-1, 1, 3.0 / 16.0);
            spread(0, 1, 5.0 / 16.0);
            spread(1, 1, 1.0 / 16.0);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounce_never_repeats_a_view_back_to_back() {
        assert_eq!(schedule(2, Mode::Bounce), vec![0, 1]);
        assert_eq!(schedule(4, Mode::Bounce), vec![0, 1, 2, 3, 2, 1]);
        assert_eq!(schedule(3, Mode::Loop), vec![0, 1, 2]);
    }

    #[test]
    fn gif_decodes_with_frames_delays_and_loop_count() {
        let dir = std::env::temp_dir().join(format!("st-gif-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("w.gif");
        let frames: Vec<Vec<u8>> = (0..3).map(|k| vec![(k * 100) as u8; 4 * 3 * 3]).collect();
        write_gif(&path, 4, 3, &frames, 120, 3, true).unwrap();
        let mut opts = gif::DecodeOptions::new();
        opts.set_color_output(gif::ColorOutput::RGBA);
        let mut dec = opts.read_info(std::fs::File::open(&path).unwrap()).unwrap();
        let mut n = 0;
        while let Some(f) = dec.read_next_frame().unwrap() {
            assert_eq!(f.delay, 12);
            n += 1;
        }
        assert_eq!(n, 3);
        assert_eq!(dec.repeat(), gif::Repeat::Finite(3));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
