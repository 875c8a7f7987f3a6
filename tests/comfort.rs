//! Stereo comfort through the whole tool: the frame log's parallax against the WHITTED.md
//! formula, automatic convergence on a named node, floating windows on the eye that needs them,
//! stereo signalling in videos (read back with ffprobe), and wobble GIFs pivoting on a node.

mod common;

use common::{ffmpeg, missing_tool, position_buffers, quad, scratch};
use glam::{Mat4, Vec3};
use serde_json::json;
use std::path::{Path, PathBuf};
use stereotrace::output::read_planes;
use stereotrace::render::{EyeCamera, Rig, RigParams, View};

const YFOV: f32 = 0.8;
const W: u32 = 160;
const H: u32 = 90;

/// A scene seen from the origin looking down -Z: a wall at depth 6 filling the view, a square
/// `near` in front of it, and a node "Subject" at `subject` (no mesh of its own).
fn scene(dir: &Path, near: Vec<[f32; 3]>, subject: [f32; 3]) -> PathBuf {
    let wall = quad([
        [-20.0, -20.0, -6.0],
        [20.0, -20.0, -6.0],
        [20.0, 20.0, -6.0],
        [-20.0, 20.0, -6.0],
    ]);
    let (views, accessors, buffers) = position_buffers(&[&wall, &near]);
    let primitives: Vec<_> = (0..2)
        .map(|k| json!({"attributes": {"POSITION": k}}))
        .collect();
    let g = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1, 2]}],
        "nodes": [
            {"mesh": 0},
            {"name": "Cam", "camera": 0},
            {"name": "Subject", "translation": subject}
        ],
        "cameras": [{"type": "perspective", "perspective": {"yfov": YFOV, "znear": 0.1}}],
        "meshes": [{"primitives": primitives}],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": buffers
    });
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join("scene.gltf");
    std::fs::write(&path, g.to_string()).unwrap();
    path
}

/// A square at `depth` covering film x from `x0` to `x1` (fractions of the half-width, -1 the
/// left edge) and the middle of the height.
fn square(depth: f32, x0: f32, x1: f32) -> Vec<[f32; 3]> {
    let tan_y = (YFOV * 0.5).tan();
    let tan_x = tan_y * W as f32 / H as f32;
    let (a, b) = (x0 * tan_x * depth, x1 * tan_x * depth);
    let y = 0.5 * tan_y * depth;
    quad([
        [a, -y, -depth],
        [b, -y, -depth],
        [b, y, -depth],
        [a, y, -depth],
    ])
}

fn pipeline(dir: &Path, stereo: &str, outputs: &str) -> PathBuf {
    let p = dir.join("p.toml");
    std::fs::write(
        &p,
        format!(
            "[scene]\npath = \"scene.gltf\"\n[render]\nwidth = {W}\nheight = {H}\nspp = 1\n\
             [stereo]\n{stereo}\n{outputs}"
        ),
    )
    .unwrap();
    p
}

fn render(p: &Path, out: &Path) {
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_stereotrace"))
        .args(["render", "--quiet", "--out"])
        .arg(out)
        .arg(p)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// The frame log's rows as maps from column to value.
fn log(out: &Path) -> Vec<std::collections::HashMap<String, String>> {
    let mut r = csv::Reader::from_path(out.join("frame-log.csv")).unwrap();
    let header: Vec<String> = r.headers().unwrap().iter().map(String::from).collect();
    r.records()
        .map(|rec| {
            let rec = rec.unwrap();
            header
                .iter()
                .cloned()
                .zip(rec.iter().map(String::from))
                .collect()
        })
        .collect()
}

fn number(row: &std::collections::HashMap<String, String>, key: &str) -> f32 {
    row[key]
        .parse()
        .unwrap_or_else(|_| panic!("{key} = {:?}", row[key]))
}

/// WHITTED.md section 2: parallax W/2 * interaxial * (1/c - 1/Z) / tan_x pixels.
fn whitted_parallax(ia: f32, c: f32, z: f32) -> f32 {
    let tan_x = (YFOV * 0.5).tan() * W as f32 / H as f32;
    0.5 * W as f32 * ia * (1.0 / c - 1.0 / z) / tan_x
}

#[test]
fn the_frame_log_gives_the_parallax_the_whitted_formula_predicts() {
    let dir = scratch("comfort-parallax");
    scene(&dir, square(2.0, -0.3, 0.3), [0.0, 0.0, -4.0]);
    let p = pipeline(
        &dir,
        "interaxial = 0.08\nconvergence = 3.5",
        "[[output]]\nkind = \"exr\"\npath = \"f.exr\"\n",
    );
    render(&p, &dir.join("out"));
    let rows = log(&dir.join("out"));
    let row = &rows[0];
    let (near, far) = (number(row, "near_m"), number(row, "far_m"));
    assert!(
        (near - 2.0).abs() < 1e-3 && (far - 6.0).abs() < 1e-3,
        "{row:?}"
    );
    for (column, z) in [("near_parallax_px", 2.0), ("far_parallax_px", 6.0)] {
        let expected = whitted_parallax(0.08, 3.5, z);
        let got = number(row, column);
        assert!(
            (got - expected).abs() < 0.05,
            "{column}: {got} vs {expected}"
        );
        let pct = number(row, &column.replace("_px", "_pct"));
        assert!((pct - 100.0 * expected / W as f32).abs() < 0.01);
    }
    // 1.8 px in front (1.1% of 160 pixels) is over the default budget of 1%.
    assert_eq!(row["over_budget"], "1");
}

#[test]
fn auto_convergence_puts_the_subject_at_zero_parallax() {
    let dir = scratch("comfort-subject");
    let subject = [0.4, -0.2, -4.5];
    scene(&dir, square(2.0, -0.3, 0.3), subject);
    let p = pipeline(
        &dir,
        "interaxial = \"auto\"\nconvergence = \"auto\"\nsubject = \"Subject\"",
        "[[output]]\nkind = \"exr\"\npath = \"f.exr\"\n",
    );
    render(&p, &dir.join("out"));
    let row = &log(&dir.join("out"))[0];
    let (c, ia) = (number(row, "convergence_m"), number(row, "interaxial_m"));
    let rig = RigParams {
        rig: Rig::OffAxis,
        interaxial: ia,
        convergence: c,
        width: W,
        height: H,
        yfov: YFOV,
        znear: 0.1,
        zfar: None,
    };
    let point = Vec3::from(subject);
    let left = EyeCamera::new(Mat4::IDENTITY, &rig, View::LEFT)
        .project(point)
        .unwrap();
    let right = EyeCamera::new(Mat4::IDENTITY, &rig, View::RIGHT)
        .project(point)
        .unwrap();
    assert!((right.x - left.x).abs() < 0.1, "{left} {right} (c {c})");
    // The automatic interaxial keeps the frame within the budget, touching one of its bounds.
    assert_eq!(row["over_budget"], "0");
    let (front, behind) = (
        number(row, "near_parallax_pct"),
        number(row, "far_parallax_pct"),
    );
    assert!(
        (front + 1.0).abs() < 0.01 || (behind - 2.0).abs() < 0.01,
        "{front} {behind}"
    );
}

#[test]
fn a_near_object_at_the_left_edge_gets_a_floating_window_in_the_left_eye_only() {
    let dir = scratch("comfort-window");
    // A square 1.5 m away from the left edge to a third of the way in, in front of the 3 m
    // convergence plane.
    scene(&dir, square(1.5, -1.5, -0.3), [0.0, 0.0, -4.0]);
    let outputs = "[[output]]\nkind = \"exr\"\npath = \"f_{eye}.exr\"\nviews = \"separate\"\n";
    let plain = pipeline(&dir, "interaxial = 0.065\nconvergence = 3.0", outputs);
    render(&plain, &dir.join("plain"));
    let windowed = pipeline(
        &dir,
        "interaxial = 0.065\nconvergence = 3.0\nfloating_window = \"auto\"",
        outputs,
    );
    render(&windowed, &dir.join("windowed"));
    let row = &log(&dir.join("windowed"))[0];
    let (left, right) = (
        number(row, "window_left_px"),
        number(row, "window_right_px"),
    );
    let expected = -whitted_parallax(0.065, 3.0, 1.5);
    assert!((left - expected).abs() < 0.05, "{left} vs {expected}");
    assert_eq!(right, 0.0);
    // The first three planes (R, G, B) of each eye's file, pixel by pixel.
    let read = |run: &str, eye: &str| {
        let planes = &read_planes(&dir.join(run).join(format!("f_{eye}.exr"))).unwrap()[0].1;
        let at = |x: usize, y: usize| -> [f32; 3] {
            std::array::from_fn(|c| planes.data[c][y * planes.width + x])
        };
        (0..H as usize)
            .map(|y| (0..W as usize).map(|x| at(x, y)).collect::<Vec<_>>())
            .collect::<Vec<_>>()
    };
    let border = left.floor() as usize;
    for eye in ["left", "right"] {
        let (before, after) = (read("plain", eye), read("windowed", eye));
        for y in 0..H as usize {
            for x in 0..W as usize {
                let masked = eye == "left" && x < border;
                let expect = if masked { [0.0; 3] } else { before[y][x] };
                if x != border || eye == "right" {
                    assert_eq!(after[y][x], expect, "{eye} eye at ({x}, {y})");
                }
            }
        }
    }
}

/// ffprobe, from the PATH; a missing one fails the test unless `STEREOTRACE_SKIP_FFPROBE=1`.
fn ffprobe() -> Option<PathBuf> {
    let found = std::env::var_os("PATH").and_then(|paths| {
        std::env::split_paths(&paths)
            .map(|d| d.join("ffprobe"))
            .find(|p| p.is_file())
    });
    if found.is_none() {
        missing_tool("ffprobe", "STEREOTRACE_SKIP_FFPROBE");
    }
    found
}

fn probe_json(ffprobe: &Path, args: &[&str], file: &Path) -> serde_json::Value {
    let o = std::process::Command::new(ffprobe)
        .args(["-v", "error", "-of", "json"])
        .args(args)
        .arg(file)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

#[test]
fn stereo_videos_are_reported_as_stereo_by_ffprobe_with_their_layout() {
    if !ffmpeg() {
        return;
    }
    let Some(ffprobe) = ffprobe() else { return };
    let dir = scratch("comfort-video");
    scene(&dir, square(2.0, -0.3, 0.3), [0.0, 0.0, -4.0]);
    let p = pipeline(
        &dir,
        "interaxial = 0.065\nconvergence = 3.0",
        "[[output]]\nkind = \"side-by-side\"\npath = \"sbs_{frame}.png\"\nvideo = \"sbs.mkv\"\n\
         [[output]]\nkind = \"side-by-side\"\npath = \"cross_{frame}.png\"\nlayout = \"cross\"\nvideo = \"cross.mkv\"\n\
         [[output]]\nkind = \"top-bottom\"\npath = \"tb_{frame}.png\"\nvideo = \"tb.webm\"\n\
         [[output]]\nkind = \"side-by-side\"\npath = \"mp4_{frame}.png\"\nvideo = \"sbs.mp4\"\n",
    );
    let out = dir.join("out");
    render(&p, &out);
    // Matroska and WebM: the stream's StereoMode, which ffprobe shows as stereo 3D side data.
    for (file, layout, inverted, tag) in [
        ("sbs.mkv", "side by side", 0, "left_right"),
        ("cross.mkv", "side by side", 1, "right_left"),
        ("tb.webm", "top and bottom", 0, "top_bottom"),
    ] {
        let v = probe_json(&ffprobe, &["-show_streams"], &out.join(file));
        let stream = &v["streams"][0];
        assert_eq!(stream["tags"]["stereo_mode"], tag, "{file}: {stream}");
        let side = stream["side_data_list"]
            .as_array()
            .and_then(|l| l.iter().find(|s| s["side_data_type"] == "Stereo 3D"))
            .unwrap_or_else(|| panic!("{file}: no stereo 3D side data in {stream}"));
        assert_eq!(side["type"], layout, "{file}");
        assert_eq!(side["inverted"], inverted, "{file}");
    }
    // MP4: H.264's frame-packing SEI, reported on the decoded frames; ffprobe names the side
    // data but prints no layout for it, and showinfo's text differs between FFmpeg versions
    // (5.1: "stereoscopic information", later: "Stereo 3D"), so the layout is read from the
    // bitstream itself.
    let mp4 = out.join("sbs.mp4");
    let v = probe_json(&ffprobe, &["-show_frames", "-read_intervals", "%+#1"], &mp4);
    let frame_side = v["frames"][0]["side_data_list"].to_string();
    assert!(frame_side.contains("Stereo 3D"), "{frame_side}");
    let o = std::process::Command::new("ffmpeg")
        .args(["-v", "error", "-i"])
        .arg(&mp4)
        .args([
            "-c:v",
            "copy",
            "-bsf:v",
            "h264_mp4toannexb",
            "-frames:v",
            "1",
        ])
        .args(["-f", "h264", "-"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // ITU-T H.264 D.2.26: type 3 is side by side; content interpretation 1 puts the left view
    // in frame 0 (the left half).
    assert_eq!(frame_packing(&o.stdout), Some((3, 1)));
}

/// The first frame-packing arrangement SEI (payload type 45) of an H.264 Annex B stream: its
/// `frame_packing_arrangement_type` and `content_interpretation_type` (ITU-T H.264 D.1.26).
fn frame_packing(stream: &[u8]) -> Option<(u32, u32)> {
    // NAL units between start codes; SEI NAL units (type 6) without emulation prevention.
    let starts: Vec<usize> = (0..stream.len().saturating_sub(3))
        .filter(|&i| stream[i..i + 3] == [0, 0, 1])
        .map(|i| i + 3)
        .collect();
    for (k, &start) in starts.iter().enumerate() {
        let end = starts.get(k + 1).map_or(stream.len(), |&next| next - 3);
        let nal = &stream[start..end];
        if nal.first().map(|b| b & 0x1f) != Some(6) {
            continue;
        }
        let mut rbsp = Vec::new();
        for (i, &b) in nal[1..].iter().enumerate() {
            if b == 3 && i >= 2 && rbsp.ends_with(&[0, 0]) {
                continue;
            }
            rbsp.push(b);
        }
        // SEI messages: payload type and size as runs of 0xff plus a last byte.
        let mut at = 0;
        while at + 2 < rbsp.len() {
            let mut read = || {
                let mut v = 0u32;
                while rbsp.get(at) == Some(&0xff) {
                    v += 255;
                    at += 1;
                }
                v += *rbsp.get(at)? as u32;
                at += 1;
                Some(v)
            };
            let (kind, size) = (read()?, read()? as usize);
            if kind == 45 {
                let mut bits = Bits {
                    bytes: rbsp.get(at..at + size)?,
                    at: 0,
                };
                let _id = bits.exp_golomb()?;
                if bits.take(1)? == 1 {
                    return None;
                }
                let layout = bits.take(7)?;
                let _quincunx = bits.take(1)?;
                return Some((layout, bits.take(6)?));
            }
            at += size;
        }
    }
    None
}

/// A reader of bits, most significant first.
struct Bits<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Bits<'_> {
    fn take(&mut self, n: usize) -> Option<u32> {
        let mut v = 0;
        for _ in 0..n {
            let byte = self.bytes.get(self.at / 8)?;
            v = v << 1 | ((byte >> (7 - self.at % 8)) & 1) as u32;
            self.at += 1;
        }
        Some(v)
    }

    /// ue(v): leading zeros, a one, then as many bits.
    fn exp_golomb(&mut self) -> Option<u32> {
        let mut zeros = 0;
        while self.take(1)? == 0 {
            zeros += 1;
        }
        Some((1 << zeros) - 1 + self.take(zeros)?)
    }
}

#[test]
fn a_wobble_gif_pivoting_on_a_node_holds_that_node_still() {
    let dir = scratch("comfort-wobble");
    // A narrow bright bar at the subject's depth (5 m), well behind the 3 m convergence plane.
    let tan_y = (YFOV * 0.5).tan();
    let bar = quad([
        [-0.05, -tan_y * 2.5, -5.0],
        [0.05, -tan_y * 2.5, -5.0],
        [0.05, tan_y * 2.5, -5.0],
        [-0.05, tan_y * 2.5, -5.0],
    ]);
    scene(&dir, bar, [0.0, 0.0, -5.0]);
    let p = pipeline(
        &dir,
        "interaxial = 0.3\nconvergence = 3.0",
        "[[output]]\nkind = \"wobble-gif\"\npath = \"w.gif\"\nviews = 5\nper_frame = true\npivot = \"Subject\"\n",
    );
    let out = dir.join("out");
    render(&p, &out);
    let file = std::fs::File::open(out.join("w.gif")).unwrap();
    let mut options = gif::DecodeOptions::new();
    options.set_color_output(gif::ColorOutput::RGBA);
    let mut decoder = options.read_info(file).unwrap();
    // The bar's brightest column in each frame of the GIF (5 views, bounce: 8 frames).
    let mut columns = Vec::new();
    while let Some(frame) = decoder.read_next_frame().unwrap() {
        let row = (H as usize / 2) * W as usize * 4;
        let brightest = (0..W as usize)
            .max_by_key(|&x| {
                let px = &frame.buffer[row + 4 * x..row + 4 * x + 3];
                px.iter().map(|&c| c as u32).sum::<u32>()
            })
            .unwrap();
        columns.push(brightest);
    }
    assert_eq!(columns.len(), 8);
    let spread = columns.iter().max().unwrap() - columns.iter().min().unwrap();
    // Without the pivot the bar moves 0.3 * (1/3 - 1/5) * 80 / tan_x = 3.7 px across the views.
    assert!(spread <= 1, "the pivot node moves: {columns:?}");
}

#[test]
fn comfort_keys_with_bad_values_are_refused_at_their_line() {
    let dir = scratch("comfort-bad");
    scene(&dir, square(2.0, -0.3, 0.3), [0.0, 0.0, -4.0]);
    let exr = "[[output]]\nkind = \"exr\"\npath = \"f.exr\"\n";
    for (stereo, line, says) in [
        (
            "convergence = \"near\"",
            8,
            "expected a number of metres or \"auto\"",
        ),
        ("subject = \"Nobody\"", 8, "no node named \"Nobody\""),
        (
            "rig = \"parallel\"\nconvergence = \"auto\"",
            9,
            "converges at infinity",
        ),
        (
            "rig = \"mono\"\nfloating_window = \"auto\"",
            8,
            "no parallax",
        ),
        ("budget_front = 0", 8, "budget_front"),
        ("screen_width = -3", 8, "screen_width"),
    ] {
        let p = pipeline(&dir, stereo, exr);
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_stereotrace"))
            .arg("check")
            .arg(&p)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{stereo}: {err}");
        assert!(err.contains(&format!("p.toml:{line}:")), "{stereo}: {err}");
        assert!(err.contains(says), "{stereo}: {err}");
    }
}

#[test]
fn check_depth_prints_what_the_render_logs() {
    let dir = scratch("comfort-check");
    scene(&dir, square(2.0, -0.3, 0.3), [0.0, 0.0, -4.0]);
    let p = pipeline(
        &dir,
        "interaxial = \"auto\"\nconvergence = 3.5",
        "[[output]]\nkind = \"exr\"\npath = \"f.exr\"\n",
    );
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_stereotrace"))
        .args(["check", "--depth"])
        .arg(&p)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    render(&p, &dir.join("out"));
    let row = &log(&dir.join("out"))[0];
    let frame_line = text
        .lines()
        .find(|l| l.trim_start().starts_with("0 "))
        .unwrap();
    let ia = format!("{:.4}", number(row, "interaxial_m"));
    assert!(frame_line.contains(&ia), "{frame_line} vs {ia}");
    assert!(text.contains("depth: parallax"), "{text}");
}

#[test]
fn automatic_rigs_are_the_same_for_a_frame_rendered_alone_and_at_any_thread_count() {
    let dir = scratch("comfort-alone");
    std::fs::create_dir_all(&dir).unwrap();
    let scene = common::repo().join("scenes/whitted_animated.gltf");
    let p = dir.join("p.toml");
    std::fs::write(
        &p,
        format!(
            "[scene]\npath = {:?}\n[render]\nwidth = 64\nheight = 36\nspp = 1\n\
             [stereo]\ninteraxial = \"auto\"\nconvergence = \"auto\"\nsubject = \"glass sphere\"\n\
             floating_window = \"auto\"\nsmoothing = 3\n[frames]\nstart = 0\nend = 15\n\
             [[output]]\nkind = \"side-by-side\"\npath = \"f_{{frame:04}}.png\"\n",
            scene.to_string_lossy()
        ),
    )
    .unwrap();
    let run = |out: &str, extra: &[&str]| {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_stereotrace"))
            .args(["render", "--quiet", "--out"])
            .arg(dir.join(out))
            .args(extra)
            .arg(&p)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    run("all", &["--threads", "2"]);
    run("alone", &["--frames", "7..8", "--threads", "1"]);
    for f in ["f_0007.png", "f_0008.png"] {
        let a = std::fs::read(dir.join("all").join(f)).unwrap();
        let b = std::fs::read(dir.join("alone").join(f)).unwrap();
        assert!(a == b, "{f} differs when rendered alone");
    }
    let rows = log(&dir.join("all"));
    let convergence: Vec<f32> = rows.iter().map(|r| number(r, "convergence_m")).collect();
    assert!(
        convergence.windows(2).any(|w| w[0] != w[1]),
        "the subject moves: the convergence follows it"
    );
}

#[test]
fn the_rendered_eyes_show_the_parallax_the_frame_log_reports() {
    // The square alone on a black background, 64 samples per pixel: the coverage of the pixel
    // its left edge crosses places that edge to a fraction of a pixel in each eye.
    let dir = scratch("comfort-measured");
    scene(&dir, square(2.0, -0.3, 0.3), [0.0, 0.0, -4.0]);
    let g = std::fs::read_to_string(dir.join("scene.gltf")).unwrap();
    let mut g: serde_json::Value = serde_json::from_str(&g).unwrap();
    g["meshes"][0]["primitives"]
        .as_array_mut()
        .unwrap()
        .remove(0);
    std::fs::write(dir.join("scene.gltf"), g.to_string()).unwrap();
    let p = pipeline(
        &dir,
        "interaxial = 0.08\nconvergence = 3.5",
        "[[output]]\nkind = \"exr\"\npath = \"f_{eye}.exr\"\nviews = \"separate\"\n",
    );
    let text = std::fs::read_to_string(&p)
        .unwrap()
        .replace("spp = 1", "spp = 64");
    std::fs::write(&p, text).unwrap();
    let out = dir.join("out");
    render(&p, &out);
    let edge = |eye: &str| -> f64 {
        let planes = &read_planes(&out.join(format!("f_{eye}.exr"))).unwrap()[0].1;
        let at = |x: usize, y: usize| planes.data[1][y * planes.width + x] as f64;
        // Rows in the middle third of the square's height.
        let rows: Vec<usize> = (H as usize * 2 / 5..H as usize * 3 / 5).collect();
        let sum: f64 = rows
            .iter()
            .map(|&y| {
                let first = (0..W as usize).find(|&x| at(x, y) > 0.0).unwrap();
                let coverage = at(first, y) / at(first + 2, y);
                (first + 1) as f64 - coverage
            })
            .sum();
        sum / rows.len() as f64
    };
    let measured = edge("right") - edge("left");
    let logged = number(&log(&out)[0], "near_parallax_px") as f64;
    eprintln!("parallax measured in the images {measured:.4} px, logged {logged:.4} px");
    assert!(
        (measured - logged).abs() < 0.05,
        "measured {measured:.4} px in the images, logged {logged:.4} px"
    );
}
