//! Every kind of bad input gets a clear message naming the file and the problem, exit status 2,
//! no panic, and no output file.

mod common;

use base64::Engine;
use common::{bounded, files_under, scratch};
use serde_json::json;
use std::path::{Path, PathBuf};
use std::process::Command;

/// A one-triangle glTF with an embedded buffer; `edit` may change the JSON before it is written.
fn triangle_gltf(positions: [[f32; 3]; 3], edit: impl FnOnce(&mut serde_json::Value)) -> String {
    let bytes: Vec<u8> = positions
        .iter()
        .flatten()
        .flat_map(|f| f.to_le_bytes())
        .collect();
    let data = base64::engine::general_purpose::STANDARD.encode(&bytes);
    let mut g = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0}, {"name": "Cam", "camera": 0, "translation": [0.0, 0.0, 3.0]}],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [-1.0, -1.0, 0.0], "max": [1.0, 1.0, 0.0]}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "buffers": [{"byteLength": 36, "uri": format!("data:application/octet-stream;base64,{data}")}]
    });
    edit(&mut g);
    serde_json::to_string(&g).unwrap()
}

const GOOD_TRIANGLE: [[f32; 3]; 3] = [[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 1.0, 0.0]];

fn pipeline(scene: &str, extra: &str) -> String {
    format!(
        "[scene]\npath = \"{scene}\"\n[render]\nwidth = 8\nheight = 6\nspp = 1\n{extra}\n[[output]]\nkind = \"png\"\npath = \"img_{{eye}}.png\"\n"
    )
}

struct Case {
    dir: PathBuf,
}

impl Case {
    fn new(name: &str) -> Case {
        let dir = scratch(&format!("bad-{name}"));
        std::fs::create_dir_all(dir.join("out")).unwrap();
        Case { dir }
    }

    fn file(&self, name: &str, content: impl AsRef<[u8]>) -> PathBuf {
        let p = self.dir.join(name);
        if let Some(parent) = p.parent() {
            std::fs::create_dir_all(parent).unwrap();
        }
        std::fs::write(&p, content).unwrap();
        p
    }

    /// Runs `render` of `pipeline` into the case's `out` folder.
    fn render(&self, pipeline: &Path) -> std::process::Output {
        Command::new(env!("CARGO_BIN_EXE_stereotrace"))
            .args(["render", "--quiet", "--out"])
            .arg(self.dir.join("out"))
            .arg(pipeline)
            .output()
            .unwrap()
    }

    /// Runs `render` and checks that it succeeds.
    fn renders(&self, pipeline: &Path) {
        let out = self.render(pipeline);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }

    /// Runs `render` and checks the failure contract; returns stderr.
    fn fails(&self, pipeline: &Path, expected_in_message: &[&str]) -> String {
        let out = self.render(pipeline);
        let stderr = String::from_utf8_lossy(&out.stderr).to_string();
        assert_eq!(out.status.code(), Some(2), "stderr: {stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
        for e in expected_in_message {
            assert!(stderr.contains(e), "expected '{e}' in: {stderr}");
        }
        let written: Vec<_> = files_under(&self.dir.join("out"));
        assert!(
            written.is_empty(),
            "files written despite the error: {written:?}"
        );
        stderr
    }
}

#[test]
fn missing_pipeline_file() {
    let c = Case::new("missing-pipeline");
    c.fails(&c.dir.join("nope.toml"), &["nope.toml"]);
}

#[test]
fn missing_scene_file() {
    let c = Case::new("missing-scene");
    let p = c.file("p.toml", pipeline("absent.gltf", ""));
    c.fails(&p, &["p.toml:2:", "absent.gltf", "does not exist"]);
}

#[test]
fn malformed_toml() {
    let c = Case::new("malformed-toml");
    let p = c.file("p.toml", "[scene\npath = 3\n");
    c.fails(&p, &["p.toml:1:"]);
}

#[test]
fn unknown_key() {
    let c = Case::new("unknown-key");
    c.file("s.gltf", triangle_gltf(GOOD_TRIANGLE, |_| {}));
    let p = c.file("p.toml", pipeline("s.gltf", "samples = 4"));
    c.fails(&p, &["p.toml:7:", "samples"]);
}

#[test]
fn wrong_type() {
    let c = Case::new("wrong-type");
    c.file("s.gltf", triangle_gltf(GOOD_TRIANGLE, |_| {}));
    let p = c.file(
        "p.toml",
        pipeline("s.gltf", "").replace("width = 8", "width = \"wide\""),
    );
    c.fails(&p, &["p.toml:4:", "invalid type"]);
}

#[test]
fn out_of_range_value() {
    let c = Case::new("range");
    c.file("s.gltf", triangle_gltf(GOOD_TRIANGLE, |_| {}));
    let p = c.file("p.toml", pipeline("s.gltf", "[stereo]\nconvergence = -1.0"));
    c.fails(&p, &["p.toml:8:", "convergence"]);
    let p = c.file(
        "p2.toml",
        pipeline("s.gltf", "").replace("height = 6", "height = 20000"),
    );
    c.fails(&p, &["p2.toml:5:", "height"]);
}

#[test]
fn truncated_glb() {
    let c = Case::new("truncated-glb");
    let glb = std::fs::read(common::data().join("scenes/Box/Box.glb")).unwrap();
    c.file("s.glb", &glb[..glb.len() / 2]);
    let p = c.file("p.toml", pipeline("s.glb", ""));
    c.fails(&p, &["s.glb"]);
}

#[test]
fn malformed_gltf_json() {
    let c = Case::new("malformed-gltf");
    c.file("s.gltf", "{\"asset\": {\"version\": \"2.0\"}, \"nodes\": [");
    let p = c.file("p.toml", pipeline("s.gltf", ""));
    c.fails(&p, &["s.gltf", "not a readable glTF"]);
}

#[test]
fn buffer_uri_escaping_the_scene_folder() {
    let c = Case::new("uri-escape");
    c.file("secret.bin", [0u8; 36]);
    c.file(
        "scene/s.gltf",
        triangle_gltf(GOOD_TRIANGLE, |g| {
            g["buffers"][0]["uri"] = json!("../secret.bin")
        }),
    );
    let p = c.file("p.toml", pipeline("scene/s.gltf", ""));
    c.fails(&p, &["s.gltf", "buffers[0]", "escapes"]);
}

#[test]
fn buffer_uri_that_does_not_exist() {
    let c = Case::new("uri-missing");
    c.file(
        "s.gltf",
        triangle_gltf(GOOD_TRIANGLE, |g| {
            g["buffers"][0]["uri"] = json!("missing.bin")
        }),
    );
    let p = c.file("p.toml", pipeline("s.gltf", ""));
    c.fails(&p, &["s.gltf", "buffers[0]", "missing.bin"]);
}

#[test]
fn accessor_reading_out_of_bounds() {
    let c = Case::new("accessor-oob");
    c.file(
        "s.gltf",
        triangle_gltf(GOOD_TRIANGLE, |g| g["accessors"][0]["count"] = json!(30)),
    );
    let p = c.file("p.toml", pipeline("s.gltf", ""));
    c.fails(
        &p,
        &[
            "s.gltf",
            "meshes[0].primitives[0].attributes.POSITION",
            "past the end",
        ],
    );
}

#[test]
fn nan_and_infinite_vertex_positions() {
    for (name, bad) in [("nan", f32::NAN), ("inf", f32::INFINITY)] {
        let c = Case::new(name);
        let mut tri = GOOD_TRIANGLE;
        tri[1][2] = bad;
        c.file("s.gltf", triangle_gltf(tri, |_| {}));
        let p = c.file("p.toml", pipeline("s.gltf", ""));
        c.fails(&p, &["s.gltf", "POSITION", "element 1 is not finite"]);
    }
}

#[test]
fn camera_name_that_does_not_exist() {
    let c = Case::new("camera");
    c.file("s.gltf", triangle_gltf(GOOD_TRIANGLE, |_| {}));
    let p = c.file(
        "p.toml",
        pipeline("s.gltf", "").replace("path = \"s.gltf\"", "path = \"s.gltf\"\ncamera = \"Nope\""),
    );
    c.fails(&p, &["p.toml:3:", "Nope", "Cam"]);
}

#[test]
fn output_path_escaping_the_output_directory() {
    let c = Case::new("out-escape");
    c.file("s.gltf", triangle_gltf(GOOD_TRIANGLE, |_| {}));
    let p = c.file(
        "p.toml",
        pipeline("s.gltf", "").replace("img_{eye}.png", "../../img_{eye}.png"),
    );
    c.fails(&p, &["p.toml:10:", "escapes the output directory"]);
    let p = c.file(
        "p2.toml",
        pipeline("s.gltf", "").replace("img_{eye}.png", "/tmp/img_{eye}.png"),
    );
    c.fails(&p, &["p2.toml:10:", "absolute"]);
}

#[test]
fn the_valid_triangle_renders() {
    // The baseline of the cases above: the same files without the defect succeed.
    let c = Case::new("valid");
    c.file("s.gltf", triangle_gltf(GOOD_TRIANGLE, |_| {}));
    let p = c.file("p.toml", pipeline("s.gltf", ""));
    c.renders(&p);
    assert!(c.dir.join("out/img_left.png").is_file());
    assert!(c.dir.join("out/img_right.png").is_file());
}

#[test]
fn an_output_path_whose_extension_is_not_the_format_written() {
    let c = Case::new("extension");
    c.file("s.gltf", triangle_gltf(GOOD_TRIANGLE, |_| {}));
    let anaglyph = pipeline("s.gltf", "")
        .replace("kind = \"png\"", "kind = \"anaglyph\"")
        .replace("img_{eye}.png", "a.jpg");
    let p = c.file("p.toml", anaglyph);
    c.fails(&p, &["p.toml:10:", "PNG", ".png"]);
    let exr = pipeline("s.gltf", "")
        .replace("kind = \"png\"", "kind = \"exr\"")
        .replace("img_{eye}.png", "b.png");
    let p = c.file("p2.toml", exr);
    c.fails(&p, &["p2.toml:10:", "EXR", ".exr"]);
}

#[test]
fn a_pipeline_without_outputs() {
    let c = Case::new("no-outputs");
    c.file("s.gltf", triangle_gltf(GOOD_TRIANGLE, |_| {}));
    let text = pipeline("s.gltf", "");
    let p = c.file("p.toml", &text[..text.find("[[output]]").unwrap()]);
    c.fails(&p, &["p.toml", "no [[output]]", "kind = \"png\""]);
}

#[test]
fn a_scene_given_where_a_pipeline_is_expected() {
    let c = Case::new("scene-as-pipeline");
    let glb = std::fs::read(common::data().join("scenes/Box/Box.glb")).unwrap();
    let p = c.file("Box.glb", &glb);
    c.fails(
        &p,
        &["Box.glb", "glTF scene, not a pipeline", "stereotrace new"],
    );
    // Binary that is not glTF either.
    let p = c.file("p.toml", [0xff, 0xfe, 0x00, 0x81]);
    c.fails(&p, &["p.toml", "not a pipeline", "UTF-8"]);
}

#[test]
fn a_bad_value_inside_an_output_points_at_its_key() {
    let c = Case::new("output-value");
    c.file("s.gltf", triangle_gltf(GOOD_TRIANGLE, |_| {}));
    let text = pipeline("s.gltf", "")
        .replace("kind = \"png\"", "kind = \"anaglyph\"\nmethod = \"bogus\"")
        .replace("img_{eye}.png", "a.png");
    let p = c.file("p.toml", text);
    c.fails(&p, &["p.toml:10:10:", "bogus"]);
}

#[test]
fn an_unknown_animation_lists_the_ones_there_are() {
    let c = Case::new("animation-name");
    let scene = common::data().join("scenes/InterpolationTest/InterpolationTest.glb");
    let text = pipeline(&scene.to_string_lossy(), "")
        .replace("[render]", "animation = \"Spinning\"\n[render]");
    let p = c.file("p.toml", text);
    c.fails(
        &p,
        &[
            "p.toml:3:",
            "no animation named 'Spinning'",
            "\"Step Scale\"",
        ],
    );
}

/// A value out of the schema's range that would give infinite, NaN or negative radiance is
/// refused at load, naming the object.
#[test]
fn factors_and_lights_that_would_give_non_finite_or_negative_radiance() {
    type Edit = fn(&mut serde_json::Value);
    let cases: [(&str, Edit, &str); 6] = [
        (
            "base-colour",
            |g| {
                g["materials"] =
                    json!([{"pbrMetallicRoughness": {"baseColorFactor": [1e39, 1.0, 1.0, 1.0]}}]);
                g["meshes"][0]["primitives"][0]["material"] = json!(0);
            },
            "materials[0].pbrMetallicRoughness.baseColorFactor",
        ),
        (
            "emissive",
            |g| {
                g["materials"] = json!([{"emissiveFactor": [-1.0, 0.0, 0.0]}]);
                g["meshes"][0]["primitives"][0]["material"] = json!(0);
            },
            "materials[0].emissiveFactor",
        ),
        (
            "light-intensity",
            |g| {
                g["extensionsUsed"] = json!(["KHR_lights_punctual"]);
                g["extensions"] = json!({"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 1e39}]}});
                g["nodes"][1]["extensions"] = json!({"KHR_lights_punctual": {"light": 0}});
            },
            "lights[0].intensity",
        ),
        (
            "light-colour",
            |g| {
                g["extensionsUsed"] = json!(["KHR_lights_punctual"]);
                g["extensions"] = json!({"KHR_lights_punctual": {"lights": [{"type": "point", "color": [1.0, -2.0, 1.0]}]}});
                g["nodes"][1]["extensions"] = json!({"KHR_lights_punctual": {"light": 0}});
            },
            "lights[0].color",
        ),
        (
            "texcoord",
            |g| {
                let uv: Vec<u8> = [0.0f32, 0.0, f32::NAN, 0.0, 1.0, 1.0]
                    .iter()
                    .flat_map(|f| f.to_le_bytes())
                    .collect();
                let data = base64::engine::general_purpose::STANDARD.encode(&uv);
                g["buffers"].as_array_mut().unwrap().push(json!({"byteLength": 24, "uri": format!("data:application/octet-stream;base64,{data}")}));
                g["bufferViews"]
                    .as_array_mut()
                    .unwrap()
                    .push(json!({"buffer": 1, "byteLength": 24}));
                g["accessors"].as_array_mut().unwrap().push(
                    json!({"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"}),
                );
                g["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(1);
            },
            "TEXCOORD_0",
        ),
        (
            "vertex-colour",
            |g| {
                let rgba: Vec<u8> = [
                    1.0f32, 1.0, 1.0, 1.0, -5.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0,
                ]
                .iter()
                .flat_map(|f| f.to_le_bytes())
                .collect();
                let data = base64::engine::general_purpose::STANDARD.encode(&rgba);
                g["buffers"].as_array_mut().unwrap().push(json!({"byteLength": 48, "uri": format!("data:application/octet-stream;base64,{data}")}));
                g["bufferViews"]
                    .as_array_mut()
                    .unwrap()
                    .push(json!({"buffer": 1, "byteLength": 48}));
                g["accessors"].as_array_mut().unwrap().push(
                    json!({"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC4"}),
                );
                g["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = json!(1);
            },
            "COLOR_0",
        ),
    ];
    for (name, edit, object) in cases {
        let c = Case::new(&format!("radiance-{name}"));
        c.file("s.gltf", triangle_gltf(GOOD_TRIANGLE, edit));
        let p = c.file("p.toml", pipeline("s.gltf", ""));
        c.fails(&p, &["s.gltf", object]);
    }
}

/// Documents on which the glTF crate's validation or readers panic are refused before it reads
/// them, naming the object, in `render`, `check` and `info` alike.
#[test]
fn documents_that_would_panic_the_gltf_reader() {
    type Edit = fn(&mut serde_json::Value);
    let cases: [(&str, Edit, &str); 5] = [
        (
            "float-indices",
            |g| {
                g["accessors"].as_array_mut().unwrap().push(
                    json!({"bufferView": 0, "componentType": 5126, "count": 3, "type": "SCALAR"}),
                );
                g["meshes"][0]["primitives"][0]["indices"] = json!(1);
            },
            "meshes[0].primitives[0].indices",
        ),
        (
            "channel-node",
            |g| {
                g["accessors"].as_array_mut().unwrap().push(
                    json!({"bufferView": 0, "componentType": 5126, "count": 1, "type": "SCALAR"}),
                );
                g["animations"] = json!([{"channels": [{"sampler": 0, "target": {"node": 7, "path": "translation"}}], "samplers": [{"input": 1, "output": 0}]}]);
            },
            "animations[0].channels[0].target.node",
        ),
        (
            "channel-path",
            |g| {
                g["accessors"].as_array_mut().unwrap().push(
                    json!({"bufferView": 0, "componentType": 5126, "count": 1, "type": "SCALAR"}),
                );
                g["animations"] = json!([{"channels": [{"sampler": 0, "target": {"node": 0, "path": "color"}}], "samplers": [{"input": 1, "output": 0}]}]);
            },
            "animations[0].channels[0].target.path",
        ),
        (
            "position-index",
            |g| g["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(99),
            "attributes.POSITION: 99 is not an index into accessors",
        ),
        (
            "position-vec2",
            |g| {
                g["accessors"][0]["type"] = json!("VEC2");
                g["accessors"][0]["count"] = json!(4);
            },
            "POSITION must be VEC3",
        ),
    ];
    for (name, edit, object) in cases {
        let c = Case::new(&format!("gltf-{name}"));
        let scene = c.file("s.gltf", triangle_gltf(GOOD_TRIANGLE, edit));
        let p = c.file("p.toml", pipeline("s.gltf", ""));
        c.fails(&p, &["s.gltf", object]);
        for command in ["check", "info"] {
            let target = if command == "info" { &scene } else { &p };
            let o = Command::new(env!("CARGO_BIN_EXE_stereotrace"))
                .arg(command)
                .arg(target)
                .output()
                .unwrap();
            let stderr = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(2), "{name} {command}: {stderr}");
            assert!(stderr.contains(object), "{name} {command}: {stderr}");
        }
    }
}

#[test]
fn a_glb_whose_header_lies_about_its_length() {
    let c = Case::new("glb-length");
    let mut glb = std::fs::read(common::data().join("scenes/Box/Box.glb")).unwrap();
    glb.extend_from_slice(&[0; 8]);
    c.file("s.glb", &glb);
    let p = c.file("p.toml", pipeline("s.glb", ""));
    c.fails(
        &p,
        &[
            "s.glb",
            "the GLB header gives a length of 1664 bytes, but the file has 1672",
        ],
    );
}

#[test]
fn outputs_that_would_write_over_each_other_or_the_inputs() {
    let c = Case::new("collisions");
    c.file("s.gltf", triangle_gltf(GOOD_TRIANGLE, |_| {}));
    let with = |outputs: &str| {
        format!(
            "[scene]\npath = \"s.gltf\"\n[render]\nwidth = 8\nheight = 6\nspp = 1\n[frames]\nend = 3\n{outputs}"
        )
    };
    // The same files under two spellings.
    let p = c.file(
        "p1.toml",
        with("[[output]]\nkind = \"png\"\npath = \"a/f{frame}_{eye}.png\"\n[[output]]\nkind = \"png\"\npath = \"./a/b/../f{frame}_{eye}.png\"\n"),
    );
    c.fails(
        &p,
        &["p1.toml:14:", "[[output]] number 2 writes a/f0_left.png"],
    );
    // A fixed name that one frame of another output takes.
    let p = c.file(
        "p2.toml",
        with("[[output]]\nkind = \"wobble-gif\"\npath = \"w2.gif\"\n[[output]]\nkind = \"wobble-gif\"\nper_frame = true\npath = \"w{frame}.gif\"\n"),
    );
    c.fails(&p, &["p2.toml:15:", "writes w2.gif"]);
    // Two videos of one name.
    let p = c.file(
        "p3.toml",
        with("[[output]]\nkind = \"anaglyph\"\npath = \"a{frame}.png\"\nvideo = \"v.mp4\"\n[[output]]\nkind = \"side-by-side\"\npath = \"s{frame}.png\"\nvideo = \"v.mp4\"\n"),
    );
    c.fails(
        &p,
        &[
            "p3.toml:16:",
            "the video of [[output]] number 2 writes v.mp4",
        ],
    );
}

#[test]
fn an_output_that_would_overwrite_the_pipeline_itself() {
    let c = Case::new("overwrite-input");
    c.file("s.gltf", triangle_gltf(GOOD_TRIANGLE, |_| {}));
    // The pipeline is saved under the name an output writes, in the output folder.
    let p = c.file("out/img_left.png", pipeline("../s.gltf", ""));
    let before = std::fs::read(&p).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_stereotrace"))
        .args(["render", "--quiet", "--out"])
        .arg(c.dir.join("out"))
        .arg(&p)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("would overwrite") && stderr.contains("an input of this run"),
        "{stderr}"
    );
    assert_eq!(std::fs::read(&p).unwrap(), before);
}

#[test]
fn values_that_were_accepted_in_silence() {
    let c = Case::new("silent");
    c.file("s.gltf", triangle_gltf(GOOD_TRIANGLE, |_| {}));
    let p = c.file(
        "p.toml",
        pipeline("s.gltf", "background = [0.1, 0.2, 0.3, 0.4]"),
    );
    c.fails(
        &p,
        &[
            "p.toml:7:",
            "expected three numbers (red, green, blue), got 4",
        ],
    );
    c.file(
        "old.gltf",
        triangle_gltf(GOOD_TRIANGLE, |g| g["asset"]["version"] = json!("1.0")),
    );
    let p = c.file("p2.toml", pipeline("old.gltf", ""));
    c.fails(&p, &["old.gltf", "asset.version", "glTF 2.x"]);
}

#[test]
fn a_folder_where_a_file_is_expected_is_bad_input() {
    let c = Case::new("folder");
    std::fs::create_dir_all(c.dir.join("p.toml")).unwrap();
    c.fails(&c.dir.join("p.toml"), &["p.toml"]);
    let o = Command::new(env!("CARGO_BIN_EXE_stereotrace"))
        .arg("info")
        .arg(&c.dir)
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

#[test]
fn benchmark_settings_that_measure_nothing() {
    for args in [
        &[
            "bench",
            "sweep",
            "p.toml",
            "--sweep",
            "render.spp=1",
            "--repeat",
            "0",
        ][..],
        &[
            "bench",
            "sweep",
            "p.toml",
            "--sweep",
            "render.spp=1",
            "--threshold",
            "nan",
        ],
        &["bench", "accel", "generated:10", "--repeat", "0"],
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_stereotrace"))
            .args(args)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(
            stderr.contains("--repeat") || stderr.contains("--threshold"),
            "{stderr}"
        );
    }
}

/// Renders a one-frame anaglyph with a video through a stand-in `ffmpeg` running `script`
/// (after answering `-version`); returns the exit status, stderr and the video files left.
fn render_with_fake_ffmpeg(name: &str, script: &str) -> (Option<i32>, String, Vec<PathBuf>) {
    render_with_fake_ffmpeg_at(name, script, (8, 6))
}

/// `render_with_fake_ffmpeg` at a film size, with the encoder watchdog at 2 s; the render
/// must end within 20 s.
fn render_with_fake_ffmpeg_at(
    name: &str,
    script: &str,
    (width, height): (u32, u32),
) -> (Option<i32>, String, Vec<PathBuf>) {
    use std::os::unix::fs::PermissionsExt;
    let c = Case::new(name);
    let bin = c.dir.join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    let fake = bin.join("ffmpeg");
    std::fs::write(
        &fake,
        format!("#!/bin/sh\n[ \"$1\" = -version ] && exit 0\n{script}"),
    )
    .unwrap();
    std::fs::set_permissions(&fake, std::fs::Permissions::from_mode(0o755)).unwrap();
    c.file("s.gltf", triangle_gltf(GOOD_TRIANGLE, |_| {}));
    let text = pipeline("s.gltf", "")
        .replace(
            "width = 8\nheight = 6",
            &format!("width = {width}\nheight = {height}"),
        )
        .replace("kind = \"png\"", "kind = \"anaglyph\"")
        .replace("img_{eye}.png", "a.png\"\nvideo = \"a.mp4");
    let p = c.file("p.toml", text);
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let mut render = Command::new(env!("CARGO_BIN_EXE_stereotrace"));
    render
        .args(["render", "--quiet", "--out"])
        .arg(c.dir.join("out"))
        .arg(&p)
        .env("PATH", path)
        .env("STEREOTRACE_ENCODER_TIMEOUT", "2");
    let o = bounded(render);
    let videos = files_under(&c.dir.join("out"))
        .into_iter()
        .filter(|f| f.to_string_lossy().contains(".mp4"))
        .collect();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
        videos,
    )
}

/// An encoder that fails (a stand-in `ffmpeg` that reads its input and reports a full disk) is
/// a failed write: exit 1 naming the video, and no video file or temporary left.
#[test]
fn a_failing_video_encoder_is_a_write_error() {
    let (code, stderr, videos) = render_with_fake_ffmpeg(
        "video-fails",
        "cat > /dev/null\necho 'No space left on device' >&2\nexit 1\n",
    );
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("a.mp4") && stderr.contains("No space left"),
        "{stderr}"
    );
    assert!(videos.is_empty(), "{videos:?}");
}

/// An encoder that exits 0 having written a cut-off file (ffmpeg on a full disk) does not get
/// its file kept.
#[test]
fn a_video_cut_off_by_a_full_disk_is_not_kept() {
    // The last argument is the output file: an 'ftyp' box and the start of 'mdat', no 'moov'.
    let (code, stderr, videos) = render_with_fake_ffmpeg(
        "video-cut",
        "cat > /dev/null\nfor last; do :; done\nprintf '\\000\\000\\000\\010ftyp\\000\\000\\001\\000mdat' > \"$last\"\nexit 0\n",
    );
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("a.mp4") && stderr.contains("broken video"),
        "{stderr}"
    );
    assert!(videos.is_empty(), "{videos:?}");
}

/// An encoder that stops reading its input, or never exits after it, is stopped by the
/// watchdog: exit 1 naming the video, no video file or temporary left, well within 20 s.
#[test]
fn an_encoder_that_stops_reading_does_not_hang_the_render() {
    // Never reads and never exits: a frame small enough to sit in the pipe's buffer.
    let (code, stderr, videos) = render_with_fake_ffmpeg("video-silent", "exec sleep 30\n");
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("a.mp4") && stderr.contains("did not exit after its input ended"),
        "{stderr}"
    );
    assert!(videos.is_empty(), "{videos:?}");
    // A frame larger than the pipe's buffer (256 x 192 x 3 bytes): the write itself blocks.
    let (code, stderr, videos) =
        render_with_fake_ffmpeg_at("video-stuck", "exec sleep 30\n", (256, 192));
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("a.mp4") && stderr.contains("stopped reading its input"),
        "{stderr}"
    );
    assert!(videos.is_empty(), "{videos:?}");
}

/// Runs stereotrace, failing the test (instead of hanging) past 20 s.
fn run_bounded(args: &[&std::ffi::OsStr]) -> std::process::Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_stereotrace"));
    c.args(args);
    bounded(c)
}

#[test]
fn devices_pipes_and_absurd_thread_counts_are_refused() {
    let c = Case::new("devices");
    let o = run_bounded(&["info".as_ref(), "/dev/zero".as_ref()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("not a regular file"));
    // A buffer URI that names a named pipe with no writer.
    let fifo = c.dir.join("data.bin");
    assert!(
        Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    c.file(
        "s.gltf",
        triangle_gltf(GOOD_TRIANGLE, |g| {
            g["buffers"][0]["uri"] = json!("data.bin");
        }),
    );
    let p = c.file("p.toml", pipeline("s.gltf", ""));
    let o = run_bounded(&["check".as_ref(), p.as_os_str()]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("buffers[0]") && stderr.contains("not a regular file"),
        "{stderr}"
    );
    c.file("good.gltf", triangle_gltf(GOOD_TRIANGLE, |_| {}));
    let good = c.file("good.toml", pipeline("good.gltf", ""));
    let o = run_bounded(&[
        "render".as_ref(),
        "--threads".as_ref(),
        "1000000".as_ref(),
        good.as_os_str(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--threads"));
}

#[test]
fn an_output_that_would_overwrite_a_file_of_the_scene() {
    let c = Case::new("overwrite-scene-image");
    // The scene names an image beside it; the outputs are written into the scene's folder.
    c.file("img_left.png", b"an image of the scene");
    c.file(
        "s.gltf",
        triangle_gltf(GOOD_TRIANGLE, |g| {
            g["images"] = json!([{"uri": "img_left.png"}]);
        }),
    );
    let p = c.file("p.toml", pipeline("s.gltf", ""));
    let o = Command::new(env!("CARGO_BIN_EXE_stereotrace"))
        .args(["render", "--quiet", "--out"])
        .arg(&c.dir)
        .arg(&p)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("img_left.png, an input of this run"),
        "{stderr}"
    );
    assert_eq!(
        std::fs::read(c.dir.join("img_left.png")).unwrap(),
        b"an image of the scene"
    );
}

#[test]
fn output_names_that_can_never_be_written() {
    let c = Case::new("unwritable-names");
    c.file("s.gltf", triangle_gltf(GOOD_TRIANGLE, |_| {}));
    let with = |outputs: &str| {
        format!("[scene]\npath = \"s.gltf\"\n[render]\nwidth = 8\nheight = 6\nspp = 1\n{outputs}")
    };
    let long = "x".repeat(300);
    let cases = [
        (
            "[[output]]\nkind = \"exr\"\npath = \"f.exr/\"\n".to_string(),
            "names a folder, not a file",
        ),
        (
            "[[output]]\nkind = \"exr\"\npath = \"f\\u0000.exr\"\n".to_string(),
            "NUL character",
        ),
        (
            format!("[[output]]\nkind = \"exr\"\npath = \"{long}.exr\"\n"),
            "is 304 bytes long; file systems allow 255",
        ),
        (
            "[[output]]\nkind = \"exr\"\npath = \"a.exr\"\n[[output]]\nkind = \"exr\"\npath = \"a.exr/b.exr\"\n".to_string(),
            "writes into the folder a.exr, which [[output]] number 1 writes as a file",
        ),
        (
            "[[output]]\nkind = \"anaglyph\"\npath = \"a.png\"\nvideo = \"v.mp4/\"\n".to_string(),
            "names a folder",
        ),
    ];
    for (k, (outputs, expected)) in cases.iter().enumerate() {
        let p = c.file(&format!("p{k}.toml"), with(outputs));
        c.fails(&p, &[&format!("p{k}.toml:"), expected]);
    }
}

#[test]
fn compare_refuses_a_difference_image_over_an_input() {
    let c = Case::new("compare-diff-over-input");
    let a = c.file("a.png", b"");
    image::RgbImage::from_pixel(2, 2, image::Rgb([10, 20, 30]))
        .save(&a)
        .unwrap();
    let b = c.dir.join("b.png");
    std::fs::copy(&a, &b).unwrap();
    let before = std::fs::read(&a).unwrap();
    for diff in [&a, &c.dir.join("./b.png")] {
        let o = Command::new(env!("CARGO_BIN_EXE_stereotrace"))
            .arg("compare")
            .args([&a, &b])
            .arg("--diff")
            .arg(diff)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{stderr}");
        assert!(stderr.contains("--diff would overwrite"), "{stderr}");
    }
    assert_eq!(std::fs::read(&a).unwrap(), before);
    assert_eq!(std::fs::read(&b).unwrap(), before);
}

/// A one-triangle glTF whose buffer is `positions` then `extra` bytes (base64 inline), with
/// `edit` adding what uses them.
fn triangle_with_bytes(extra: &[u8], edit: impl FnOnce(&mut serde_json::Value)) -> String {
    let mut bytes: Vec<u8> = GOOD_TRIANGLE
        .iter()
        .flatten()
        .flat_map(|f| f.to_le_bytes())
        .collect();
    bytes.extend_from_slice(extra);
    let data = base64::engine::general_purpose::STANDARD.encode(&bytes);
    let len = bytes.len();
    triangle_gltf(GOOD_TRIANGLE, |g| {
        g["buffers"][0] = json!({
            "byteLength": len,
            "uri": format!("data:application/octet-stream;base64,{data}")
        });
        edit(g);
    })
}

/// The triangle skinned by one joint: JOINTS_0 (unsigned bytes) at byte 36, WEIGHTS_0 at 48.
fn skinned_triangle(joints: [[u8; 4]; 3], weights: [[f32; 4]; 3]) -> String {
    let mut extra: Vec<u8> = joints.iter().flatten().copied().collect();
    extra.extend(weights.iter().flatten().flat_map(|f| f.to_le_bytes()));
    triangle_with_bytes(&extra, |g| {
        g["scenes"][0]["nodes"] = json!([0, 1, 2]);
        g["nodes"][0]["skin"] = json!(0);
        g["nodes"]
            .as_array_mut()
            .unwrap()
            .push(json!({"name": "joint"}));
        g["skins"] = json!([{"joints": [2]}]);
        g["meshes"][0]["primitives"][0]["attributes"]["JOINTS_0"] = json!(1);
        g["meshes"][0]["primitives"][0]["attributes"]["WEIGHTS_0"] = json!(2);
        let acc = g["accessors"].as_array_mut().unwrap();
        acc.push(json!({"bufferView": 1, "componentType": 5121, "count": 3, "type": "VEC4"}));
        acc.push(json!({"bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC4"}));
        let views = g["bufferViews"].as_array_mut().unwrap();
        views.push(json!({"buffer": 0, "byteOffset": 36, "byteLength": 12}));
        views.push(json!({"buffer": 0, "byteOffset": 48, "byteLength": 48}));
    })
}

/// `check` accepts the pipeline.
fn checks_ok(p: &Path) {
    let o = Command::new(env!("CARGO_BIN_EXE_stereotrace"))
        .arg("check")
        .arg(p)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn skins_and_sparse_accessors_that_would_lose_vertices() {
    let c = Case::new("skins-sparse");
    let one = [[1.0, 0.0, 0.0, 0.0]; 3];
    // The skinned triangle itself renders.
    c.file("good.gltf", skinned_triangle([[0; 4]; 3], one));
    let p = c.file("good.toml", pipeline("good.gltf", ""));
    checks_ok(&p);
    // A vertex weighing a joint the skin does not have.
    c.file(
        "joint.gltf",
        skinned_triangle([[0; 4], [3, 0, 0, 0], [0; 4]], one),
    );
    let p = c.file("joint.toml", pipeline("joint.gltf", ""));
    c.fails(
        &p,
        &[
            "meshes[0].primitives[0].attributes.JOINTS_0",
            "vertex 1 weighs joint 3, but nodes[0] is skinned by skins[0], which has 1 joints",
        ],
    );
    // NaN and negative weights.
    for (name, w) in [("nan", f32::NAN), ("negative", -0.5)] {
        let weights = [
            [1.0, 0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0, 0.0],
            [w, 0.0, 0.0, 0.0],
        ];
        c.file(
            &format!("{name}.gltf"),
            skinned_triangle([[0; 4]; 3], weights),
        );
        let p = c.file(
            &format!("{name}.toml"),
            pipeline(&format!("{name}.gltf"), ""),
        );
        c.fails(
            &p,
            &[
                "attributes.WEIGHTS_0",
                "vertex 2 has weights",
                "finite and non-negative",
            ],
        );
    }
    // Sparse POSITION: one index (an unsigned byte at 36) and its value (at 40).
    let sparse = |index: u8| {
        let mut extra = vec![index, 0, 0, 0];
        extra.extend([0.0f32, 0.5, 0.0].iter().flat_map(|f| f.to_le_bytes()));
        triangle_with_bytes(&extra, |g| {
            g["accessors"][0]["sparse"] = json!({
                "count": 1,
                "indices": {"bufferView": 1, "componentType": 5121},
                "values": {"bufferView": 2}
            });
            let views = g["bufferViews"].as_array_mut().unwrap();
            views.push(json!({"buffer": 0, "byteOffset": 36, "byteLength": 1}));
            views.push(json!({"buffer": 0, "byteOffset": 40, "byteLength": 12}));
        })
    };
    c.file("sparse-ok.gltf", sparse(2));
    let p = c.file("sparse-ok.toml", pipeline("sparse-ok.gltf", ""));
    checks_ok(&p);
    c.file("sparse.gltf", sparse(7));
    let p = c.file("sparse.toml", pipeline("sparse.gltf", ""));
    c.fails(
        &p,
        &[
            "attributes.POSITION.sparse.indices",
            "index 7 at position 0 is out of range: the accessor has 3 elements",
        ],
    );
}

/// A one-pixel PNG as a `data:` URI, for materials that need a texture that decodes.
fn png_uri() -> String {
    let mut png = Vec::new();
    image::RgbaImage::from_pixel(1, 1, image::Rgba([128, 128, 255, 255]))
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    format!(
        "data:image/png;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&png)
    )
}

/// The triangle with TEXCOORD_0 (accessor 1) and a TANGENT whose w is `w` (accessor 2, unused
/// unless `edit` names it), material 0 `material`, texture 0 a PNG that decodes.
fn material_triangle(
    material: serde_json::Value,
    w: f32,
    edit: impl FnOnce(&mut serde_json::Value),
) -> String {
    let uv = [0.0f32, 0.0, 1.0, 0.0, 0.5, 1.0];
    let tangents = [1.0f32, 0.0, 0.0, w].repeat(3);
    let extra: Vec<u8> = uv
        .iter()
        .chain(&tangents)
        .flat_map(|f| f.to_le_bytes())
        .collect();
    let uri = png_uri();
    triangle_with_bytes(&extra, |g| {
        g["bufferViews"] = json!([
            {"buffer": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 24},
            {"buffer": 0, "byteOffset": 60, "byteLength": 48}
        ]);
        g["accessors"].as_array_mut().unwrap().extend([
            json!({"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"}),
            json!({"bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC4"}),
        ]);
        g["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(1);
        g["meshes"][0]["primitives"][0]["material"] = json!(0);
        g["materials"] = json!([material]);
        g["images"] = json!([{ "uri": uri }]);
        g["textures"] = json!([{"source": 0}]);
        edit(g);
    })
}

/// Material inputs that cannot be rendered (WHITTED-materials.md's inputs) are refused with the
/// object named, never a panic or NaN pixels.
#[test]
fn material_inputs_that_cannot_be_rendered() {
    let normal = json!({"normalTexture": {"index": 0}});
    let cases: Vec<(&str, String, &str)> = vec![
        (
            "image-without-source",
            material_triangle(json!({}), 1.0, |g| {
                g["images"] = json!([{"name": "nothing"}])
            }),
            "images[0]",
        ),
        (
            "image-view-without-mime-type",
            material_triangle(json!({}), 1.0, |g| g["images"] = json!([{"bufferView": 1}])),
            "images[0].mimeType",
        ),
        (
            "normal-map-without-texcoords",
            material_triangle(normal.clone(), 1.0, |g| {
                g["meshes"][0]["primitives"][0]["attributes"]
                    .as_object_mut()
                    .unwrap()
                    .remove("TEXCOORD_0");
            }),
            "materials[0].normalTexture reads TEXCOORD_0",
        ),
        (
            "tangent-handedness",
            material_triangle(normal.clone(), 0.5, |g| {
                g["meshes"][0]["primitives"][0]["attributes"]["TANGENT"] = json!(2);
            }),
            "attributes.TANGENT",
        ),
        (
            "tangent-type",
            material_triangle(normal.clone(), 1.0, |g| {
                g["accessors"][2]["type"] = json!("VEC3");
                g["accessors"][2]["count"] = json!(4);
                g["meshes"][0]["primitives"][0]["attributes"]["TANGENT"] = json!(2);
            }),
            "TANGENT must be VEC4",
        ),
        (
            "texture-transform",
            material_triangle(
                json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0,
                    "extensions": {"KHR_texture_transform": {"offset": [1e39, 0.0]}}}}}),
                1.0,
                |g| g["extensionsUsed"] = json!(["KHR_texture_transform"]),
            ),
            "baseColorTexture.extensions.KHR_texture_transform",
        ),
        (
            "alpha-cutoff",
            material_triangle(
                json!({"alphaMode": "MASK", "alphaCutoff": -0.5}),
                1.0,
                |_| {},
            ),
            "alphaCutoff",
        ),
        (
            "emissive-strength",
            material_triangle(
                json!({"extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 1e39}}}),
                1.0,
                |_| {},
            ),
            "emissiveStrength",
        ),
    ];
    for (name, scene, object) in cases {
        let c = Case::new(&format!("material-{name}"));
        c.file("s.gltf", scene);
        let p = c.file("p.toml", pipeline("s.gltf", ""));
        c.fails(&p, &["s.gltf", object]);
    }
    // The control: the same triangle, normal-mapped with good tangents, renders.
    let c = Case::new("material-good");
    c.file(
        "s.gltf",
        material_triangle(normal, 1.0, |g| {
            g["meshes"][0]["primitives"][0]["attributes"]["TANGENT"] = json!(2);
        }),
    );
    let p = c.file("p.toml", pipeline("s.gltf", ""));
    c.renders(&p);
}
