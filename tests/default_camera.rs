//! A scene without a camera gets one framing camera for the pipeline's whole frame range (a
//! single frame or a shard of the range sees what the full render sees), and a scene without
//! lights a head-light that leaves the nearest white surfaces short of clipping.

mod common;

use common::{data, scratch};
use std::path::Path;
use std::process::Command;

/// A pipeline over frames 0..=`end` of a sample model with no camera and no lights.
fn pipeline(dir: &Path, model: &str, end: u32) -> std::path::PathBuf {
    let text = format!(
        "[scene]\npath = {scene:?}\nanimation = \"all\"\n[render]\nwidth = 160\nheight = 120\nspp = 1\nbackground = [0.0, 0.0, 0.0]\n[frames]\nstart = 0\nend = {end}\nfps = 24\n[[output]]\nkind = \"png\"\npath = \"f_{{frame:04}}_{{eye}}.png\"\n",
        scene = data().join("scenes").join(model).to_string_lossy(),
    );
    let p = dir.join("p.toml");
    std::fs::write(&p, text).unwrap();
    p
}

fn render(pipeline: &Path, out: &Path, frames: &str) -> String {
    let o = Command::new(env!("CARGO_BIN_EXE_stereotrace"))
        .args(["render", "--threads", "2", "--frames", frames, "--out"])
        .arg(out)
        .arg(pipeline)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(o.status.success(), "{stderr}");
    stderr
}

#[test]
fn one_frame_of_the_range_is_framed_as_in_the_full_render() {
    let dir = scratch("default-camera-range");
    let p = pipeline(&dir, "BoxAnimated/BoxAnimated.glb", 47);
    let (full, single) = (dir.join("full"), dir.join("single"));
    render(&p, &full, "0..47");
    let stderr = render(&p, &single, "30..30");
    assert!(
        stderr.contains("over frames 0..47"),
        "the warning says how the camera was framed: {stderr}"
    );
    for eye in ["left", "right"] {
        let name = format!("f_0030_{eye}.png");
        assert_eq!(
            std::fs::read(full.join(&name)).unwrap(),
            std::fs::read(single.join(&name)).unwrap(),
            "{name}: a single frame gets the camera of the whole range"
        );
    }
}

#[test]
fn the_head_light_does_not_clip_a_white_model() {
    let dir = scratch("default-camera-exposure");
    // AnimatedMorphSphere is white; with the head-light at the scene's centre distance 44% of
    // its pixels clipped.
    let p = pipeline(&dir, "AnimatedMorphSphere/AnimatedMorphSphere.glb", 47);
    render(&p, &dir, "0..0");
    let img = image::open(dir.join("f_0000_left.png")).unwrap().to_rgb8();
    let object: Vec<_> = img.pixels().filter(|p| p.0 != [0, 0, 0]).collect();
    let clipped = object.iter().filter(|p| p.0.contains(&255)).count();
    assert!(object.len() > 1000, "the model is in view");
    assert!(
        clipped * 100 < object.len(),
        "{clipped} of {} pixels clip",
        object.len()
    );
}
