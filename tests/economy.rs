//! The tool models no more than a scene needs: untouched static geometry is built once, textures
//! no material uses are never decoded, an output that needs one eye traces one, and a mono rig
//! traces one view. Each claim is checked on what the run reports, not on timings.

mod common;
use common::{repo, scratch};
use stereotrace::pipeline::LoadedPipeline;
use stereotrace::run::{RunOptions, RunSummary, run};
use stereotrace::scene::Scene;

fn render(name: &str, scene: &str, extra: &str) -> (std::path::PathBuf, RunSummary) {
    let dir = scratch(name);
    let scene = repo().join("scenes").join(scene);
    let text = format!(
        "[scene]\npath = {scene:?}\nanimation = \"all\"\n[render]\nwidth = 40\nheight = 24\nspp = 1\n[frames]\nstart = 0\nend = 3\n{extra}"
    );
    std::fs::write(dir.join("p.toml"), text).unwrap();
    let p = LoadedPipeline::load(&dir.join("p.toml")).unwrap();
    let opts = RunOptions {
        frames: None,
        threads: None,
        out_dir: dir.join("out"),
        progress: false,
        shard: None,
        resume: false,
    };
    let s = run(&p, &opts).unwrap();
    (dir.join("out"), s)
}

#[test]
fn static_geometry_is_built_on_the_first_frame_and_reused_after() {
    let (out, _) = render(
        "economy-static",
        "whitted_animated.gltf",
        "[[output]]\nkind = \"exr\"\npath = \"f_{frame:04}.exr\"\n",
    );
    let log = std::fs::read_to_string(out.join("frame-log.csv")).unwrap();
    let rows: Vec<Vec<&str>> = log
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    let static_rows: Vec<&Vec<&str>> = rows.iter().filter(|r| r[1] == "static").collect();
    assert_eq!(static_rows.len(), 4, "one static row per frame:\n{log}");
    assert_eq!(static_rows[0][2], "build");
    for r in &static_rows[1..] {
        assert_eq!(r[2], "reuse", "frame {}: {log}", r[0]);
    }
    // The moving sphere is a rigid instance: its object-space tree is placed, never rebuilt.
    let moving: Vec<&Vec<&str>> = rows.iter().filter(|r| r[1] != "static").collect();
    assert!(!moving.is_empty(), "{log}");
    assert!(
        moving
            .iter()
            .skip(1)
            .all(|r| r[2] != "build" && r[2] != "rebuild"),
        "{log}"
    );
}

#[test]
fn textures_that_no_material_uses_are_never_decoded() {
    let dir = scratch("economy-textures");
    let mut doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(repo().join("scenes/whitted.gltf")).unwrap())
            .unwrap();
    // Two images that are not PNG at all: decoding either would fail the load. One is reachable
    // only from a texture no material names, the other only from an occlusion texture, which
    // the Whitted model does not read (it has no ambient light to occlude).
    let junk = "data:image/png;base64,bm90IGEgcG5nIGF0IGFsbA==";
    doc["images"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({ "uri": junk }));
    doc["images"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({ "uri": junk }));
    doc["textures"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({ "source": 1 }));
    doc["textures"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({ "source": 2 }));
    doc["materials"][1]["occlusionTexture"] = serde_json::json!({ "index": 2 });
    let path = dir.join("extra_textures.gltf");
    std::fs::write(&path, serde_json::to_string(&doc).unwrap()).unwrap();

    let scene = Scene::load(&path).unwrap();
    let decoded: Vec<usize> = scene.textures.iter().map(|t| t.source).collect();
    assert_eq!(
        decoded,
        [0],
        "only the checker is decoded: texture 1 is used by no material, texture 2 only as an \
         occlusion texture"
    );

    // The control: once a material's base colour names the junk image, loading must fail.
    doc["materials"][1]["pbrMetallicRoughness"]["baseColorTexture"] =
        serde_json::json!({ "index": 1 });
    std::fs::write(&path, serde_json::to_string(&doc).unwrap()).unwrap();
    let err = Scene::load(&path).unwrap_err().to_string();
    assert!(err.contains("cannot decode image"), "{err}");
}

#[test]
fn an_output_of_one_eye_traces_one_and_a_stereo_output_two() {
    let one = "[[output]]\nkind = \"pseudo-stereo\"\neye = \"left\"\npath = \"p_{frame:04}.png\"\n";
    let (_, s) = render("economy-one-eye", "whitted.gltf", one);
    assert_eq!((s.frames, s.eyes_traced), (4, 4));
    let two = "[[output]]\nkind = \"anaglyph\"\npath = \"a_{frame:04}.png\"\n";
    let (_, s) = render("economy-two-eyes", "whitted.gltf", two);
    assert_eq!((s.frames, s.eyes_traced), (4, 8));
}

#[test]
fn a_mono_rig_traces_one_view_per_frame_and_writes_one() {
    let (out, s) = render(
        "economy-mono",
        "whitted.gltf",
        "[stereo]\nrig = \"mono\"\n[[output]]\nkind = \"exr\"\npath = \"m_{frame:04}.exr\"\n",
    );
    assert_eq!((s.frames, s.eyes_traced), (4, 4));
    let views = stereotrace::output::exr::read_views(&out.join("m_0002.exr")).unwrap();
    let names: Vec<&str> = views.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names.len(), 1, "{names:?}");
}
