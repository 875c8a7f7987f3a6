//! OpenImageIO interop: every EXR kind stereotrace writes reads back in OpenImageIO with the right
//! views, channel names and values, and `stereotrace compare` gives idiff's verdict and exit status
//! on a set of image pairs and flag sets.

mod common;

use common::{oiio, scratch};
use glam::Vec3;
use std::path::Path;
use std::process::Command;
use stereotrace::output::exr::{write_multiview, write_single_view};
use stereotrace::output::image::Image;

fn pattern(w: usize, h: usize, k: f32) -> Image {
    let mut img = Image::new(w, h);
    for y in 0..h {
        for x in 0..w {
            img.set(
                x,
                y,
                Vec3::new(
                    x as f32 * 0.1 * k,
                    y as f32 * 0.05,
                    0.3 + 0.01 * (x + y) as f32 * k,
                ),
            );
        }
    }
    img
}

/// What OpenImageIO sees in a file: channel names, multiView / view attributes, all pixels.
fn oiio_read(python: &Path, file: &Path) -> serde_json::Value {
    let script = r#"
import json, sys, OpenImageIO as oiio
buf = oiio.ImageBuf(sys.argv[1])
spec = buf.spec()
out = {"channels": list(spec.channelnames), "width": spec.width, "height": spec.height,
       "multiView": spec.getattribute("multiView"), "view": spec.getattribute("view"),
       "pixels": buf.get_pixels(oiio.FLOAT).reshape(-1).tolist()}
print(json.dumps(out))
"#;
    let out = Command::new(python)
        .args(["-c", script])
        .arg(file)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// Interleaved pixel values in OpenImageIO's channel order for the given images.
fn expected_pixels(images: &[&Image]) -> Vec<f32> {
    let (w, h) = (images[0].width, images[0].height);
    let mut v = Vec::new();
    for i in 0..w * h {
        // OpenImageIO lists the default view's R, G, B, then each other view's R, G, B.
        for img in images {
            let q = img.pixels[i];
            v.extend([q.x, q.y, q.z]);
        }
    }
    v
}

fn assert_close(got: &serde_json::Value, want: &[f32], tol: f32, what: &str) {
    let got: Vec<f32> = got
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap() as f32)
        .collect();
    assert_eq!(got.len(), want.len(), "{what}: value count");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert!(
            (g - w).abs() <= tol * w.abs().max(1.0),
            "{what}: value {i}: {g} vs {w}"
        );
    }
}

#[test]
fn openimageio_reads_every_exr_kind_we_write() {
    let Some((_, python)) = oiio() else { return };
    let dir = scratch("oiio-exr");
    let (l, r) = (pattern(9, 5, 1.0), pattern(9, 5, 2.0));
    for half in [false, true] {
        let tol = if half { 1e-3 } else { 0.0 };
        let path = dir.join(format!("pair_{half}.exr"));
        write_multiview(&path, &[("left", &l), ("right", &r)], half).unwrap();
        let v = oiio_read(&python, &path);
        assert_eq!(
            v["channels"],
            serde_json::json!(["R", "G", "B", "right.R", "right.G", "right.B"])
        );
        assert_eq!(v["multiView"], serde_json::json!(["left", "right"]));
        assert_close(&v["pixels"], &expected_pixels(&[&l, &r]), tol, "multi-view");

        for (eye, img) in [("left", &l), ("right", &r)] {
            let path = dir.join(format!("{eye}_{half}.exr"));
            write_single_view(&path, eye, img, half).unwrap();
            let v = oiio_read(&python, &path);
            assert_eq!(v["channels"], serde_json::json!(["R", "G", "B"]));
            assert_eq!(v["view"], serde_json::json!(eye));
            assert_close(&v["pixels"], &expected_pixels(&[img]), tol, eye);
        }
    }
}

#[test]
fn compare_agrees_with_idiff_on_verdict_and_exit_status() {
    let Some((bin, _)) = oiio() else { return };
    let dir = scratch("oiio-idiff");
    let base = pattern(32, 24, 1.0);
    let write = |name: &str, img: &Image| {
        let p = dir.join(format!("{name}.exr"));
        write_multiview(&p, &[("center", img)], false).unwrap();
        p
    };
    let a = write("base", &base);
    let mut pairs = vec![("identical", write("identical", &base))];
    let mut noise = base.clone();
    for (i, p) in noise.pixels.iter_mut().enumerate() {
        *p += Vec3::splat(((i * 7919 % 13) as f32 - 6.0) * 2e-5);
    }
    pairs.push(("tiny noise", write("noise", &noise)));
    let mut hot = base.clone();
    for i in [5, 300, 700] {
        hot.pixels[i] += Vec3::new(0.5, 0.0, 0.0);
    }
    pairs.push(("hot pixels", write("hot", &hot)));
    let mut shifted = base.clone();
    for y in 0..24 {
        for x in 0..32 {
            let edge = |e: usize| if x >= e { 0.8 } else { 0.1 };
            shifted.set(
                x,
                y,
                Vec3::new(edge(17), base.get(x, y).y, base.get(x, y).z),
            );
        }
    }
    let mut edge_ref = shifted.clone();
    for y in 0..24 {
        for x in 0..32 {
            edge_ref.set(
                x,
                y,
                Vec3::new(
                    if x >= 16 { 0.8 } else { 0.1 },
                    base.get(x, y).y,
                    base.get(x, y).z,
                ),
            );
        }
    }
    let edge_a = write("edge_a", &edge_ref);
    pairs.push(("shifted edge", write("edge_b", &shifted)));
    let mut nan = base.clone();
    nan.pixels[40] = Vec3::new(f32::NAN, 0.0, 0.0);
    nan.pixels[41] = Vec3::splat(f32::INFINITY);
    pairs.push(("NaN and Inf pixels", write("nan", &nan)));
    pairs.push(("different size", write("bigger", &pattern(33, 24, 1.0))));
    let mut warm = base.clone();
    for p in warm.pixels.iter_mut() {
        *p *= 1.004;
    }
    pairs.push(("small drift everywhere", write("drift", &warm)));

    let flag_sets: [&[&str]; 7] = [
        &[],
        &["--fail", "0.02", "--failpercent", "0.5"],
        &["--fail", "0.1", "--warn", "0.001", "--warnpercent", "1"],
        &[
            "--fail",
            "0.001",
            "--failpercent",
            "50",
            "--hardfail",
            "0.3",
        ],
        &[
            "--fail",
            "0.001",
            "--failpercent",
            "50",
            "--warn",
            "0.0001",
            "--hardwarn",
            "0.01",
        ],
        &["--fail", "0.001", "--allowfailures", "5"],
        &[
            "--fail",
            "0.0001",
            "--failrelative",
            "0.01",
            "--failpercent",
            "1",
        ],
    ];
    let mut table = Vec::new();
    let mut disagreements = Vec::new();
    for (name, b) in &pairs {
        let first = if *name == "shifted edge" { &edge_a } else { &a };
        for flags in flag_sets {
            let ours = Command::new(env!("CARGO_BIN_EXE_stereotrace"))
                .arg("compare")
                .args(flags)
                .arg(first)
                .arg(b)
                .output()
                .unwrap()
                .status
                .code();
            let idiff_flags: Vec<String> = flags.iter().map(|f| f.replacen("--", "-", 1)).collect();
            let theirs = Command::new(bin.join("idiff"))
                .arg("-q")
                .args(&idiff_flags)
                .arg(first)
                .arg(b)
                .output()
                .unwrap()
                .status
                .code();
            table.push(format!(
                "{name:>24} {:<60} ours {ours:?} idiff {theirs:?}",
                flags.join(" ")
            ));
            if ours != theirs {
                disagreements.push(table.last().unwrap().clone());
            }
        }
    }
    // Unreadable input: both exit 4.
    let missing = dir.join("missing.exr");
    let ours = Command::new(env!("CARGO_BIN_EXE_stereotrace"))
        .arg("compare")
        .arg(&a)
        .arg(&missing)
        .output()
        .unwrap();
    let theirs = Command::new(bin.join("idiff"))
        .arg("-q")
        .arg(&a)
        .arg(&missing)
        .output()
        .unwrap();
    assert_eq!(ours.status.code(), theirs.status.code(), "missing file");
    assert_eq!(ours.status.code(), Some(4));
    println!("{}", table.join("\n"));
    assert!(disagreements.is_empty(), "{disagreements:#?}");
}

#[test]
fn a_view_missing_on_one_side_fails() {
    let dir = scratch("compare-views");
    let (l, r) = (pattern(6, 4, 1.0), pattern(6, 4, 2.0));
    let both = dir.join("both.exr");
    let left_only = dir.join("left.exr");
    write_multiview(&both, &[("left", &l), ("right", &r)], false).unwrap();
    write_multiview(&left_only, &[("left", &l)], false).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_stereotrace"))
        .args(["compare", "--json"])
        .arg(&both)
        .arg(&left_only)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["missing_views"], serde_json::json!(["right"]));
    let same = Command::new(env!("CARGO_BIN_EXE_stereotrace"))
        .arg("compare")
        .arg(&both)
        .arg(&both)
        .output()
        .unwrap();
    assert_eq!(same.status.code(), Some(0));
    // One view against a plain file of the same pixels: compared directly, whatever the names.
    let plain = dir.join("plain.exr");
    write_multiview(&plain, &[("center", &l)], false).unwrap();
    let one = Command::new(env!("CARGO_BIN_EXE_stereotrace"))
        .arg("compare")
        .arg(&left_only)
        .arg(&plain)
        .output()
        .unwrap();
    assert_eq!(one.status.code(), Some(0));
}

/// A multi-part stereo EXR whose parts cover different data windows (each eye's RGBA part and a
/// depth part with windows of their own, as in OpenEXR's sample set) used to panic `compare`
/// with an index out of bounds. Each part is now placed in the display window: the file equals
/// itself, and a change in one part is found in its view at its display position.
#[test]
fn parts_with_their_own_data_windows_compare_over_the_display_window() {
    let Some((_, python)) = oiio() else {
        return;
    };
    let dir = scratch("compare-windows");
    let script = common::data().join("exr").join("multipart_windows.py");
    let make = |name: &str, bump: &str| {
        let path = dir.join(name);
        let ok = Command::new(&python)
            .arg(&script)
            .arg(&path)
            .arg(bump)
            .status()
            .unwrap();
        assert!(ok.success(), "{} could not write {name}", script.display());
        path
    };
    let (a, b) = (make("a.exr", "0"), make("b.exr", "0.5"));
    let compare = |x: &Path, y: &Path| {
        Command::new(env!("CARGO_BIN_EXE_stereotrace"))
            .args(["compare", "--json"])
            .arg(x)
            .arg(y)
            .output()
            .unwrap()
    };
    let same = compare(&a, &a);
    assert_eq!(
        same.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&same.stderr)
    );
    let differ = compare(&a, &b);
    assert_eq!(differ.status.code(), Some(2));
    let v: serde_json::Value = serde_json::from_slice(&differ.stdout).unwrap();
    let view = |name: &str| {
        v["views"]
            .as_array()
            .unwrap()
            .iter()
            .find(|e| e[0] == name)
            .map(|e| e[1].clone())
            .unwrap_or_else(|| panic!("no view {name} in {v}"))
    };
    let (left, right) = (view("left"), view("right"));
    assert_eq!(
        (left["width"].clone(), left["height"].clone()),
        (8.into(), 6.into())
    );
    assert_eq!(left["max_error"], 0.0);
    assert!((right["max_error"].as_f64().unwrap() - 0.5).abs() < 1e-6);
    assert_eq!(right["max_at"], serde_json::json!([3, 3, 0]));
}
