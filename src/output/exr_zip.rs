//! OpenEXR's ZIP compression of scanline chunks, on all threads.
//!
//! A ZIP chunk holds 16 scanlines (OpenEXR "Technical Introduction", "Data Compression"): each
//! line's channels in header order, samples little-endian; the bytes split into their even and
//! odd halves, each byte replaced by its difference to the one before plus 128 (the library's
//! predictor, `ImfZip.cpp`), then zlib. A chunk whose compressed bytes would not be smaller is
//! stored as it was, which readers recognise by its size.
//!
//! The exr crate compresses with miniz_oxide on a thread pool of its own, made for each file;
//! libdeflate at the same level is about three times faster on our films (640x360 stereo, 32-bit:
//! 42 ms against 124 ms on one core, 3.52 MB either way), and the chunks here are compressed on
//! the render's own threads. Each chunk depends only on its pixels, so the file is the same
//! whatever the thread count.

use rayon::prelude::*;
use std::cell::RefCell;

/// Scanlines in one ZIP chunk (OpenEXR's `ZIP_COMPRESSION`).
pub const LINES_PER_CHUNK: usize = 16;

/// OpenEXR's default ZIP level since 3.1.3 (its `setDefaultZipCompressionLevel`, lowered from 6,
/// where it compressed twice as fast for files about as small).
const LEVEL: i32 = 4;

thread_local! {
    // A level-4 compressor holds about half a megabyte of tables: one a thread, not one a chunk.
    static COMPRESSOR: RefCell<Option<libdeflater::Compressor>> = const { RefCell::new(None) };
}

/// The chunks of an image of `rows` scanlines, top to bottom. `row_bytes(y, out)` appends
/// scanline `y`'s bytes as the file stores them uncompressed.
pub fn chunks(rows: usize, row_bytes: impl Fn(usize, &mut Vec<u8>) + Sync) -> Vec<Vec<u8>> {
    (0..rows.div_ceil(LINES_PER_CHUNK))
        .into_par_iter()
        .map(|chunk| {
            let mut raw = Vec::new();
            let first = chunk * LINES_PER_CHUNK;
            for y in first..(first + LINES_PER_CHUNK).min(rows) {
                row_bytes(y, &mut raw);
            }
            compress(&raw)
        })
        .collect()
}

/// One chunk's stored bytes.
fn compress(raw: &[u8]) -> Vec<u8> {
    let predicted = predict(raw);
    let packed = COMPRESSOR.with_borrow_mut(|slot| {
        let compressor = slot.get_or_insert_with(|| {
            libdeflater::Compressor::new(
                libdeflater::CompressionLvl::new(LEVEL).expect("a level libdeflate offers"),
            )
        });
        let mut out = vec![0; compressor.zlib_compress_bound(predicted.len())];
        // The bound is libdeflate's own worst case, so the output always fits.
        let n = compressor
            .zlib_compress(&predicted, &mut out)
            .expect("a buffer of libdeflate's bound");
        out.truncate(n);
        out
    });
    if packed.len() < raw.len() {
        packed
    } else {
        raw.to_vec()
    }
}

/// The bytes split into even and odd halves, then each byte's difference to the one before.
fn predict(raw: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(raw.len());
    out.extend(raw.iter().step_by(2));
    out.extend(raw.iter().skip(1).step_by(2));
    let mut previous = out.first().copied().unwrap_or(0);
    for b in out.iter_mut().skip(1) {
        let value = *b;
        *b = value.wrapping_sub(previous).wrapping_add(128);
        previous = value;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// OpenEXR's reordering and predictor as its `ImfZip.cpp` writes them: two cursors taking
    /// bytes in turn, then differences in integers.
    fn predict_as_openexr(raw: &[u8]) -> Vec<u8> {
        let mut t = vec![0u8; raw.len()];
        let (mut t1, mut t2) = (0, raw.len().div_ceil(2));
        let mut bytes = raw.iter();
        while let Some(&b) = bytes.next() {
            t[t1] = b;
            t1 += 1;
            let Some(&b) = bytes.next() else { break };
            t[t2] = b;
            t2 += 1;
        }
        let mut p = t.first().copied().unwrap_or(0) as i32;
        for v in t.iter_mut().skip(1) {
            let d = *v as i32 - p + (128 + 256);
            p = *v as i32;
            *v = d as u8;
        }
        t
    }

    #[test]
    fn the_predictor_is_openexrs_for_even_odd_and_empty_lengths() {
        for n in [0usize, 1, 2, 3, 7, 64, 1001] {
            let raw: Vec<u8> = (0..n).map(|i| (i * 37 % 251) as u8).collect();
            assert_eq!(predict(&raw), predict_as_openexr(&raw), "{n} bytes");
        }
    }

    #[test]
    fn a_chunk_that_does_not_shrink_is_stored_as_it_was() {
        // Bytes from a multiplicative generator: deflate cannot shorten them.
        let mut x = 0x2545_f491u32;
        let raw: Vec<u8> = (0..4096)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 17;
                x ^= x << 5;
                x as u8
            })
            .collect();
        assert_eq!(compress(&raw), raw);
        let flat = vec![7u8; 4096];
        assert!(compress(&flat).len() < flat.len());
    }

    #[test]
    fn chunks_hold_sixteen_lines_and_the_last_one_the_rest() {
        let rows = 2 * LINES_PER_CHUNK + 3;
        let stored = chunks(rows, |y, out| out.extend_from_slice(&[y as u8; 64]));
        assert_eq!(stored.len(), 3);
        let mut inflater = libdeflater::Decompressor::new();
        let mut last = vec![0; 3 * 64];
        let n = inflater.zlib_decompress(&stored[2], &mut last).unwrap();
        assert_eq!(n, 3 * 64);
        let expected: Vec<u8> = (32..35u8).flat_map(|y| [y; 64]).collect();
        assert_eq!(last, predict(&expected));
    }
}
