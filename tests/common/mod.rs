//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use stereotrace::output::image::Image;
use stereotrace::pipeline::LoadedPipeline;
use stereotrace::pipeline::run::{RunOptions, run};

pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// `../shared` beside the repository (CI always provides it).
pub fn shared() -> PathBuf {
    repo().join("..").join("shared")
}

/// A fresh empty directory under the target folder.
pub fn scratch(name: &str) -> PathBuf {
    let d = repo().join("target").join("test-scratch").join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Static reference scene folders (those with a scene.gltf and params.json).
pub fn reference_dirs() -> Vec<PathBuf> {
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(shared().join("refs"))
        .map(|rd| rd.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    dirs.retain(|d| d.join("scene.gltf").is_file() && d.join("params.json").is_file());
    dirs.sort();
    dirs
}

/// A pipeline file for a reference scene built from its params.json.
pub fn reference_pipeline(dir: &Path, out: &Path) -> PathBuf {
    let params: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("params.json")).unwrap()).unwrap();
    let res = &params["resolution"];
    let bg = &params["background"];
    let text = format!(
        "[scene]\npath = {scene:?}\n[render]\nwidth = {w}\nheight = {h}\nspp = {spp}\nmax_depth = {depth}\nbackground = [{b0}, {b1}, {b2}]\n[stereo]\nrig = \"off-axis\"\ninteraxial = {ia}\nconvergence = {cv}\n[[output]]\nkind = \"exr\"\npath = \"ours.exr\"\n",
        scene = dir.join("scene.gltf").to_string_lossy(),
        w = res[0],
        h = res[1],
        spp = params["spp"],
        depth = params["max_depth"],
        b0 = bg[0],
        b1 = bg[1],
        b2 = bg[2],
        ia = params["interaxial"],
        cv = params["convergence"],
    );
    let path = out.join("pipeline.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// Renders a reference scene with its parameters; returns (eye name, image) pairs.
pub fn render_reference(dir: &Path) -> Vec<(String, Image)> {
    let name = dir.file_name().unwrap().to_string_lossy().to_string();
    let out = scratch(&format!("ref-{name}"));
    let pipeline = reference_pipeline(dir, &out);
    let p = LoadedPipeline::load(&pipeline).unwrap();
    run(
        &p,
        &RunOptions {
            frames: None,
            threads: None,
            out_dir: out.clone(),
            progress: false,
        },
    )
    .unwrap();
    stereotrace::output::exr::read_views(&out.join("ours.exr")).unwrap()
}
