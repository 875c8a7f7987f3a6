//! A disk that fills during a render: the run exits 1 naming the file it could not write and
//! the cause, and nothing half-written stays (every image left decodes, no temporary, no cut-off
//! video). The disks are small tmpfs mounts, so the test needs root (and mount rights); without
//! them it fails, unless `STEREOTRACE_SKIP_TMPFS=1` skips it knowingly.

mod common;

use common::{files_under, scratch};
use std::path::{Path, PathBuf};
use std::process::Command;

/// A tmpfs of `size` mounted at `dir`, unmounted when dropped.
struct SmallDisk(PathBuf);

impl SmallDisk {
    fn mount(dir: &Path, size: &str) -> Option<SmallDisk> {
        std::fs::create_dir_all(dir).unwrap();
        let root = Command::new("id")
            .arg("-u")
            .output()
            .is_ok_and(|o| o.stdout.trim_ascii() == b"0");
        let mounted = root
            && Command::new("mount")
                .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"])
                .arg(dir)
                .status()
                .is_ok_and(|s| s.success());
        if !mounted {
            common::missing_tool(
                "a small tmpfs disk (mount -t tmpfs needs root)",
                "STEREOTRACE_SKIP_TMPFS",
            );
            return None;
        }
        Some(SmallDisk(dir.to_path_buf()))
    }
}

impl Drop for SmallDisk {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(&self.0).status();
    }
}

/// A 64x48 scene of 41 frames, each an anaglyph PNG, with the anaglyphs also as a video.
fn pipeline(dir: &Path, video: &str) -> PathBuf {
    let scene = common::data().join("scenes/Box/Box.glb");
    assert!(
        scene.is_file(),
        "{} is part of the test data",
        scene.display()
    );
    let p = dir.join("p.toml");
    std::fs::write(
        &p,
        format!(
            "[scene]\npath = {scene:?}\n[render]\nwidth = 64\nheight = 48\nspp = 1\n\
             [frames]\nstart = 0\nend = 40\n[[output]]\nkind = \"anaglyph\"\n\
             path = \"a{{frame}}.png\"\nvideo = \"{video}\"\n"
        ),
    )
    .unwrap();
    p
}

/// Runs the render into `out`; checks exit 1, the message and what was left.
fn render_fails(p: &Path, out: &Path, names: &str) {
    let o = Command::new(env!("CARGO_BIN_EXE_stereotrace"))
        .args(["render", "--quiet", "--out"])
        .arg(out)
        .arg(p)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains(names) && stderr.contains("No space left on device"),
        "{stderr}"
    );
    let left = files_under(out);
    for f in &left {
        let name = f.file_name().unwrap().to_string_lossy();
        assert!(!name.contains(".tmp-"), "a temporary was left: {f:?}");
        assert!(!name.ends_with(".mp4"), "a cut-off video was kept: {f:?}");
        if name.ends_with(".png") {
            stereotrace::output::read_rgb8(f)
                .unwrap_or_else(|e| panic!("{f:?} was left half-written: {e}"));
        }
    }
}

#[test]
fn a_full_output_disk_fails_the_render_and_leaves_nothing_half_written() {
    if !common::ffmpeg() {
        return;
    }
    let dir = scratch("disk-full");
    let p = pipeline(&dir, "a.mp4");
    // 40 KiB fills after a few frames' PNGs and manifest lines.
    let out = dir.join("out");
    let Some(_disk) = SmallDisk::mount(&out, "40k") else {
        return;
    };
    render_fails(&p, &out, "out/");
    assert!(
        files_under(&out)
            .iter()
            .any(|f| f.to_string_lossy().ends_with(".png")),
        "the frames before the disk filled are kept"
    );
}

#[test]
fn a_full_disk_under_the_video_alone_fails_the_render_and_keeps_no_video() {
    if !common::ffmpeg() {
        return;
    }
    let dir = scratch("disk-full-video");
    let p = pipeline(&dir, "vid/a.mp4");
    let out = dir.join("out");
    // The frames have room; the video's folder holds 8 KiB, less than its file.
    let Some(_disk) = SmallDisk::mount(&out.join("vid"), "8k") else {
        return;
    };
    render_fails(&p, &out, "vid/a.mp4");
    let pngs = files_under(&out)
        .iter()
        .filter(|f| f.to_string_lossy().ends_with(".png"))
        .count();
    assert_eq!(pngs, 41, "every frame's anaglyph is written");
}
