//! Resolving glTF buffers (GLB chunk, data URIs, files beside the scene) and checking that an
//! accessor's bytes really lie inside them before the `gltf` reader touches them. The `gltf` crate
//! validates indices between JSON objects but not byte ranges, so a crafted file could otherwise make
//! the reader return short data or trip its debug assertions.

use crate::error::{Error, Result};
use crate::paths::{Outside, depth_inside};
use base64::Engine;
use std::path::{Path, PathBuf};

/// Bytes behind a URI: `data:` URIs are decoded, anything else is a relative path that must stay
/// inside the folder of the scene file.
pub fn read_uri(scene_file: &Path, object: &str, uri: &str) -> Result<Vec<u8>> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (header, payload) = rest
            .split_once(',')
            .ok_or_else(|| Error::scene(scene_file, object, "malformed data URI (no comma)"))?;
        if !header.ends_with(";base64") {
            return Err(Error::scene(
                scene_file,
                object,
                "data URI is not base64-encoded",
            ));
        }
        return base64::engine::general_purpose::STANDARD
            .decode(payload.trim())
            .map_err(|e| Error::scene(scene_file, object, format!("bad base64 in data URI: {e}")));
    }
    let path = resolve_relative(scene_file, object, uri)?;
    crate::paths::read_regular(&path).map_err(|e| {
        Error::scene(
            scene_file,
            object,
            format!("cannot read '{}': {e}", path.display()),
        )
    })
}

/// The file a relative URI names, refusing absolute paths, other schemes and `..` that climbs out of
/// the scene's folder (a scene must not read arbitrary files of the machine rendering it).
pub fn resolve_relative(scene_file: &Path, object: &str, uri: &str) -> Result<PathBuf> {
    let decoded = percent_decode(uri);
    if decoded.contains("://") || decoded.starts_with('/') || decoded.contains('\\') {
        return Err(Error::scene(
            scene_file,
            object,
            format!("URI '{uri}' is not a relative path inside the scene's folder"),
        ));
    }
    match depth_inside(Path::new(&decoded)) {
        Ok(_) => {}
        Err(Outside::Escapes) => {
            return Err(Error::scene(
                scene_file,
                object,
                format!("URI '{uri}' escapes the scene's folder"),
            ));
        }
        Err(Outside::Absolute) => {
            return Err(Error::scene(
                scene_file,
                object,
                format!("URI '{uri}' is not a relative path"),
            ));
        }
    }
    let base = scene_file.parent().unwrap_or(Path::new("."));
    Ok(base.join(decoded))
}

/// glTF URIs are RFC 3986 references: spaces and other bytes arrive percent-encoded.
fn percent_decode(s: &str) -> String {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' && i + 2 < bytes.len() {
            let hex = std::str::from_utf8(&bytes[i + 1..i + 3]).unwrap_or("");
            if let Ok(v) = u8::from_str_radix(hex, 16) {
                out.push(v);
                i += 3;
                continue;
            }
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Loads every buffer of the document.
pub fn load_buffers(
    scene_file: &Path,
    document: &gltf::Document,
    blob: Option<&[u8]>,
) -> Result<Vec<Vec<u8>>> {
    let mut out = Vec::new();
    for buffer in document.buffers() {
        let object = format!("buffers[{}]", buffer.index());
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => blob
                .ok_or_else(|| {
                    Error::scene(
                        scene_file,
                        &object,
                        "refers to a GLB binary chunk the file lacks",
                    )
                })?
                .to_vec(),
            gltf::buffer::Source::Uri(uri) => read_uri(scene_file, &object, uri)?,
        };
        if data.len() < buffer.length() {
            return Err(Error::scene(
                scene_file,
                &object,
                format!(
                    "holds {} bytes but byteLength says {} (truncated file?)",
                    data.len(),
                    buffer.length()
                ),
            ));
        }
        out.push(data);
    }
    Ok(out)
}

/// Bytes of a buffer view, bounds-checked.
pub fn view_bytes<'a>(
    scene_file: &Path,
    buffers: &'a [Vec<u8>],
    view: &gltf::buffer::View,
) -> Result<&'a [u8]> {
    let data = &buffers[view.buffer().index()];
    let end = view.offset().checked_add(view.length());
    match end {
        Some(end) if end <= data.len() => Ok(&data[view.offset()..end]),
        _ => Err(Error::scene(
            scene_file,
            format!("bufferViews[{}]", view.index()),
            format!(
                "bytes {}..{} lie outside buffer {} ({} bytes)",
                view.offset(),
                view.offset().saturating_add(view.length()),
                view.buffer().index(),
                data.len()
            ),
        )),
    }
}

/// Checks that reading `count` elements of `element_size` bytes at `offset` with the view's stride
/// stays inside the view (and the view inside its buffer).
fn check_range(
    scene_file: &Path,
    buffers: &[Vec<u8>],
    object: &str,
    view: &gltf::buffer::View,
    offset: usize,
    count: usize,
    element_size: usize,
) -> Result<()> {
    let bytes = view_bytes(scene_file, buffers, view)?;
    let stride = view.stride().unwrap_or(element_size);
    if stride < element_size {
        return Err(Error::scene(
            scene_file,
            object,
            format!("byteStride {stride} is smaller than one element ({element_size} bytes)"),
        ));
    }
    let need = (count.max(1) - 1)
        .checked_mul(stride)
        .and_then(|n| n.checked_add(offset))
        .and_then(|n| n.checked_add(element_size));
    match need {
        Some(n) if n <= bytes.len() => Ok(()),
        _ => Err(Error::scene(
            scene_file,
            object,
            format!(
                "reads {count} elements of {element_size} bytes past the end of bufferViews[{}] ({} bytes)",
                view.index(),
                bytes.len()
            ),
        )),
    }
}

/// A sparse accessor's indices (in range already) name elements of the accessor and strictly
/// increase (glTF 2.0 section 3.6.2.3).
fn check_sparse_indices(
    scene_file: &Path,
    buffers: &[Vec<u8>],
    accessor: &gltf::Accessor,
    object: &str,
) -> Result<()> {
    let Some(sparse) = accessor.sparse() else {
        return Ok(());
    };
    let indices = sparse.indices();
    let size = indices.index_type().size();
    let bytes = &view_bytes(scene_file, buffers, &indices.view())?[indices.offset()..];
    let mut previous: Option<u64> = None;
    for (k, b) in bytes.chunks_exact(size).take(sparse.count()).enumerate() {
        let i = b
            .iter()
            .rev()
            .fold(0u64, |v, &byte| (v << 8) | u64::from(byte));
        let fault = if i >= accessor.count() as u64 {
            Some(format!(
                "index {i} at position {k} is out of range: the accessor has {} elements",
                accessor.count()
            ))
        } else if previous.is_some_and(|p| i <= p) {
            Some(format!(
                "index {i} at position {k} does not increase (indices must strictly increase)"
            ))
        } else {
            None
        };
        if let Some(message) = fault {
            return Err(Error::scene(
                scene_file,
                format!("{object}.sparse.indices"),
                message,
            ));
        }
        previous = Some(i);
    }
    Ok(())
}

/// Every byte an accessor (dense or sparse) can read lies inside its buffers.
pub fn check_accessor(
    scene_file: &Path,
    buffers: &[Vec<u8>],
    accessor: &gltf::Accessor,
    object: &str,
) -> Result<()> {
    if accessor.count() == 0 {
        return Err(Error::scene(scene_file, object, "accessor has count 0"));
    }
    if let Some(view) = accessor.view() {
        check_range(
            scene_file,
            buffers,
            object,
            &view,
            accessor.offset(),
            accessor.count(),
            accessor.size(),
        )?;
    }
    if let Some(sparse) = accessor.sparse() {
        let indices = sparse.indices();
        check_range(
            scene_file,
            buffers,
            &format!("{object}.sparse.indices"),
            &indices.view(),
            indices.offset(),
            sparse.count(),
            indices.index_type().size(),
        )?;
        check_sparse_indices(scene_file, buffers, accessor, object)?;
        let values = sparse.values();
        check_range(
            scene_file,
            buffers,
            &format!("{object}.sparse.values"),
            &values.view(),
            values.offset(),
            sparse.count(),
            accessor.size(),
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_uris_stay_inside_the_scene_folder() {
        let scene = Path::new("/scenes/a/scene.gltf");
        assert!(resolve_relative(scene, "b", "data.bin").is_ok());
        assert!(resolve_relative(scene, "b", "sub/../data.bin").is_ok());
        assert!(resolve_relative(scene, "b", "../data.bin").is_err());
        assert!(resolve_relative(scene, "b", "sub/../../x.bin").is_err());
        assert!(resolve_relative(scene, "b", "/etc/passwd").is_err());
        assert!(resolve_relative(scene, "b", "http://example.com/x.bin").is_err());
        assert!(resolve_relative(scene, "b", "%2E%2E/x.bin").is_err());
    }

    #[test]
    fn percent_escapes_are_decoded() {
        assert_eq!(percent_decode("my%20file.bin"), "my file.bin");
        assert_eq!(percent_decode("100%"), "100%");
    }
}
