//! Single-part scanline EXR files whose `chunkCount` attribute disagrees with their data window
//! and compression. The OpenEXR library reads such files (it needs `chunkCount` only in
//! multi-part files and counts the chunks itself otherwise); the exr crate refuses them ("chunk
//! count not matching data size"). OpenEXR 3.1's `exrmultiview` writes them: it copies the first
//! input's header, `chunkCount` included, and then changes the compression (by default to PIZ,
//! 32 lines per chunk), so every file it makes from ours (ZIP, 16 lines per chunk) lies. The
//! attribute is corrected in a copy of the bytes before the crate reads them.
//!
//! Layout (OpenEXR "File Layout"): magic, a version word whose flags say tiled (bit 9), deep
//! (bit 11) and multi-part (bit 12), then attributes as `name\0 type\0 size:i32 value` up to an
//! empty name.

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

/// The file with its `chunkCount` made true, or `None` when there is nothing to correct (or the
/// file is not a single-part scanline file this understands).
pub fn with_true_chunk_count(bytes: &[u8]) -> Option<Vec<u8>> {
    let word = |at: usize| bytes.get(at..at + 4).map(|b| [b[0], b[1], b[2], b[3]]);
    if word(0)? != MAGIC {
        return None;
    }
    let version = u32::from_le_bytes(word(4)?);
    if version & (TILED | DEEP | MULTI_PART) != 0 {
        return None;
    }
    let (mut count_at, mut rows, mut compression) = (None, None, None);
    let mut at = 8;
    loop {
        let name_end = at + bytes.get(at..)?.iter().position(|&b| b == 0)?;
        if name_end == at {
            break;
        }
        let type_end = name_end + 1 + bytes.get(name_end + 1..)?.iter().position(|&b| b == 0)?;
        let size = i32::from_le_bytes(word(type_end + 1)?);
        let value = type_end + 5;
        let size = usize::try_from(size).ok()?;
        let v = bytes.get(value..value.checked_add(size)?)?;
        match (&bytes[at..name_end], &bytes[name_end + 1..type_end]) {
            (b"chunkCount", b"int") if size == 4 => count_at = Some(value),
            (b"compression", b"compression") if size == 1 => compression = Some(v[0]),
            (b"dataWindow", b"box2i") if size == 16 => {
                let y =
                    |k: usize| i64::from(i32::from_le_bytes([v[k], v[k + 1], v[k + 2], v[k + 3]]));
                rows = Some(y(12) - y(4) + 1);
            }
            _ => {}
        }
        at = value + size;
    }
    let (count_at, rows) = (count_at?, u64::try_from(rows?).ok()?);
    let truth = u32::try_from(rows.div_ceil(lines_per_chunk(compression?)?)).ok()?;
    let stated = u32::from_le_bytes(word(count_at)?);
    (stated != truth).then(|| {
        let mut fixed = bytes.to_vec();
        fixed[count_at..count_at + 4].copy_from_slice(&truth.to_le_bytes());
        fixed
    })
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
}
