//! OpenEXR stereo files, following OpenEXR's multi-view convention (docs: MultiViewOpenEXR) so that
//! OpenImageIO, Nuke and Blender read the views: one single-part file with a `multiView` attribute
//! (`left` first, so it is the default view with plain `R,G,B` channels; the other view as
//! `right.R` etc.), or one file per view carrying a `view` attribute. Scanline, ZIP, float32 or half.

use super::exr_header::{check_size, with_true_chunk_count};
use super::exr_zip;
use super::image::Image;
use super::planes::Planes;
use super::write_atomic;
use crate::error::{Error, Result};
use exr::block::chunk::{Chunk, CompressedBlock, CompressedScanLineBlock};
use exr::block::writer::ChunksWriter;
use exr::prelude::*;
use smallvec::SmallVec;
use std::path::Path;

/// ZIP over 16 scanlines, top to bottom (the crate's `SMALL_LOSSLESS`), written out: the chunks
/// `exr_zip` compresses are exactly these.
fn encoding() -> Encoding {
    Encoding {
        compression: Compression::ZIP16,
        blocks: Blocks::ScanLines,
        line_order: LineOrder::Increasing,
    }
}

fn samples(values: Vec<f32>, half: bool) -> FlatSamples {
    if half {
        FlatSamples::F16(values.into_iter().map(f16::from_f32).collect())
    } else {
        FlatSamples::F32(values)
    }
}

fn rgb_channels(image: &Image, prefix: &str, half: bool) -> Vec<AnyChannel<FlatSamples>> {
    ["R", "G", "B"]
        .iter()
        .enumerate()
        // Radiance is not perceptually linear (OpenEXR's pLinear flag). The exr crate guesses
        // the flag from the name, false for "R" but true for "right.R": set it for every view
        // alike.
        .map(|(c, name)| AnyChannel {
            name: Text::from(format!("{prefix}{name}").as_str()),
            sample_data: samples(image.channel(c), half),
            quantize_linearly: false,
            sampling: exr::math::Vec2(1, 1),
        })
        .collect()
}

fn write_layer(
    path: &Path,
    size: (usize, usize),
    attributes: LayerAttributes,
    channels: Vec<AnyChannel<FlatSamples>>,
) -> Result<()> {
    let list: SmallVec<[AnyChannel<FlatSamples>; 4]> = channels.into_iter().collect();
    let layer = Layer::new(size, attributes, encoding(), AnyChannels::sort(list));
    let image = exr::image::Image::from_layer(layer);
    // The crate writes the header and the offset table; the chunks are compressed here.
    let headers = image.write().infer_meta_data();
    debug_assert_eq!(headers[0].compression, Compression::ZIP16);
    let layer = &image.layer_data;
    let width = size.0;
    let chunks = exr_zip::chunks(size.1, |y, out| {
        for channel in &layer.channel_data.list {
            let row = y * width..(y + 1) * width;
            match &channel.sample_data {
                FlatSamples::F32(v) => out.extend(v[row].iter().flat_map(|s| s.to_le_bytes())),
                FlatSamples::F16(v) => out.extend(v[row].iter().flat_map(|s| s.to_le_bytes())),
                FlatSamples::U32(v) => out.extend(v[row].iter().flat_map(|s| s.to_le_bytes())),
            }
        }
    });
    write_atomic(path, |w| {
        exr::block::write(w, headers, true, |_, writer| {
            for (index, pixels) in chunks.into_iter().enumerate() {
                let block = CompressedScanLineBlock {
                    y_coordinate: (index * exr_zip::LINES_PER_CHUNK) as i32,
                    compressed_pixels_le: pixels,
                };
                writer.write_chunk(
                    index,
                    Chunk {
                        layer_index: 0,
                        compressed_block: CompressedBlock::ScanLine(block),
                    },
                )?;
            }
            Ok(())
        })
        .map_err(|e| std::io::Error::other(e.to_string()))
    })
}

fn attributes() -> LayerAttributes {
    LayerAttributes {
        software_name: Some(Text::from("stereotrace")),
        ..LayerAttributes::default()
    }
}

/// Writes views into one single-part multi-view file; the first view is the default view.
/// A single view named `center` is written as a plain RGB file without multi-view attributes.
pub fn write_multiview(path: &Path, views: &[(&str, &Image)], half: bool) -> Result<()> {
    let first = views
        .first()
        .ok_or_else(|| Error::input(path, "no view to write"))?
        .1;
    let mut channels = Vec::new();
    for (i, (name, img)) in views.iter().enumerate() {
        let prefix = if i == 0 {
            String::new()
        } else {
            format!("{name}.")
        };
        channels.extend(rgb_channels(img, &prefix, half));
    }
    let mut attrs = attributes();
    if !(views.len() == 1 && views[0].0 == "center") {
        attrs.multi_view_names = Some(views.iter().map(|(n, _)| Text::from(*n)).collect());
    }
    write_layer(path, (first.width, first.height), attrs, channels)
}

/// Writes one view into its own file with a `view` attribute.
pub fn write_single_view(path: &Path, view: &str, image: &Image, half: bool) -> Result<()> {
    let mut attrs = attributes();
    if view != "center" {
        attrs.view_name = Some(Text::from(view));
    }
    write_layer(
        path,
        (image.width, image.height),
        attrs,
        rgb_channels(image, "", half),
    )
}

/// Canonical channel order within a view: R, G, B, A first, then the rest by name (the order
/// OpenImageIO presents EXR channels in, so channel i of two files means the same thing).
fn channel_rank(name: &str) -> (usize, String) {
    let rank = ["R", "G", "B", "A"]
        .iter()
        .position(|c| *c == name)
        .unwrap_or(4);
    (rank, name.to_string())
}

/// Every view of an EXR file with all its channels: multi-view single-part files are split by
/// their channel prefixes, multi-part files by each part's `view` attribute; a file without views
/// yields one view named by its layer name, or `""`.
pub fn read_view_planes(path: &Path) -> Result<Vec<(String, Planes)>> {
    let bytes = crate::paths::read_regular(path)?;
    // Eight samples per pixel of the largest film: a 16384x16384 stereo RGBA file.
    check_size(&bytes, 8 * MAX_READ_PIXELS as u64)
        .map_err(|m| Error::input(path, format!("not a readable EXR file: {m}")))?;
    let bytes = with_true_chunk_count(&bytes).unwrap_or(bytes);
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(bytes))
        .map_err(|e| Error::input(path, format!("cannot read EXR: {e}")))?;
    let display = image.attributes.display_window;
    let size = (display.size.0, display.size.1);
    if size.0.saturating_mul(size.1) > MAX_READ_PIXELS {
        return Err(Error::input(
            path,
            format!(
                "the display window is {}x{} pixels, more than this tool compares ({MAX_READ_PIXELS})",
                size.0, size.1
            ),
        ));
    }
    let mut views: Vec<(String, Planes)> = Vec::new();
    for layer in &image.layer_data {
        let data_window = (layer.attributes.layer_position, layer.size);
        let names: Vec<String> = layer
            .attributes
            .multi_view_names
            .as_ref()
            .map(|v| v.iter().map(|t| t.to_string()).collect())
            .unwrap_or_default();
        // In a multi-view part the plain channels are the default view's, the first of
        // `multiView`, whatever `view` says (exrmultiview keeps its last input's `view`).
        let part_view = names
            .first()
            .cloned()
            .or_else(|| layer.attributes.view_name.as_ref().map(|t| t.to_string()))
            .or_else(|| layer.attributes.layer_name.as_ref().map(|t| t.to_string()))
            .unwrap_or_default();
        for ch in &layer.channel_data.list {
            let full = ch.name.to_string();
            let (view, base) = match full.rsplit_once('.') {
                Some((prefix, base)) if names.iter().any(|n| n == prefix) => {
                    (prefix.to_string(), base.to_string())
                }
                _ => (part_view.clone(), full.clone()),
            };
            let values = in_display_window(
                ch.sample_data.values_as_f32(),
                data_window,
                display.position,
                size,
            );
            let planes = match views.iter().position(|(n, _)| *n == view) {
                Some(i) => &mut views[i].1,
                None => {
                    let empty = Planes {
                        width: size.0,
                        height: size.1,
                        names: Vec::new(),
                        data: Vec::new(),
                    };
                    views.push((view, empty));
                    &mut views.last_mut().expect("a view was just pushed").1
                }
            };
            planes.names.push(base);
            planes.data.push(values);
        }
    }
    for (_, p) in &mut views {
        let mut chans: Vec<(String, Vec<f32>)> = p.names.drain(..).zip(p.data.drain(..)).collect();
        chans.sort_by_key(|(n, _)| channel_rank(n));
        (p.names, p.data) = chans.into_iter().unzip();
    }
    Ok(views)
}

/// The most pixels `read_view_planes` places a file's display window in: 16384 x 16384, the
/// largest film a pipeline may ask for.
const MAX_READ_PIXELS: usize = 16384 * 16384;

/// One channel of a part, stored over its data window (`origin`, `size`), placed in the display
/// window (`display_origin`, `display_size`): parts of one file may cover different rectangles
/// (OpenEXR's multi-part stereo samples give each eye, depth and disparity part its own), and
/// comparing is done over the display window, as idiff does. Pixels outside the data window
/// are 0 (OpenEXR's meaning: no data).
fn in_display_window(
    values: impl Iterator<Item = f32>,
    (origin, size): (Vec2<i32>, Vec2<usize>),
    display_origin: Vec2<i32>,
    (width, height): (usize, usize),
) -> Vec<f32> {
    let mut plane = vec![0.0; width * height];
    let values: Vec<f32> = values.collect();
    for y in 0..size.1 {
        let dy = i64::from(origin.1) + y as i64 - i64::from(display_origin.1);
        if !(0..height as i64).contains(&dy) {
            continue;
        }
        for x in 0..size.0 {
            let dx = i64::from(origin.0) + x as i64 - i64::from(display_origin.0);
            if let (true, Some(&v)) = ((0..width as i64).contains(&dx), values.get(y * size.0 + x))
            {
                plane[dy as usize * width + dx as usize] = v;
            }
        }
    }
    plane
}

/// Every view of an EXR file as a linear RGB image (each view must have R, G and B).
pub fn read_views(path: &Path) -> Result<Vec<(String, Image)>> {
    read_view_planes(path)?
        .into_iter()
        .map(|(name, p)| {
            let plane = |c: &str| p.names.iter().position(|n| n == c).map(|i| &p.data[i]);
            match (plane("R"), plane("G"), plane("B")) {
                (Some(r), Some(g), Some(b)) => {
                    Ok((name, Image::from_channels(p.width, p.height, r, g, b)))
                }
                _ => Err(Error::input(
                    path,
                    format!("view '{name}' lacks one of the R, G, B channels"),
                )),
            }
        })
        .collect()
}

/// Writes arbitrary channel planes as a single-part float EXR (for difference images).
pub fn write_planes(path: &Path, p: &Planes) -> Result<()> {
    let channels = p
        .names
        .iter()
        .zip(&p.data)
        .map(|(n, d)| AnyChannel::new(Text::from(n.as_str()), FlatSamples::F32(d.clone())))
        .collect();
    write_layer(path, (p.width, p.height), attributes(), channels)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn gradient(w: usize, h: usize, k: f32) -> Image {
        let mut img = Image::new(w, h);
        for y in 0..h {
            for x in 0..w {
                img.set(x, y, Vec3::new(x as f32 * k, y as f32, 0.25 + k));
            }
        }
        img
    }

    #[test]
    fn multiview_file_round_trips_both_views() {
        let dir = std::env::temp_dir().join(format!("st-exr-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("pair.exr");
        let (l, r) = (gradient(7, 5, 1.0), gradient(7, 5, 2.0));
        write_multiview(&path, &[("left", &l), ("right", &r)], false).unwrap();
        let views = read_views(&path).unwrap();
        let get = |n: &str| &views.iter().find(|(v, _)| v == n).unwrap().1;
        assert_eq!(get("left"), &l);
        assert_eq!(get("right"), &r);
        write_single_view(&path, "right", &r, true).unwrap();
        let views = read_views(&path).unwrap();
        assert_eq!(views[0].0, "right");
        assert!((views[0].1.get(3, 2) - r.get(3, 2)).abs().max_element() < 1e-2);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn both_views_channels_carry_the_same_linearity_flag() {
        let dir = std::env::temp_dir().join(format!("st-exr-plinear-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("pair.exr");
        let img = gradient(4, 3, 1.0);
        write_multiview(&path, &[("left", &img), ("right", &img)], false).unwrap();
        let meta = exr::meta::MetaData::read_from_file(&path, false).unwrap();
        let channels = &meta.headers[0].channels.list;
        assert_eq!(channels.len(), 6);
        assert!(
            channels.iter().all(|c| !c.quantize_linearly),
            "{:?}",
            channels
                .iter()
                .map(|c| (c.name.to_string(), c.quantize_linearly))
                .collect::<Vec<_>>()
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
