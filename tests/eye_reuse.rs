//! `[render] eye_reuse = "paired"` traces both eyes in one pass with their rays in shared packets;
//! it must change only time: the images are bit for bit those of `"off"`.

mod common;

use common::{reference_dirs, reference_pipeline, repo, scratch};
use std::path::Path;
use stereotrace::pipeline::LoadedPipeline;
use stereotrace::render::EyeReuse;
use stereotrace::run::{RunOptions, run};

/// The EXR bytes of `pipeline` rendered with `eye_reuse` set as given.
fn render(pipeline: &Path, eye_reuse: &str, threads: usize, name: &str) -> Vec<u8> {
    let text = std::fs::read_to_string(pipeline).unwrap();
    let out = scratch(name);
    let edited = out.join("pipeline.toml");
    let dir = pipeline.parent().unwrap();
    // Relative paths in the pipeline stay relative to its own folder.
    let text = text
        .replace(
            "[render]",
            &format!("[render]\neye_reuse = \"{eye_reuse}\""),
        )
        .replace("\"../scenes/", &format!("\"{}/../scenes/", dir.display()));
    std::fs::write(&edited, text).unwrap();
    let p = LoadedPipeline::load(&edited).unwrap();
    let expected = if eye_reuse == "paired" {
        EyeReuse::Paired
    } else {
        EyeReuse::Off
    };
    assert_eq!(p.spec.render.eye_reuse, expected, "the setting took");
    run(
        &p,
        &RunOptions {
            frames: None,
            threads: Some(threads),
            out_dir: out.clone(),
            progress: false,
            shard: None,
            resume: false,
        },
    )
    .unwrap();
    let exr = std::fs::read_dir(&out)
        .unwrap()
        .chain(std::fs::read_dir(out.join("out")).into_iter().flatten())
        .filter_map(|e| e.ok().map(|e| e.path()))
        .find(|p| p.extension().is_some_and(|x| x == "exr"))
        .expect("an EXR output");
    std::fs::read(exr).unwrap()
}

#[test]
fn paired_eyes_give_the_images_of_separate_eyes_on_every_reference_scene() {
    let dirs = reference_dirs();
    assert!(
        !dirs.is_empty(),
        "no reference scenes under tests/data/refs"
    );
    for dir in dirs {
        let name = dir.file_name().unwrap().to_string_lossy().to_string();
        let pipeline = reference_pipeline(&dir, &scratch(&format!("reuse-{name}")));
        let off = render(&pipeline, "off", 2, &format!("reuse-{name}-off"));
        let paired = render(&pipeline, "paired", 2, &format!("reuse-{name}-paired"));
        assert!(off == paired, "{name}: paired EXR differs from off");
    }
}

#[test]
fn paired_eyes_do_not_depend_on_the_thread_count() {
    let pipeline = repo().join("pipelines/default.toml");
    let one = render(&pipeline, "paired", 1, "reuse-default-1");
    let two = render(&pipeline, "paired", 2, "reuse-default-2");
    let off = render(&pipeline, "off", 2, "reuse-default-off");
    assert!(one == two, "paired EXR differs between 1 and 2 threads");
    assert!(
        one == off,
        "paired EXR differs from off on the default pipeline"
    );
}

#[test]
fn an_unknown_eye_reuse_is_refused_with_the_allowed_values() {
    let out = scratch("reuse-bad");
    let path = out.join("bad.toml");
    let text = std::fs::read_to_string(repo().join("pipelines/default.toml"))
        .unwrap()
        .replace("[render]", "[render]\neye_reuse = \"sometimes\"");
    std::fs::write(&path, text).unwrap();
    let err = match LoadedPipeline::load(&path) {
        Ok(_) => panic!("an unknown eye_reuse was accepted"),
        Err(e) => e.to_string(),
    };
    assert!(
        err.contains("eye_reuse") || err.contains("unknown variant `sometimes`"),
        "{err}"
    );
    assert!(
        err.contains("paired"),
        "the message lists the values: {err}"
    );
}
