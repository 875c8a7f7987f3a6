//! `bench sweep` through the real binary: the table has a row per combination, frame and eye;
//! more samples mean less error; acceleration methods that find the same hits give the same
//! image; the Pareto column is exactly the undominated combinations; bad keys and values fail
//! before anything is traced or written.

mod common;
use common::{repo, scratch};
use std::path::Path;
use std::process::Command;

fn pipeline(dir: &Path) -> std::path::PathBuf {
    let scene = repo().join("scenes/whitted_animated.gltf");
    let text = format!(
        "[scene]\npath = {scene:?}\nanimation = \"all\"\n[render]\nwidth = 48\nheight = 32\nspp = 1\n[stereo]\nconvergence = 4.0\n[frames]\nstart = 0\nend = 1\n[[output]]\nkind = \"exr\"\npath = \"f_{{frame:04}}.exr\"\n"
    );
    let path = dir.join("p.toml");
    std::fs::write(&path, text).unwrap();
    path
}

fn sweep(dir: &Path, args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_stereotrace"))
        .args(["bench", "sweep"])
        .arg(pipeline(dir))
        .args(args)
        .arg("--out")
        .arg(dir.join("out"))
        .output()
        .unwrap()
}

/// Rows of a CSV as maps from column name to value (no quoted fields in these tables).
fn table(path: &Path) -> Vec<std::collections::HashMap<String, String>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let head: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    lines
        .map(|l| {
            head.iter()
                .cloned()
                .zip(l.split(',').map(String::from))
                .collect()
        })
        .collect()
}

fn num(row: &std::collections::HashMap<String, String>, key: &str) -> f64 {
    row[key]
        .parse()
        .unwrap_or_else(|_| panic!("{key} = {}", row[key]))
}

#[test]
fn sweep_measures_every_combination_against_the_high_quality_render() {
    let dir = scratch("sweep-table");
    let out = sweep(
        &dir,
        &[
            "--sweep",
            "accel.update=rebuild,refit",
            "--sweep",
            "render.spp=1,9",
            "--repeat",
            "2",
            "--reference-spp",
            "64",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let results = table(&dir.join("out/results.csv"));
    // 4 combinations x 2 frames x 2 eyes.
    assert_eq!(results.len(), 16);
    for r in &results {
        assert!(
            num(r, "frame_s_min") <= num(r, "frame_s")
                && num(r, "frame_s") <= num(r, "frame_s_max")
        );
        assert!(num(r, "rays") > 0.0 && num(r, "peak_mb") > 0.0);
        let mae = num(r, "mean_abs_error");
        assert!(mae.is_finite() && mae > 0.0);
    }
    let summary = table(&dir.join("out/summary.csv"));
    assert_eq!(summary.len(), 4);
    let find = |update: &str, spp: &str| {
        summary
            .iter()
            .find(|r| r["accel.update"] == update && r["render.spp"] == spp)
            .unwrap()
    };
    for update in ["rebuild", "refit"] {
        // Nine samples per pixel against one: the error of a mean falls like 1/sqrt(n), so
        // about a third; a half is a safe bound that one sample could never meet.
        let (one, nine) = (find(update, "1"), find(update, "9"));
        assert!(
            num(nine, "mean_abs_error") < 0.5 * num(one, "mean_abs_error"),
            "{update}: {} vs {}",
            nine["mean_abs_error"],
            one["mean_abs_error"]
        );
        assert!(num(nine, "psnr") > num(one, "psnr"));
    }
    // The sphere moves rigidly, so rebuild and refit trace the same hits: the same image.
    for spp in ["1", "9"] {
        assert_eq!(
            find("rebuild", spp)["mean_abs_error"],
            find("refit", spp)["mean_abs_error"]
        );
    }
    // The Pareto column marks exactly the combinations that nothing beats in both time and error.
    for r in &summary {
        let (t, e) = (num(r, "frame_s"), num(r, "mean_abs_error"));
        let dominated = summary.iter().any(|q| {
            let (qt, qe) = (num(q, "frame_s"), num(q, "mean_abs_error"));
            qt <= t && qe <= e && (qt < t || qe < e)
        });
        assert_eq!(r["pareto"] == "true", !dominated, "{}", r["label"]);
    }
    for f in ["chart.svg", "chart.png"] {
        assert!(
            dir.join("out").join(f).metadata().unwrap().len() > 1000,
            "{f}"
        );
    }
}

#[test]
fn a_bad_key_or_value_fails_before_anything_is_written() {
    for (args, expected) in [
        (["--sweep", "render.spx=1,2"], "unknown field `spx`"),
        (
            ["--sweep", "render.spp=0,4"],
            "spp must be between 1 and 65536",
        ),
        (
            ["--sweep", "accel.split=sah,best"],
            "unknown variant `best`",
        ),
        (["--sweep", "render.spp"], "is not KEY=V1,V2"),
    ] {
        let dir = scratch("sweep-bad");
        let out = sweep(&dir, &args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(expected), "{args:?}: {err}");
        assert!(!dir.join("out").exists(), "{args:?} wrote files");
    }
}
