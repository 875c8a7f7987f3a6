//! Ctrl-C during `render`: it stops after the tiles being traced, keeps every finished frame,
//! writes the frame log, leaves no temporary file (a video's among them), says how to go on and
//! exits 130; temporaries a killed run left behind are removed by the next run.

mod common;

use common::{ffmpeg, repo, scratch};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Many frames of the animated scene, each as PNGs and a frame of an anaglyph video.
fn pipeline(dir: &Path, video: bool) -> std::path::PathBuf {
    let text = format!(
        "[scene]\npath = {:?}\nanimation = \"all\"\n[render]\nwidth = 160\nheight = 90\nspp = 4\n\
         [frames]\nstart = 0\nend = 5000\nfps = 24\n\
         [[output]]\nkind = \"png\"\npath = \"f_{{frame:04}}_{{eye}}.png\"\n\
         [[output]]\nkind = \"anaglyph\"\npath = \"a_{{frame:04}}.png\"\n{}",
        repo()
            .join("scenes/whitted_animated.gltf")
            .to_string_lossy(),
        if video { "video = \"a.mp4\"\n" } else { "" }
    );
    let p = dir.join("p.toml");
    std::fs::write(&p, text).unwrap();
    p
}

fn files(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn sigint_keeps_finished_frames_writes_the_log_and_leaves_no_temporaries() {
    let video = ffmpeg();
    let dir = scratch("interrupt");
    let out = dir.join("out");
    let p = pipeline(&dir, video);
    let child = Command::new(env!("CARGO_BIN_EXE_stereotrace"))
        .args(["render", "--threads", "2", "--out"])
        .arg(&out)
        .arg(&p)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Interrupt once a few frames are written, mid-run.
    let t0 = Instant::now();
    while !out.join("a_0003.png").exists() {
        assert!(t0.elapsed() < Duration::from_secs(120), "no frame written");
        std::thread::sleep(Duration::from_millis(20));
    }
    let kill = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let o = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(130), "{stderr}");
    assert!(
        stderr.contains("interrupted: ") && stderr.contains("The same command with --resume"),
        "{stderr}"
    );

    let names = files(&out);
    assert!(
        names.iter().all(|n| !n.starts_with('.')),
        "temporary files left: {names:?}"
    );
    assert!(!names.contains(&"a.mp4".to_string()), "an unfinished video");
    // Every finished frame is whole, and the log lists exactly those frames.
    let finished: Vec<&String> = names.iter().filter(|n| n.starts_with("a_")).collect();
    assert!(finished.len() >= 4);
    for k in 0..finished.len() {
        for name in [
            format!("a_{k:04}.png"),
            format!("f_{k:04}_left.png"),
            format!("f_{k:04}_right.png"),
        ] {
            let img = image::open(out.join(&name)).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!((img.width(), img.height()), (160, 90));
        }
    }
    let log = std::fs::read_to_string(out.join("frame-log.csv")).unwrap();
    let frames: std::collections::BTreeSet<&str> = log
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap())
        .collect();
    assert_eq!(frames.len(), finished.len(), "{log}");
    let n = finished.len();
    assert!(
        stderr.contains(&format!("{n} frame(s) from 0 to {} are finished", n - 1)),
        "says what is finished: {stderr}"
    );
}

#[test]
fn a_killed_runs_temporaries_are_removed_by_the_next_run() {
    let dir = scratch("interrupt-stale");
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();
    // Process 2^22 + 1 is above Linux's largest process id: it cannot be running here.
    let host = format!("{:08x}", stereotrace::output::host_id());
    let stale = [
        format!(".f_0000_left.png.tmp-4194305-{host}"),
        format!(".tmp-4194305-{host}-a.mp4"),
    ];
    for s in &stale {
        std::fs::write(out.join(s), "partial").unwrap();
    }
    std::fs::write(out.join(".keep"), "not ours").unwrap();
    // Another machine's worker writing into a shared folder: its process is not ours to judge.
    let elsewhere = format!(
        ".f_0001_left.png.tmp-4194305-{:08x}",
        !stereotrace::output::host_id()
    );
    std::fs::write(out.join(&elsewhere), "being written").unwrap();
    let p = pipeline(&dir, false);
    let o = Command::new(env!("CARGO_BIN_EXE_stereotrace"))
        .args(["render", "--frames", "0..0", "--out"])
        .arg(&out)
        .arg(&p)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert!(
        stderr.contains("removed 2 temporary file(s) left by an interrupted run"),
        "{stderr}"
    );
    let names = files(&out);
    assert!(stale.iter().all(|s| !names.contains(s)), "{names:?}");
    assert!(
        names.contains(&".keep".to_string()) && names.contains(&elsewhere),
        "other hidden files and other machines' temporaries stay: {names:?}"
    );
}
