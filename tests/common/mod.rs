//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use stereotrace::output::image::Image;
use stereotrace::pipeline::LoadedPipeline;
use stereotrace::run::{RunOptions, run};

pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The test data kept in the repository (`tests/data/README.md`): the Mitsuba references and the
/// small sample models the suite reads, each with its license.
pub fn data() -> PathBuf {
    repo().join("tests").join("data")
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
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(data().join("refs"))
        .map(|rd| rd.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    dirs.retain(|d| d.join("scene.gltf").is_file() && d.join("params.json").is_file());
    dirs.sort();
    dirs
}

/// A pipeline file for a reference scene built from its params.json.
pub fn reference_pipeline(dir: &Path, out: &Path) -> PathBuf {
    reference_pipeline_on(dir, out, "cpu")
}

/// `reference_pipeline` traced by `backend` (`[render] backend`).
pub fn reference_pipeline_on(dir: &Path, out: &Path, backend: &str) -> PathBuf {
    let params: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("params.json")).unwrap()).unwrap();
    let res = &params["resolution"];
    let bg = &params["background"];
    let text = format!(
        "[scene]\npath = {scene:?}\n[render]\nbackend = {backend:?}\nwidth = {w}\nheight = {h}\nspp = {spp}\nmax_depth = {depth}\nbackground = [{b0}, {b1}, {b2}]\n[stereo]\nrig = \"off-axis\"\ninteraxial = {ia}\nconvergence = {cv}\n[[output]]\nkind = \"exr\"\npath = \"ours.exr\"\n",
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
    render_reference_on(dir, "cpu")
}

/// `render_reference` traced by `backend`.
pub fn render_reference_on(dir: &Path, backend: &str) -> Vec<(String, Image)> {
    let name = dir.file_name().unwrap().to_string_lossy().to_string();
    let out = scratch(&format!("ref-{name}-{backend}"));
    let pipeline = reference_pipeline_on(dir, &out, backend);
    let p = LoadedPipeline::load(&pipeline).unwrap();
    run(&p, &whole_range_into(&out)).unwrap();
    stereotrace::output::exr::read_views(&out.join("ours.exr")).unwrap()
}

/// Options that render a pipeline's whole range into `out`, with no progress bars.
pub fn whole_range_into(out: &Path) -> RunOptions {
    RunOptions {
        frames: None,
        threads: None,
        out_dir: out.to_path_buf(),
        progress: false,
        shard: None,
        resume: false,
    }
}

/// OpenImageIO's command-line tools folder and a Python that imports `OpenImageIO`: from
/// `STEREOTRACE_OIIO_BIN` / `STEREOTRACE_OIIO_PYTHON`, else what `scripts/test.sh` provisioned
/// under `target/tools`, else `idiff` and `python3` on the PATH. Not found, the calling test
/// fails with the way to get it, unless `STEREOTRACE_SKIP_OIIO=1` asks to skip it knowingly.
pub fn oiio() -> Option<(PathBuf, PathBuf)> {
    let provisioned = repo().join("target").join("tools").join("bin");
    let bin = std::env::var_os("STEREOTRACE_OIIO_BIN")
        .map(PathBuf::from)
        .or_else(|| {
            provisioned
                .join("idiff")
                .is_file()
                .then(|| provisioned.clone())
        })
        .or_else(|| which("idiff").and_then(|p| p.parent().map(Path::to_path_buf)));
    let python = std::env::var_os("STEREOTRACE_OIIO_PYTHON")
        .map(PathBuf::from)
        .or_else(|| {
            let p = provisioned.join("python");
            p.is_file().then_some(p)
        })
        .or_else(|| which("python3"));
    let found = match (bin, python) {
        (Some(b), Some(p)) if b.join("idiff").is_file() && python_has_oiio(&p) => Some((b, p)),
        _ => None,
    };
    if found.is_none() {
        missing_tool(
            "OpenImageIO (idiff and its Python module)",
            "STEREOTRACE_SKIP_OIIO",
        );
    }
    found
}

/// Whether ffmpeg runs. Not found, the calling test fails with the way to get it, unless
/// `STEREOTRACE_SKIP_FFMPEG=1` asks to skip it knowingly.
pub fn ffmpeg() -> bool {
    let ok = stereotrace::output::video::ffmpeg_available();
    if !ok {
        missing_tool("ffmpeg", "STEREOTRACE_SKIP_FFMPEG");
    }
    ok
}

/// A tool a test compares against is missing: a failure naming how to get it, or with
/// `skip_var=1` a skip said out loud (the test then checks nothing about that tool).
pub fn missing_tool(tool: &str, skip_var: &str) {
    if std::env::var(skip_var).as_deref() == Ok("1") {
        eprintln!("SKIPPED (by {skip_var}=1): the checks against {tool}");
        return;
    }
    panic!(
        "{tool} was not found. Run the suite with scripts/test.sh, which provisions it under \
         target/tools, or set {skip_var}=1 to skip the checks against it knowingly"
    );
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

/// Runs `c` to its end with its output captured, failing the test (instead of hanging) past
/// 20 s, the bound every hostile case is held to.
pub fn bounded(mut c: std::process::Command) -> std::process::Output {
    use std::process::Stdio;
    use std::time::{Duration, Instant};
    let mut child = c
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if t0.elapsed() > Duration::from_secs(20) {
            let _ = child.kill();
            panic!("{c:?} did not end within 20 s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

/// Every file under `dir` (none when it does not exist).
pub fn files_under(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    if let Ok(rd) = std::fs::read_dir(dir) {
        for e in rd.flatten() {
            let p = e.path();
            if p.is_dir() {
                out.extend(files_under(&p));
            } else {
                out.push(p);
            }
        }
    }
    out
}

/// Two triangles per quad, corners in order around it.
pub fn quad(c: [[f32; 3]; 4]) -> Vec<[f32; 3]> {
    vec![c[0], c[1], c[2], c[0], c[2], c[3]]
}

/// Triangle soups as one embedded glTF buffer: part k gets buffer view k and a POSITION
/// accessor k with its bounds. Returns the `bufferViews`, `accessors` and `buffers` arrays.
pub fn position_buffers(
    parts: &[&[[f32; 3]]],
) -> (serde_json::Value, serde_json::Value, serde_json::Value) {
    use base64::Engine as _;
    use serde_json::json;
    let mut bytes = Vec::new();
    let (mut views, mut accessors) = (Vec::new(), Vec::new());
    for (k, positions) in parts.iter().enumerate() {
        let offset = bytes.len();
        bytes.extend(positions.iter().flatten().flat_map(|f| f.to_le_bytes()));
        let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
        for p in positions.iter() {
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": positions.len() * 12}));
        accessors.push(json!({"bufferView": k, "componentType": 5126,
            "count": positions.len(), "type": "VEC3", "min": lo, "max": hi}));
    }
    let data = base64::engine::general_purpose::STANDARD.encode(&bytes);
    let buffers = json!([{"byteLength": bytes.len(),
        "uri": format!("data:application/octet-stream;base64,{data}")}]);
    (json!(views), json!(accessors), buffers)
}

/// Whether the machine has a GPU adapter for the GPU backend's tests: without one the calling
/// test fails saying how to get one, or with STEREOTRACE_SKIP_GPU=1 skips out loud.
#[cfg(feature = "gpu")]
pub fn gpu_adapter() -> Option<stereotrace::gpu::Gpu> {
    match stereotrace::gpu::Gpu::open() {
        Ok(g) => {
            eprintln!("adapter: {}", g.describe());
            Some(g)
        }
        Err(e) => {
            eprintln!("{e}");
            missing_tool(
                "a GPU adapter (without a card: Debian's mesa-vulkan-drivers)",
                "STEREOTRACE_SKIP_GPU",
            );
            None
        }
    }
}
