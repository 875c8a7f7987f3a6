//! Third-party sample models from `tests/data/scenes/` load and render: textures, scenes without
//! lights or cameras, several cameras, transmission. Each render must be finite and not black.

mod common;

use common::{data, repo, scratch};
use std::path::Path;
use std::process::Command;
use stereotrace::output::exr::read_views;
use stereotrace::output::image::Image;

fn render(model: &str, extra_scene_keys: &str) -> (String, Vec<(String, Image)>) {
    let scene = data().join("scenes").join(model);
    render_at(&scene, extra_scene_keys, "width = 48\nheight = 32\nspp = 1")
}

/// Renders `scene` with `[scene]` keys and `[render]` keys added to a pipeline that writes one
/// multi-view EXR on the default (black) background: stderr and the eyes' images.
fn render_at(scene: &Path, scene_keys: &str, render_keys: &str) -> (String, Vec<(String, Image)>) {
    let name = scene.file_stem().unwrap().to_string_lossy();
    let dir = scratch(&format!("sample-{name}-{}", render_keys.len()));
    let pipeline = dir.join("p.toml");
    std::fs::write(
        &pipeline,
        format!(
            "[scene]\npath = {:?}\n{scene_keys}\n[render]\n{render_keys}\n[[output]]\nkind = \"exr\"\npath = \"img.exr\"\n",
            scene.to_string_lossy()
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
    assert!(out.status.success(), "{name}: {stderr}");
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

/// Real assets with normal, metallic-roughness and emissive textures, texture transforms, MASK
/// and BLEND coverage and COLOR_0 render every input they use: no warning that one is ignored,
/// and under 5% of the model's pixels clipped (any channel over 1) at the default exposure.
/// Before these inputs were read, DamagedHelmet's emissive factor of 1 without its texture made
/// the whole helmet emit white: every model pixel clipped.
///
/// LightsPunctualLamp is rendered with its lights off: lit, 9% of its pixels clip, all of them
/// highlights of its 15 to 180 cd point lights on polished brass (correct under WHITTED.md's
/// lights, which no exposure choice of the tool changes); its emission alone must not clip.
#[test]
fn real_assets_render_their_material_inputs_without_clipping() {
    let dark = scratch("lamp-lights-off");
    let lamp = data().join("scenes/LightsPunctualLamp");
    for file in std::fs::read_dir(&lamp).unwrap() {
        let file = file.unwrap().path();
        std::fs::copy(&file, dark.join(file.file_name().unwrap())).unwrap();
    }
    let gltf = dark.join("LightsPunctualLamp.gltf");
    let mut doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&gltf).unwrap()).unwrap();
    for light in doc["extensions"]["KHR_lights_punctual"]["lights"]
        .as_array_mut()
        .unwrap()
    {
        light["intensity"] = serde_json::json!(0.0);
    }
    std::fs::write(&gltf, doc.to_string()).unwrap();
    // (scene, lit): an unlit scene shows its emission alone, none of which may clip.
    let assets = [
        (data().join("scenes/DamagedHelmet/DamagedHelmet.glb"), true),
        (gltf, false),
        (repo().join("scenes/cutout.gltf"), true),
    ];
    for (scene, lit) in assets {
        let name = scene.file_stem().unwrap().to_string_lossy().to_string();
        let (stderr, views) = render_at(&scene, "", "width = 96\nheight = 54\nspp = 4");
        // Inputs outside this set may still be reported (LightsPunctualLamp's
        // transmissionTexture is: Whitted glass reads the factor alone).
        let inputs = [
            "normalTexture",
            "metallicRoughnessTexture",
            "emissiveTexture",
            "emissive_strength",
            "texture_transform",
            "alphaMode",
            "COLOR_0",
            "TEXCOORD",
            "texCoord",
        ];
        for line in stderr.lines().filter(|l| l.contains("ignored")) {
            assert!(!inputs.iter().any(|i| line.contains(i)), "{name}: {line}");
        }
        for (eye, img) in &views {
            let model = img.pixels.iter().filter(|p| p.max_element() > 0.0).count();
            let clipped = img.pixels.iter().filter(|p| p.max_element() > 1.0).count();
            assert!(
                img.pixels.iter().all(|p| p.is_finite()),
                "{name} {eye}: non-finite pixel"
            );
            assert!(
                model * 50 > img.pixels.len() || (!lit && model > 0),
                "{name} {eye}: the model covers only {model} pixels"
            );
            assert!(
                clipped * 20 < model && (lit || clipped == 0),
                "{name} {eye}: {clipped} of the model's {model} pixels clipped"
            );
        }
    }
}

/// `info` says what each material's inputs become, and that occlusion has no effect.
#[test]
fn info_lists_each_materials_inputs() {
    let out = Command::new(env!("CARGO_BIN_EXE_stereotrace"))
        .args(["info", "--json"])
        .arg(data().join("scenes/DamagedHelmet/DamagedHelmet.glb"))
        .output()
        .unwrap();
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let inputs = v["material_inputs"][0]["inputs"].to_string();
    for expected in [
        "baseColorTexture",
        "metallicRoughnessTexture",
        "normalTexture",
        "emissiveTexture",
        "occlusionTexture: no effect",
        "alpha OPAQUE",
    ] {
        assert!(inputs.contains(expected), "{expected} not in {inputs}");
    }
    // Base colour and emissive share the sRGB decode, the data slots the linear one: four
    // textures, each decoded once.
    assert_eq!(v["textures_decoded"], 4);
}
