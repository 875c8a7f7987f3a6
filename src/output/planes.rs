//! Images as named channel planes, the form comparisons and difference images work in, and
//! reading any image file the tool understands (EXR with its views, PNG, JPEG) into that form.

use super::exr;
use super::image::Image;
use crate::error::{Error, Result};
use std::path::Path;

/// A multi-channel image: channel planes, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct Planes {
    pub width: usize,
    pub height: usize,
    pub names: Vec<String>,
    pub data: Vec<Vec<f32>>,
}

impl Planes {
    pub fn from_image(img: &Image) -> Planes {
        Planes {
            width: img.width,
            height: img.height,
            names: vec!["R".into(), "G".into(), "B".into()],
            data: (0..3).map(|c| img.channel(c)).collect(),
        }
    }

    /// The value of channel `c` at (x, y); 0 outside the image or its channels.
    pub fn value(&self, c: usize, x: usize, y: usize) -> f32 {
        if c < self.data.len() && x < self.width && y < self.height {
            self.data[c][y * self.width + x]
        } else {
            0.0
        }
    }
}

/// The views of an image file: EXR views by name (a file without views is one view named ""),
/// any other format the image crate reads as one view "" with its R, G, B(, A) in [0, 1].
pub fn read_planes(path: &Path) -> Result<Vec<(String, Planes)>> {
    let is_exr = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    if is_exr {
        return exr::read_view_planes(path);
    }
    let img =
        image::open(path).map_err(|e| Error::input(path, format!("cannot read image: {e}")))?;
    let has_alpha = img.color().has_alpha();
    let rgba = img.to_rgba32f();
    let (w, h) = (rgba.width() as usize, rgba.height() as usize);
    let nc = if has_alpha { 4 } else { 3 };
    let data = (0..nc)
        .map(|c| rgba.pixels().map(|p| p[c]).collect())
        .collect();
    let names = ["R", "G", "B", "A"][..nc]
        .iter()
        .map(|s| s.to_string())
        .collect();
    Ok(vec![(
        String::new(),
        Planes {
            width: w,
            height: h,
            names,
            data,
        },
    )])
}

