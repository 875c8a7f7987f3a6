//! Third-party sample models from `tests/data/scenes/` load and render: textures, scenes without
//! lights or cameras, several cameras, transmission. Each render must be finite and not black.

mod common;

use common::{data, scratch};
use std::process::Command;
use stereotrace::output::exr::read_views;

fn render(
    model: &str,
    extra_scene_keys: &str,
) -> (String, Vec<(String, stereotrace::output::image::Image)>) {
    let name = model.replace('/', "_");
    let dir = scratch(&format!("sample-{name}"));
    let pipeline = dir.join("p.toml");
    std::fs::write(
        &pipeline,
        format!(
            "[scene]\npath = {:?}\n{extra_scene_keys}\n[render]\nwidth = 48\nheight = 32\nspp = 1\n[[output]]\nkind = \"exr\"\npath = \"img.exr\"\n",
            data().join("scenes").join(model).to_string_lossy()
        ),
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_stereotrace"))
        .args(["render", "--out"])
        .arg(&dir)
        .arg(&pipeline)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(out.status.success(), "{model}: {stderr}");
    (stderr, read_views(&dir.join("img.exr")).unwrap())
}

fn assert_lit(model: &str, views: &[(String, stereotrace::output::image::Image)]) {
    assert_eq!(views.len(), 2, "{model}: both eyes");
    for (eye, img) in views {
        assert!(
            img.pixels.iter().all(|p| p.is_finite()),
            "{model} {eye}: non-finite pixel"
        );
        let lit = img.pixels.iter().filter(|p| p.max_element() > 1e-4).count();
        assert!(
            lit > img.pixels.len() / 40,
            "{model} {eye}: only {lit} lit pixels"
        );
    }
}

#[test]
fn textured_model_with_its_own_camera_and_no_lights_gets_a_head_light() {
    let (stderr, views) = render("Duck/Duck.glb", "");
    assert!(stderr.contains("no lights"), "{stderr}");
    assert_lit("Duck", &views);
}

#[test]
fn model_without_camera_is_framed_by_the_default_camera() {
    let (stderr, views) = render("Box/Box.glb", "");
    assert!(stderr.contains("no camera"), "{stderr}");
    assert_lit("Box", &views);
}

#[test]
fn punctual_lights_and_transmission() {
    let (_, views) = render("LightsPunctualLamp/LightsPunctualLamp.gltf", "");
    assert!(
        views
            .iter()
            .all(|(_, img)| img.pixels.iter().all(|p| p.is_finite()))
    );
}

#[test]
fn a_camera_is_chosen_by_index() {
    let (_, views) = render("Cameras/Cameras.gltf", "camera = 0");
    assert!(
        views
            .iter()
            .all(|(_, img)| img.pixels.iter().all(|p| p.is_finite()))
    );
}

#[test]
fn info_reports_what_the_scene_holds() {
    let out = Command::new(env!("CARGO_BIN_EXE_stereotrace"))
        .args(["info", "--accel", "--json"])
        .arg(data().join("scenes/RiggedFigure/RiggedFigure.glb"))
        .output()
        .unwrap();
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["skins"], 1);
    assert_eq!(v["animations"].as_array().unwrap().len(), 1);
    assert!(v["triangles"].as_u64().unwrap() > 0);
    assert!(v["accel"]["nodes"].as_u64().unwrap() > 1);
}
