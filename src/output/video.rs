//! Video files through the ffmpeg executable: 8-bit sRGB frames are piped to it as raw RGB, and it
//! encodes H.264 (`.mp4`, `.mov`, `.mkv`) or VP9 (`.webm`) at the pipeline's frame rate. The file is
//! written under a temporary name and renamed when ffmpeg succeeds, like every other output.

use super::fed_process::{FedProcess, stall_limit};
use crate::error::{Error, Result};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// Whether an `ffmpeg` executable runs.
pub fn ffmpeg_available() -> bool {
    Command::new("ffmpeg")
        .arg("-version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// Checks a video path's container before any rendering.
pub fn check_path(path: &Path) -> std::result::Result<(), String> {
    match path.extension().and_then(|e| e.to_str()) {
        Some("mp4" | "mov" | "mkv" | "webm") => Ok(()),
        _ => Err(format!(
            "video path '{}' must end in .mp4, .mov, .mkv or .webm",
            path.display()
        )),
    }
}

/// How a video's frames hold both eyes, for the container's and the codec's stereo signalling.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StereoPacking {
    /// Left and right halves; `right_first` when the right eye is on the left (cross-eyed).
    SideBySide { right_first: bool },
    /// Top and bottom halves; `right_first` when the right eye is on top.
    TopBottom { right_first: bool },
    /// Alternate rows, the first row from the left eye unless `right_first`.
    Rows { right_first: bool },
}

impl StereoPacking {
    /// Matroska's `StereoMode` as FFmpeg's Matroska muxer names it (its `stereo_mode` tag).
    fn matroska_mode(self) -> &'static str {
        match self {
            StereoPacking::SideBySide { right_first: false } => "left_right",
            StereoPacking::SideBySide { right_first: true } => "right_left",
            StereoPacking::TopBottom { right_first: false } => "top_bottom",
            StereoPacking::TopBottom { right_first: true } => "bottom_top",
            StereoPacking::Rows { right_first: false } => "row_interleaved_lr",
            StereoPacking::Rows { right_first: true } => "row_interleaved_rl",
        }
    }

    /// The H.264 frame-packing arrangement SEI type (ITU-T H.264 table D-8: 2 rows, 3 side by
    /// side, 4 top and bottom). x264 writes it with frame 0 as the left view, so packings with
    /// the right eye first get none rather than a wrong one.
    fn h264_frame_packing(self) -> Option<u8> {
        match self {
            StereoPacking::Rows { right_first: false } => Some(2),
            StereoPacking::SideBySide { right_first: false } => Some(3),
            StereoPacking::TopBottom { right_first: false } => Some(4),
            _ => None,
        }
    }
}

pub struct VideoEncoder {
    path: PathBuf,
    tmp: PathBuf,
    fps: f32,
    stereo: Option<StereoPacking>,
    child: Option<(FedProcess, usize, usize)>,
}

impl VideoEncoder {
    pub fn new(path: PathBuf, fps: f32) -> VideoEncoder {
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let tmp = path.with_file_name(format!(".tmp-{}-{name}", super::temporary_tag()));
        VideoEncoder {
            path,
            tmp,
            fps,
            stereo: None,
            child: None,
        }
    }

    /// Signals the frames' stereo packing in the file: Matroska and WebM get the `StereoMode`
    /// element, H.264 (every container but WebM) the frame-packing arrangement SEI, which
    /// FFmpeg and stereo players read as the stream's stereo 3D side data.
    pub fn with_stereo(mut self, packing: Option<StereoPacking>) -> VideoEncoder {
        self.stereo = packing;
        self
    }

    /// Appends one frame (RGB, 8 bits per channel); the first frame fixes the size.
    pub fn push(&mut self, width: usize, height: usize, rgb: &[u8]) -> Result<()> {
        if self.child.is_none() {
            if let Some(dir) = self.tmp.parent() {
                std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
            }
            let webm = self.path.extension().is_some_and(|e| e == "webm");
            let matroska = webm || self.path.extension().is_some_and(|e| e == "mkv");
            let codec: &[&str] = if webm {
                &["-c:v", "libvpx-vp9", "-b:v", "0", "-crf", "30"]
            } else {
                &["-c:v", "libx264", "-crf", "18", "-preset", "medium"]
            };
            let mut stereo: Vec<String> = Vec::new();
            if let Some(packing) = self.stereo {
                if let Some(kind) = packing.h264_frame_packing().filter(|_| !webm) {
                    stereo.extend(["-x264-params".into(), format!("frame-packing={kind}")]);
                }
                if matroska {
                    stereo.extend([
                        "-metadata:s:v:0".into(),
                        format!("stereo_mode={}", packing.matroska_mode()),
                    ]);
                }
            }
            let mut command = Command::new("ffmpeg");
            // In a process group of its own, so that Ctrl-C at the terminal reaches only
            // stereotrace, which then stops ffmpeg itself and removes its temporary file.
            #[cfg(unix)]
            std::os::unix::process::CommandExt::process_group(&mut command, 0);
            command
                .args([
                    "-y",
                    "-loglevel",
                    "error",
                    "-f",
                    "rawvideo",
                    "-pix_fmt",
                    "rgb24",
                    "-s",
                ])
                .arg(format!("{width}x{height}"))
                .arg("-r")
                .arg(format!("{}", self.fps))
                .args(["-i", "-"])
                .args(codec)
                .args(&stereo)
                // yuv420p for players' sake; it needs even sizes, so pad odd ones by a pixel.
                .args([
                    "-pix_fmt",
                    "yuv420p",
                    "-vf",
                    "pad=ceil(iw/2)*2:ceil(ih/2)*2",
                ])
                // No random segment ID or date in Matroska/WebM: the same frames give the same
                // file, so a farm's assembled video is byte-identical to a single run's.
                .args(["-fflags", "+bitexact"])
                .arg(&self.tmp);
            let child = FedProcess::spawn(&mut command, stall_limit()).map_err(|e| {
                Error::input(
                    &self.path,
                    format!("cannot start ffmpeg (is it installed?): {e}"),
                )
            })?;
            self.child = Some((child, width, height));
        }
        let (child, w, h) = self.child.as_mut().expect("encoder started above");
        if (*w, *h) != (width, height) {
            return Err(Error::input(&self.path, "video frames changed size"));
        }
        let fed = child.feed(rgb.to_vec());
        if fed.is_err() {
            let _ = std::fs::remove_file(&self.tmp);
        }
        fed.map_err(|e| Error::io(&self.path, e))
    }

    /// Closes the stream, waits for ffmpeg and moves the file into place.
    pub fn finish(mut self) -> Result<Option<PathBuf>> {
        let Some((child, _, _)) = self.child.take() else {
            return Ok(None);
        };
        let (status, stderr) = child.finish().map_err(|e| {
            let _ = std::fs::remove_file(&self.tmp);
            Error::io(&self.path, e)
        })?;
        if !status.success() {
            let _ = std::fs::remove_file(&self.tmp);
            // Writing failed, not the input: status 1.
            return Err(Error::io(
                &self.path,
                std::io::Error::other(format!("ffmpeg failed: {stderr}")),
            ));
        }
        // ffmpeg can exit 0 having written a cut-off file (a full disk): the container must be
        // whole before the file takes its name.
        let matroska = self
            .path
            .extension()
            .is_some_and(|e| e == "mkv" || e == "webm");
        let whole = std::fs::read(&self.tmp)
            .map_err(|e| e.to_string())
            .and_then(|bytes| super::container::check_whole(&bytes, matroska));
        if let Err(why) = whole {
            // Older ffmpeg (Debian 12's 5.1) exits 0 without a word when the disk fills: ask
            // the disk, while the cut-off file still holds its space.
            let full = disk_full_beside(&self.tmp).map_or(String::new(), |e| {
                format!("; the disk it writes to is full: {e}")
            });
            let _ = std::fs::remove_file(&self.tmp);
            return Err(Error::io(
                &self.path,
                std::io::Error::other(format!(
                    "ffmpeg exited 0 but wrote a broken video: {why}{full}"
                )),
            ));
        }
        std::fs::rename(&self.tmp, &self.path).map_err(|e| Error::io(&self.path, e))?;
        Ok(Some(self.path.clone()))
    }
}

/// The error of writing (and syncing) a small file beside `path` when it is a full disk's;
/// the file is removed either way.
fn disk_full_beside(path: &Path) -> Option<std::io::Error> {
    use std::io::Write;
    let probe = path.with_file_name(format!(".stereotrace-space-probe-{}", std::process::id()));
    let written = std::fs::File::create(&probe)
        .and_then(|mut f| f.write_all(&[0u8; 65536]).and_then(|()| f.sync_all()));
    let _ = std::fs::remove_file(&probe);
    written
        .err()
        .filter(|e| e.kind() == std::io::ErrorKind::StorageFull)
}

impl Drop for VideoEncoder {
    fn drop(&mut self) {
        // An encoder dropped without finish (an error elsewhere) leaves no partial file.
        if let Some((child, _, _)) = self.child.take() {
            drop(child);
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}
