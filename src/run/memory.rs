//! What a render will hold in memory, estimated from the scene and the pipeline before anything
//! large is allocated, and the limit it is held to (`--max-memory`; by default three quarters of
//! the machine's memory). A small file that places one big mesh in a thousand nodes, or a film
//! of 16384x16384, is refused with the estimate and the limit instead of aborting on allocation
//! half-way through a frame (or being killed by the kernel).
//!
//! The constants are peak resident sizes measured on the release build (2 threads), with a
//! margin; they are upper estimates of the common case, not bounds.

use super::frame_loop::views_needed;
use crate::error::{Error, Result};
use crate::pipeline::LoadedPipeline;
use crate::render::EyeReuse;
use std::fmt;
use std::path::Path;

/// Posed geometry, the kd-tree and its build's scratch, per triangle after instancing. Measured:
/// one 99k-triangle grid placed in 10 and 20 nodes peaks at 331 and 702 MB (370 bytes per
/// added triangle).
pub const BYTES_PER_TRIANGLE: u64 = 400;
/// Per pixel of each traced view: the radiance film (12 bytes), tiles, and the outputs' 8-bit
/// and float copies. Measured with a PNG and a multi-view EXR output: 31.5 bytes per added view
/// pixel from 1024x1024 to 2048x2048, and a peak of 4.10 GiB at 8192x8192 (32.8 per view pixel,
/// the process's own memory included).
const BYTES_PER_VIEW_PIXEL: u64 = 36;
/// Under `eye_reuse = "reproject"`, per pixel of the source view (its 64-byte record and the
/// target's plan) and per camera sample (the 12 bytes a pixel across a depth edge keeps of each,
/// every sample counted). Measured on `pipelines/diffuse.toml` against `off`: 119 bytes per
/// added pixel at 4 spp (2048x2048 against 1024x1024), 256 at 16 spp (1024x1024).
const BYTES_PER_KEPT_PIXEL: u64 = 80;
const BYTES_PER_KEPT_SAMPLE: u64 = 12;
/// Per pixel of each frame a whole-range wobble GIF holds until the end: its RGB frame and the
/// RGBA copy the encoder quantises.
const BYTES_PER_HELD_PIXEL: u64 = 7;

/// The estimate, by part.
#[derive(Clone, Copy, Debug)]
pub struct MemoryEstimate {
    pub triangles: u64,
    pub geometry: u64,
    pub film: u64,
    /// Frames kept for outputs of the whole range.
    pub held: u64,
}

impl MemoryEstimate {
    pub fn of(p: &LoadedPipeline) -> MemoryEstimate {
        let r = &p.spec.render;
        let pixels = u64::from(r.width) * u64::from(r.height);
        let views = views_needed(p, &p.rig_views(), 0).len() as u64;
        let kept = match r.eye_reuse {
            EyeReuse::Reproject | EyeReuse::ReprojectRadiance => {
                pixels * (BYTES_PER_KEPT_PIXEL + u64::from(r.spp) * BYTES_PER_KEPT_SAMPLE)
            }
            EyeReuse::Off | EyeReuse::Paired => 0,
        };
        let frames = u64::from(p.spec.frames.end - p.spec.frames.start) + 1;
        let whole_range_gifs = p.spec.outputs.iter().filter(|o| o.single_file()).count() as u64;
        let triangles = p.scene.placed_triangle_count() as u64;
        MemoryEstimate {
            triangles,
            geometry: triangles.saturating_mul(BYTES_PER_TRIANGLE),
            film: pixels * views * BYTES_PER_VIEW_PIXEL + kept,
            held: whole_range_gifs
                .saturating_mul(frames)
                .saturating_mul(pixels * BYTES_PER_HELD_PIXEL),
        }
    }

    pub fn total(&self) -> u64 {
        self.geometry
            .saturating_add(self.film)
            .saturating_add(self.held)
    }

    /// Refuses (bad input, exit 2) when the estimate passes `limit`.
    pub fn check(&self, file: &Path, limit: Option<u64>) -> Result<()> {
        match limit {
            Some(limit) if self.total() > limit => Err(Error::input(
                file,
                format!(
                    "this render would need about {} of memory ({self}), over the limit of {}; \
                     lower the resolution or samples, place fewer copies of the meshes, or raise \
                     the limit with --max-memory",
                    Bytes(self.total()),
                    Bytes(limit)
                ),
            )),
            _ => Ok(()),
        }
    }
}

impl fmt::Display for MemoryEstimate {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} triangles after instancing: {}; film and outputs: {}",
            self.triangles,
            Bytes(self.geometry),
            Bytes(self.film)
        )?;
        if self.held > 0 {
            write!(
                f,
                "; frames held for whole-range GIFs: {}",
                Bytes(self.held)
            )?;
        }
        Ok(())
    }
}

/// A byte count in binary units, as `--max-memory` takes them.
pub struct Bytes(pub u64);

impl fmt::Display for Bytes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
        let mut v = self.0 as f64;
        let mut unit = 0;
        while v >= 1024.0 && unit + 1 < UNITS.len() {
            v /= 1024.0;
            unit += 1;
        }
        if unit == 0 {
            write!(f, "{} B", self.0)
        } else {
            write!(f, "{v:.1} {}", UNITS[unit])
        }
    }
}

/// `--max-memory` as given: a limit in bytes, or none.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryLimit(pub Option<u64>);

/// Parses `--max-memory`: a byte count with an optional binary suffix (`512M`, `16G`, `1.5T`;
/// K, M, G, T are powers of 1024), or `none` for no limit.
pub fn parse_memory_limit(s: &str) -> std::result::Result<MemoryLimit, String> {
    let t = s.trim();
    if t.eq_ignore_ascii_case("none") {
        return Ok(MemoryLimit(None));
    }
    let upper = t.to_ascii_uppercase();
    let digits = upper.trim_end_matches('B').trim_end_matches('I').trim_end();
    let (number, scale) = match digits.chars().last() {
        Some('K') => (&digits[..digits.len() - 1], 1u64 << 10),
        Some('M') => (&digits[..digits.len() - 1], 1 << 20),
        Some('G') => (&digits[..digits.len() - 1], 1 << 30),
        Some('T') => (&digits[..digits.len() - 1], 1 << 40),
        _ => (digits, 1),
    };
    let value: f64 = number
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a size such as 512M, 16G or none"))?;
    if !(value.is_finite() && value > 0.0) {
        return Err(format!("'{s}': a memory limit must be a positive size"));
    }
    Ok(MemoryLimit(Some(
        (value * scale as f64).min(u64::MAX as f64) as u64,
    )))
}

/// The default limit: three quarters of the machine's memory (`MemTotal` of `/proc/meminfo`),
/// leaving room for the system and the page cache the outputs go through; none where the
/// machine does not say.
pub fn default_memory_limit() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let kib: u64 = info
        .lines()
        .find_map(|l| l.strip_prefix("MemTotal:"))?
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    Some(kib * 1024 / 4 * 3)
}

/// The limit a command runs under: the one given, else the default.
pub fn memory_limit(given: Option<MemoryLimit>) -> Option<u64> {
    given.map_or_else(default_memory_limit, |g| g.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_binary_suffixes() {
        assert_eq!(parse_memory_limit("512M"), Ok(MemoryLimit(Some(512 << 20))));
        assert_eq!(parse_memory_limit("16G"), Ok(MemoryLimit(Some(16 << 30))));
        assert_eq!(parse_memory_limit("16GiB"), Ok(MemoryLimit(Some(16 << 30))));
        assert_eq!(parse_memory_limit("1.5k"), Ok(MemoryLimit(Some(1536))));
        assert_eq!(parse_memory_limit("4096"), Ok(MemoryLimit(Some(4096))));
        assert_eq!(parse_memory_limit("none"), Ok(MemoryLimit(None)));
        for bad in ["", "G", "-1G", "0", "nanG", "lots"] {
            assert!(parse_memory_limit(bad).is_err(), "{bad}");
        }
        assert_eq!(Bytes(3 << 29).to_string(), "1.5 GiB");
        assert_eq!(Bytes(12).to_string(), "12 B");
    }
}
