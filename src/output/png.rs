//! 8-bit sRGB PNG per eye, through `color.rs` (exposure, tone map, sRGB).

use super::color::Display;
use super::image::Image;
use super::write_atomic;
use crate::error::{Error, Result};
use std::path::Path;

/// Encodes linear radiance to 8-bit sRGB bytes, row-major RGB.
pub fn to_srgb8(image: &Image, display: &Display) -> Vec<u8> {
    image
        .pixels
        .iter()
        .flat_map(|&p| display.to_srgb8(p))
        .collect()
}

pub fn write_rgb8(path: &Path, width: usize, height: usize, rgb: &[u8]) -> Result<()> {
    write_atomic(path, |w| {
        image::write_buffer_with_format(
            w,
            rgb,
            width as u32,
            height as u32,
            image::ExtendedColorType::Rgb8,
            image::ImageFormat::Png,
        )
        .map_err(std::io::Error::other)
    })
}

/// Reads back an 8-bit RGB PNG this tool wrote: width, height and bytes.
pub fn read_rgb8(path: &Path) -> Result<(usize, usize, Vec<u8>)> {
    let bytes = crate::paths::read_regular(path)?;
    let img = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png)
        .map_err(|e| Error::input(path, format!("cannot read PNG: {e}")))?
        .into_rgb8();
    Ok((img.width() as usize, img.height() as usize, img.into_raw()))
}

pub fn write_png(path: &Path, image: &Image, display: &Display) -> Result<()> {
    write_rgb8(path, image.width, image.height, &to_srgb8(image, display))
}
