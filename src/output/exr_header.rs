//! EXR headers read before the exr crate reads the file, for two things the crate does not do.
//!
//! **Stale chunk counts.** Single-part scanline files whose `chunkCount` attribute disagrees
//! with their data window and compression: the OpenEXR library reads them (it needs
//! `chunkCount` only in multi-part files and counts the chunks itself otherwise); the exr crate
//! refuses them ("chunk count not matching data size"). OpenEXR 3.1's `exrmultiview` writes
//! them: it copies the first input's header, `chunkCount` included, then changes the compression
//! (by default to PIZ, 32 lines per chunk), so every file it makes from ours (ZIP, 16 lines per
//! chunk) lies. The attribute is corrected in a copy of the bytes.
//!
//! **Sizes a file cannot hold.** The crate allocates what a header's data window asks for; a
//! flipped bit there asked for 51 GB and aborted the process. A file is refused when its parts
//! together ask for more samples than `read_view_planes` compares, or for more chunks than its
//! offset tables (8 bytes a chunk) could fit in the file.
//!
//! Layout (OpenEXR "File Layout"): magic, a version word whose flags say tiled (bit 9), deep
//! (bit 11) and multi-part (bit 12), then each header as attributes `name\0 type\0 size:i32
//! value` up to an empty name; a multi-part file ends its headers with one more empty name.

const MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];
const TILED: u32 = 1 << 9;
const DEEP: u32 = 1 << 11;
const MULTI_PART: u32 = 1 << 12;

/// Scanlines per chunk by compression code (OpenEXR's `Compression` enum: none, RLE, ZIPS, ZIP,
/// PIZ, PXR24, B44, B44A, DWAA, DWAB).
fn lines_per_chunk(compression: u8) -> Option<u64> {
    Some(match compression {
        0..=2 => 1,
        3 | 5 => 16,
        4 | 6..=8 => 32,
        9 => 256,
        _ => return None,
    })
}

/// What one header says that matters here.
#[derive(Default)]
struct Header {
    /// Byte offset of the `chunkCount` value.
    chunk_count_at: Option<usize>,
    compression: Option<u8>,
    /// Width and height of the data window.
    size: Option<(u64, u64)>,
    channels: u64,
    tiled: bool,
    /// A data window whose maximum is below its minimum (the crate sizes buffers from it).
    inverted_window: bool,
}

impl Header {
    fn chunks(&self) -> Option<u64> {
        let (_, rows) = self.size?;
        Some(rows.div_ceil(lines_per_chunk(self.compression?)?))
    }
}

fn word(bytes: &[u8], at: usize) -> Option<[u8; 4]> {
    bytes
        .get(at..at.checked_add(4)?)
        .map(|b| [b[0], b[1], b[2], b[3]])
}

fn i32_at(v: &[u8], k: usize) -> i64 {
    i64::from(i32::from_le_bytes([v[k], v[k + 1], v[k + 2], v[k + 3]]))
}

/// One header from `at`; the header and the offset after its terminating empty name.
fn header(bytes: &[u8], mut at: usize, tiled: bool) -> Option<(Header, usize)> {
    let mut h = Header {
        tiled,
        ..Header::default()
    };
    loop {
        let name_end = at + bytes.get(at..)?.iter().position(|&b| b == 0)?;
        if name_end == at {
            return Some((h, at + 1));
        }
        let type_end = name_end + 1 + bytes.get(name_end + 1..)?.iter().position(|&b| b == 0)?;
        let size = usize::try_from(i32::from_le_bytes(word(bytes, type_end + 1)?)).ok()?;
        let value = type_end + 5;
        let v = bytes.get(value..value.checked_add(size)?)?;
        match (&bytes[at..name_end], &bytes[name_end + 1..type_end]) {
            (b"chunkCount", b"int") if size == 4 => h.chunk_count_at = Some(value),
            (b"compression", b"compression") if size == 1 => h.compression = Some(v[0]),
            (b"type", b"string") => h.tiled |= v.starts_with(b"tiled"),
            (b"dataWindow", b"box2i") if size == 16 => {
                let (w, rows) = (
                    i32_at(v, 8) - i32_at(v, 0) + 1,
                    i32_at(v, 12) - i32_at(v, 4) + 1,
                );
                match (u64::try_from(w), u64::try_from(rows)) {
                    (Ok(w), Ok(rows)) if w > 0 && rows > 0 => h.size = Some((w, rows)),
                    _ => h.inverted_window = true,
                }
            }
            // A channel list entry: name\0, then 16 bytes (type, pLinear, reserved, sampling).
            (b"channels", b"chlist") => {
                let mut k = 0;
                while let Some(end) = v.get(k..).and_then(|r| r.iter().position(|&b| b == 0)) {
                    if end == 0 {
                        break;
                    }
                    h.channels += 1;
                    k += end + 1 + 16;
                }
            }
            _ => {}
        }
        at = value + size;
    }
}

/// Every header of a file, with its version word; `None` for what this does not understand.
fn headers(bytes: &[u8]) -> Option<(u32, Vec<Header>)> {
    if word(bytes, 0)? != MAGIC {
        return None;
    }
    let version = u32::from_le_bytes(word(bytes, 4)?);
    let tiled = version & TILED != 0;
    let (first, mut at) = header(bytes, 8, tiled)?;
    let mut all = vec![first];
    if version & MULTI_PART != 0 {
        while *bytes.get(at)? != 0 {
            let (h, next) = header(bytes, at, tiled)?;
            all.push(h);
            at = next;
        }
    }
    Some((version, all))
}

/// The file with its `chunkCount` made true, or `None` when there is nothing to correct (or the
/// file is not a single-part scanline file this understands).
pub fn with_true_chunk_count(bytes: &[u8]) -> Option<Vec<u8>> {
    let (version, all) = headers(bytes)?;
    if version & (TILED | DEEP | MULTI_PART) != 0 {
        return None;
    }
    let h = all.first()?;
    let count_at = h.chunk_count_at?;
    let truth = u32::try_from(h.chunks()?).ok()?;
    let stated = u32::from_le_bytes(word(bytes, count_at)?);
    (stated != truth).then(|| {
        let mut fixed = bytes.to_vec();
        fixed[count_at..count_at + 4].copy_from_slice(&truth.to_le_bytes());
        fixed
    })
}

/// Refuses a file whose headers ask for more than `max_samples` samples (pixels times channels,
/// over all parts), or for more scanline chunks than the file's length could index.
pub fn check_size(bytes: &[u8], max_samples: u64) -> Result<(), String> {
    let Some((_, all)) = headers(bytes) else {
        // Not understood here: the crate's own reading decides (and reports) what is wrong.
        return Ok(());
    };
    let mut samples = 0u64;
    let mut chunks = 0u64;
    for h in &all {
        if h.inverted_window {
            return Err("a data window's maximum is below its minimum".into());
        }
        let Some((w, rows)) = h.size else { continue };
        samples = samples.saturating_add(w.saturating_mul(rows).saturating_mul(h.channels.max(1)));
        if !h.tiled {
            chunks = chunks.saturating_add(h.chunks().unwrap_or(0));
        }
    }
    if samples > max_samples {
        return Err(format!(
            "its headers ask for {samples} samples, more than this tool reads ({max_samples})"
        ));
    }
    if chunks.saturating_mul(8) > bytes.len() as u64 {
        return Err(format!(
            "its headers ask for {chunks} chunks, more than a file of {} bytes can index",
            bytes.len()
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A header of `attributes` (name, type, value) after the magic and a version word.
    fn header(version: u32, attributes: &[(&str, &str, Vec<u8>)]) -> Vec<u8> {
        let mut b = MAGIC.to_vec();
        b.extend(version.to_le_bytes());
        for (name, kind, value) in attributes {
            b.extend(name.as_bytes());
            b.push(0);
            b.extend(kind.as_bytes());
            b.push(0);
            b.extend((value.len() as i32).to_le_bytes());
            b.extend(value);
        }
        b.push(0);
        b
    }

    fn window(rows: i32) -> Vec<u8> {
        [0, 0, 63, rows - 1]
            .iter()
            .flat_map(|v: &i32| v.to_le_bytes())
            .collect()
    }

    #[test]
    fn a_stale_chunk_count_is_corrected_and_a_true_one_left_alone() {
        // 36 rows under PIZ (32 lines per chunk) are 2 chunks; the header says 3 (ZIP's count).
        let stale = header(
            2,
            &[
                ("chunkCount", "int", 3i32.to_le_bytes().to_vec()),
                ("compression", "compression", vec![4]),
                ("dataWindow", "box2i", window(36)),
            ],
        );
        let fixed = with_true_chunk_count(&stale).expect("the count is stale");
        assert_eq!(fixed.len(), stale.len());
        let at = 8 + "chunkCount\0int\0".len() + 4;
        assert_eq!(fixed[at..at + 4], 2i32.to_le_bytes());
        assert_eq!(with_true_chunk_count(&fixed), None);
        // Under no compression each row is a chunk.
        let none = header(
            2,
            &[
                ("chunkCount", "int", 3i32.to_le_bytes().to_vec()),
                ("compression", "compression", vec![0]),
                ("dataWindow", "box2i", window(36)),
            ],
        );
        let fixed = with_true_chunk_count(&none).unwrap();
        assert_eq!(fixed[at..at + 4], 36i32.to_le_bytes());
        // Multi-part files need their counts as written; cut headers are left to the reader.
        let multi = header(
            2 | MULTI_PART,
            &[("chunkCount", "int", 3i32.to_le_bytes().to_vec())],
        );
        assert_eq!(with_true_chunk_count(&multi), None);
        assert_eq!(with_true_chunk_count(&stale[..20]), None);
    }

    #[test]
    fn windows_a_file_cannot_hold_are_refused() {
        let file = |x_min: i32, rows: i32| {
            let window: Vec<u8> = [x_min, 0, 63, rows - 1]
                .iter()
                .flat_map(|v| v.to_le_bytes())
                .collect();
            let mut h = header(
                2,
                &[
                    ("compression", "compression", vec![3]),
                    ("dataWindow", "box2i", window),
                ],
            );
            h.resize(h.len() + 64, 0);
            h
        };
        assert_eq!(check_size(&file(0, 36), 1 << 20), Ok(()));
        // A flipped bit made x_min 2^29: the crate sized its buffers from the inverted window.
        assert!(
            check_size(&file(1 << 29, 36), 1 << 20)
                .unwrap_err()
                .contains("below")
        );
        // More samples than allowed, and more chunks than the file could index.
        assert!(
            check_size(&file(0, 36), 1000)
                .unwrap_err()
                .contains("samples")
        );
        assert!(
            check_size(&file(0, 1 << 20), 1 << 40)
                .unwrap_err()
                .contains("chunks")
        );
    }
}
