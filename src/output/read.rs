//! Reading any image file the tool understands (EXR with its views, PNG, JPEG) as planes.

use super::exr;
use super::planes::Planes;
use crate::error::{Error, Result};
use std::path::Path;

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
