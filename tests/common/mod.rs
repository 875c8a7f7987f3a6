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

/// OpenImageIO's command-line tools folder and a Python that imports `OpenImageIO`, when
/// installed: from `STEREOTRACE_OIIO_BIN` / `STEREOTRACE_OIIO_PYTHON`, else `idiff` and
/// `python3` on the PATH. With `STEREOTRACE_REQUIRE_OIIO=1` (CI) a missing install is an error
/// instead of a skip.
pub fn oiio() -> Option<(PathBuf, PathBuf)> {
    let bin = std::env::var_os("STEREOTRACE_OIIO_BIN")
        .map(PathBuf::from)
        .or_else(|| which("idiff").and_then(|p| p.parent().map(Path::to_path_buf)));
    let python = std::env::var_os("STEREOTRACE_OIIO_PYTHON")
        .map(PathBuf::from)
        .or_else(|| which("python3"));
    let found = match (bin, python) {
        (Some(b), Some(p)) if b.join("idiff").is_file() && python_has_oiio(&p) => Some((b, p)),
        _ => None,
    };
    if found.is_none() {
        assert!(
            std::env::var("STEREOTRACE_REQUIRE_OIIO").as_deref() != Ok("1"),
            "STEREOTRACE_REQUIRE_OIIO=1 but OpenImageIO (idiff and the Python module) was not found"
        );
        eprintln!("skipped: OpenImageIO is not installed (pip install openimageio; see .ci/run)");
    }
    found
}

fn which(name: &str) -> Option<PathBuf> {
    std::env::var_os("PATH").and_then(|paths| {
        std::env::split_paths(&paths)
            .map(|d| d.join(name))
            .find(|p| p.is_file())
    })
}

fn python_has_oiio(python: &Path) -> bool {
    std::process::Command::new(python)
        .args(["-c", "import OpenImageIO"])
        .output()
        .is_ok_and(|o| o.status.success())
}

/// Whether ffmpeg runs; with `STEREOTRACE_REQUIRE_FFMPEG=1` (CI) its absence is an error.
pub fn ffmpeg() -> bool {
    let ok = stereotrace::output::video::ffmpeg_available();
    if !ok {
        assert!(
            std::env::var("STEREOTRACE_REQUIRE_FFMPEG").as_deref() != Ok("1"),
            "STEREOTRACE_REQUIRE_FFMPEG=1 but ffmpeg was not found"
        );
        eprintln!("skipped: ffmpeg is not installed (apt-get install ffmpeg; see .ci/run)");
    }
    ok
}
