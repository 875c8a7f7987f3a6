//! `output/` turns linear stereo frames into files: EXR (multi-view), PNG, and the colour pipeline
//! every 8-bit output shares. It never sees a ray or a scene. Every file is written atomically:
//! into a temporary file beside the target, then renamed, so a failed or interrupted run never
//! leaves a half-written image under the final name.

pub mod anaglyph;
mod color;
mod container;
pub mod exr;
mod exr_header;
mod exr_zip;
mod fed_process;
pub mod image;
mod layout;
mod planes;
mod png;
mod pseudo;
mod read;
mod table;
pub mod video;
mod wobble;

pub use anaglyph::{Method as AnaglyphMethod, Space as AnaglyphSpace, anaglyph as make_anaglyph};
pub use color::{Display, ToneMap};
pub use exr::{write_multiview, write_single_view};
pub use image::Image;
pub use layout::{Order, interlaced, side_by_side, top_bottom};
pub use planes::Planes;
pub use png::{read_rgb8, to_srgb8, write_png, write_rgb8};
pub use pseudo::{Channels, PseudoStereo};
pub use read::read_planes;
pub use table::{CsvStream, csv_line, read_csv, write_csv};
pub use video::{StereoPacking, VideoEncoder, check_path as check_video_path, ffmpeg_available};
pub use wobble::{Mode as WobbleMode, pivot_shift, schedule as wobble_schedule, write_gif};

use crate::error::{Error, Result};
use std::io::{BufWriter, Write};
use std::path::Path;

/// FNV-1a (32-bit) of this machine's host name: the part of a temporary file's name that tells
/// which machine wrote it. Render-farm workers on several machines write into one shared folder,
/// and a process id means something only on its own machine.
pub fn host_id() -> u32 {
    static ID: std::sync::OnceLock<u32> = std::sync::OnceLock::new();
    *ID.get_or_init(|| {
        let name = std::fs::read_to_string("/proc/sys/kernel/hostname")
            .or_else(|_| std::env::var("HOSTNAME"))
            .unwrap_or_default();
        // FNV-1a's 32-bit offset basis and prime (Fowler, Noll, Vo).
        name.trim().bytes().fold(0x811c_9dc5, |h: u32, b| {
            (h ^ u32::from(b)).wrapping_mul(0x0100_0193)
        })
    })
}

/// `PID-HOST` (process id, `host_id` in 8 hex digits): who is writing a temporary file.
pub fn temporary_tag() -> String {
    format!("{}-{:08x}", std::process::id(), host_id())
}

/// The temporary sibling a file is written into before it is renamed into place
/// (`.NAME.tmp-PID-HOST`, which the stale-temporary scan knows), its folder created.
pub fn temporary_beside(path: &Path) -> Result<std::path::PathBuf> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy())
        .unwrap_or_default();
    Ok(dir.join(format!(".{name}.tmp-{}", temporary_tag())))
}

/// Writes a file through `fill` into a temporary sibling, then renames it into place.
pub fn write_atomic(
    path: &Path,
    fill: impl FnOnce(&mut BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<()> {
    let tmp = temporary_beside(path)?;
    let result = (|| {
        let file = std::fs::File::create(&tmp)?;
        let mut w = BufWriter::new(file);
        fill(&mut w)?;
        w.flush()?;
        w.get_ref().sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(Error::io(path, e));
    }
    Ok(())
}
