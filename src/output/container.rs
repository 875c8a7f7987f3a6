//! Whether a video file the encoder says it wrote is whole: an encoder can exit 0 having
//! written a truncated file (ffmpeg does when the disk fills). The top-level structure of the
//! container is walked, and every part must fit the file exactly.

/// Checks an MP4/MOV (ISO base media, ISO/IEC 14496-12) or Matroska/WebM file's top level;
/// the error says what is missing or cut off.
pub fn check_whole(bytes: &[u8], matroska: bool) -> Result<(), String> {
    if matroska {
        check_matroska(bytes)
    } else {
        check_iso_media(bytes)
    }
}

fn be(bytes: &[u8], at: usize, n: usize) -> Option<u64> {
    bytes
        .get(at..at + n)
        .map(|b| b.iter().fold(0u64, |v, &x| (v << 8) | x as u64))
}

/// ISO base media: a sequence of boxes (32-bit size, 4-character type; size 1: a 64-bit size
/// follows; size 0: to the end of the file) covering the file exactly, with a `moov` box (the
/// index a player needs, written last by ffmpeg).
fn check_iso_media(bytes: &[u8]) -> Result<(), String> {
    let mut at = 0usize;
    let mut moov = false;
    while at < bytes.len() {
        let size32 = be(bytes, at, 4).ok_or("cut off inside a box header")?;
        let kind = bytes
            .get(at + 4..at + 8)
            .ok_or("cut off inside a box header")?;
        let size = match size32 {
            0 => (bytes.len() - at) as u64,
            1 => be(bytes, at + 8, 8).ok_or("cut off inside a box header")?,
            s => s,
        };
        if size < 8 || at as u64 + size > bytes.len() as u64 {
            return Err(format!(
                "the '{}' box at byte {at} runs past the end of the file",
                String::from_utf8_lossy(kind)
            ));
        }
        moov |= kind == b"moov";
        at += size as usize;
    }
    if moov {
        Ok(())
    } else {
        Err("no 'moov' box: the file was not finished".into())
    }
}

/// An EBML variable-length integer at `at`: (value, length); `None` for an unknown size.
fn vint(bytes: &[u8], at: usize, keep_marker: bool) -> Option<(Option<u64>, usize)> {
    let first = *bytes.get(at)?;
    let len = first.leading_zeros() as usize + 1;
    if len > 8 {
        return None;
    }
    let raw = be(bytes, at, len)?;
    let value = if keep_marker {
        raw
    } else {
        raw & ((1u64 << (7 * len)) - 1)
    };
    let unknown = !keep_marker && value == (1u64 << (7 * len)) - 1;
    Some(((!unknown).then_some(value), len))
}

/// Matroska/WebM: the EBML header element, then a Segment whose size (when written) ends
/// exactly at the end of the file.
fn check_matroska(bytes: &[u8]) -> Result<(), String> {
    const EBML: u64 = 0x1A45_DFA3;
    const SEGMENT: u64 = 0x1853_8067;
    let element = |at: usize| -> Result<(u64, Option<u64>, usize), String> {
        let (id, id_len) = vint(bytes, at, true).ok_or("cut off inside an element header")?;
        let (size, size_len) =
            vint(bytes, at + id_len, false).ok_or("cut off inside an element header")?;
        Ok((id.unwrap_or(0), size, at + id_len + size_len))
    };
    let (id, size, body) = element(0)?;
    if id != EBML {
        return Err("no EBML header: not a Matroska file".into());
    }
    let next = body + size.ok_or("the EBML header has no size")? as usize;
    let (id, size, body) = element(next)?;
    if id != SEGMENT {
        return Err("no Segment after the EBML header".into());
    }
    match size {
        Some(s) if body as u64 + s != bytes.len() as u64 => Err(format!(
            "the Segment should end at byte {}, but the file has {} bytes",
            body as u64 + s,
            bytes.len()
        )),
        _ if body >= bytes.len() => Err("the Segment is empty".into()),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn iso_box(kind: &[u8; 4], body: usize) -> Vec<u8> {
        let mut b = ((8 + body) as u32).to_be_bytes().to_vec();
        b.extend_from_slice(kind);
        b.extend(std::iter::repeat_n(0u8, body));
        b
    }

    #[test]
    fn a_whole_mp4_passes_and_a_cut_or_unfinished_one_does_not() {
        let whole = [
            iso_box(b"ftyp", 16),
            iso_box(b"mdat", 100),
            iso_box(b"moov", 40),
        ]
        .concat();
        assert!(check_whole(&whole, false).is_ok());
        assert!(check_whole(&whole[..whole.len() - 1], false).is_err());
        let unfinished = [iso_box(b"ftyp", 16), iso_box(b"mdat", 100)].concat();
        assert!(
            check_whole(&unfinished, false)
                .unwrap_err()
                .contains("moov")
        );
    }

    #[test]
    fn a_matroska_segment_must_end_with_the_file() {
        // EBML header (ID 1A45DFA3, size 1, one byte of body), then a Segment of 3 bytes.
        let mut mkv = vec![
            0x1A, 0x45, 0xDF, 0xA3, 0x81, 0x00, 0x18, 0x53, 0x80, 0x67, 0x83,
        ];
        mkv.extend([1, 2, 3]);
        assert!(check_whole(&mkv, true).is_ok());
        assert!(check_whole(&mkv[..mkv.len() - 1], true).is_err());
        assert!(check_whole(b"not a video at all", true).is_err());
    }
}
