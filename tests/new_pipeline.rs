//! `stereotrace new SCENE`: the pipeline it writes is accepted by `check` and renders, every
//! commented-out output kind in it is valid once uncommented, and it never overwrites a file.

mod common;

use common::{data, scratch};
use std::path::Path;
use std::process::{Command, Output};

fn stereotrace(args: &[&std::ffi::OsStr]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_stereotrace"))
        .args(args)
        .output()
        .unwrap()
}

fn ok(o: &Output) -> String {
    let stderr = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(o.status.success(), "{stderr}");
    stderr
}

/// Uncomments every output block of a starter pipeline, the video (which needs ffmpeg) aside.
fn every_output(text: &str) -> String {
    let mut out = String::new();
    let mut inside = false;
    for line in text.lines() {
        inside = line == "# [[output]]" || (inside && line.starts_with("# "));
        match line.strip_prefix("# ") {
            Some(l) if inside && !l.starts_with("video") => out.push_str(l),
            _ if inside => continue,
            _ => out.push_str(line),
        }
        out.push('\n');
    }
    out
}

#[test]
fn new_writes_a_pipeline_that_checks_and_renders() {
    let dir = scratch("new-pipeline");
    for model in [
        "CesiumMan/CesiumMan.glb",
        "Duck/Duck.glb",
        "Cameras/Cameras.gltf",
        "LightsPunctualLamp/LightsPunctualLamp.gltf",
    ] {
        let name = Path::new(model).file_stem().unwrap().to_string_lossy();
        let p = dir.join("pipelines").join(format!("{name}.toml"));
        ok(&stereotrace(&[
            "new".as_ref(),
            data().join("scenes").join(model).as_os_str(),
            "-o".as_ref(),
            p.as_os_str(),
        ]));
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(
            text.contains("path = \"../../../../tests/data/scenes/"),
            "the scene path is relative to the pipeline's folder: {text}"
        );
        ok(&stereotrace(&["check".as_ref(), p.as_os_str()]));
        let out = dir.join("out").join(&*name);
        ok(&stereotrace(&[
            "render".as_ref(),
            "--quiet".as_ref(),
            "--frames".as_ref(),
            "0..0".as_ref(),
            "--out".as_ref(),
            out.as_os_str(),
            p.as_os_str(),
        ]));
        assert!(out.join("0000_left.png").is_file() && out.join("0000_right.png").is_file());
        // Every output kind the file offers is a valid one.
        let all = dir.join("pipelines").join(format!("{name}_all.toml"));
        std::fs::write(&all, every_output(&text)).unwrap();
        let check = ok(&stereotrace(&["check".as_ref(), all.as_os_str()]));
        assert!(!check.contains("error"), "{check}");
        assert_eq!(every_output(&text).matches("[[output]]").count(), 8);
    }
}

#[test]
fn new_refuses_to_overwrite_and_prints_to_standard_output_without_a_file() {
    let dir = scratch("new-pipeline-overwrite");
    let scene = data().join("scenes/Box/Box.glb");
    let p = dir.join("p.toml");
    std::fs::write(&p, "mine").unwrap();
    let o = stereotrace(&[
        "new".as_ref(),
        scene.as_os_str(),
        "-o".as_ref(),
        p.as_os_str(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("exists already"));
    assert_eq!(std::fs::read_to_string(&p).unwrap(), "mine");
    // On standard output the scene path is absolute: the pipeline may be saved anywhere.
    let o = stereotrace(&["new".as_ref(), scene.as_os_str()]);
    ok(&o);
    let q = dir.join("elsewhere").join("q.toml");
    std::fs::create_dir_all(q.parent().unwrap()).unwrap();
    std::fs::write(&q, &o.stdout).unwrap();
    ok(&stereotrace(&["check".as_ref(), q.as_os_str()]));
}

/// Fox.glb's three clips (Survey, Walk, Run) drive the same joints: `new` plays the first and
/// lists the others, its frame range is that clip's, and `check` of it says nothing about
/// animations; with `animation = "all"` the clips play over each other and `check` warns. A
/// file whose clips drive different nodes (InterpolationTest) keeps "all" without a warning.
#[test]
fn new_plays_one_of_clips_that_drive_the_same_nodes() {
    let dir = scratch("new-fox");
    let fox = data().join("scenes/Fox/Fox.glb");
    let text = String::from_utf8(ok_stdout(&[fox.as_os_str()])).unwrap();
    assert!(text.contains("\nanimation = \"Survey\"\n"), "{text}");
    assert!(
        text.contains("\"Walk\"") && text.contains("\"Run\""),
        "{text}"
    );
    // Survey lasts 3.42 s: 82 frames at 24 fps.
    assert!(text.contains("\nend = 82 "), "{text}");
    let one = dir.join("one.toml");
    std::fs::write(&one, &text).unwrap();
    let checked = ok(&stereotrace(&["check".as_ref(), one.as_os_str()]));
    assert!(!checked.contains("drive the same nodes"), "{checked}");
    let all = dir.join("all.toml");
    std::fs::write(
        &all,
        text.replace("\nanimation = \"Survey\"\n", "\nanimation = \"all\"\n"),
    )
    .unwrap();
    let warned = ok(&stereotrace(&["check".as_ref(), all.as_os_str()]));
    assert!(
        warned.contains("\"Run\" over \"Walk\"") && warned.contains("drive the same nodes"),
        "{warned}"
    );

    let clips = data().join("scenes/InterpolationTest/InterpolationTest.glb");
    let text = String::from_utf8(ok_stdout(&[clips.as_os_str()])).unwrap();
    assert!(text.contains("\nanimation = \"all\""), "{text}");
    let p = dir.join("clips.toml");
    std::fs::write(&p, &text).unwrap();
    let checked = ok(&stereotrace(&["check".as_ref(), p.as_os_str()]));
    assert!(!checked.contains("drive the same nodes"), "{checked}");
}

/// `new SCENE` to standard output, which must succeed.
fn ok_stdout(scene: &[&std::ffi::OsStr]) -> Vec<u8> {
    let mut args = vec!["new".as_ref()];
    args.extend_from_slice(scene);
    let o = stereotrace(&args);
    ok(&o);
    o.stdout
}
