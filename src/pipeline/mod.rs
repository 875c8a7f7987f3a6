//! Pipeline files: the TOML schema (serde structs are the single source of defaults), validation
//! with `file:line:column` errors, and the frame loop that drives a render (`run.rs`).

pub mod run;
pub mod template;

use crate::accel::SplitMethod;
use crate::error::{Error, Result};
use crate::output::color::{Display, ToneMap};
use crate::render::{Rig, ShadingModel};
use crate::scene::Scene;
use serde::Deserialize;
use std::ops::Range;
use std::path::{Path, PathBuf};
use template::PathTemplate;

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pipeline {
    pub scene: SceneSection,
    #[serde(default)]
    pub render: RenderSection,
    #[serde(default)]
    pub stereo: StereoSection,
    #[serde(default)]
    pub frames: FramesSection,
    #[serde(default)]
    pub accel: AccelSection,
    #[serde(default, rename = "output")]
    pub outputs: Vec<OutputSpec>,
}

/// A glTF object chosen by name or by index.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum Selector {
    Index(usize),
    Name(String),
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneSection {
    /// Relative to the pipeline file.
    pub path: String,
    /// Camera node name, camera name, or index into the glTF `cameras`; default: the first camera
    /// instance in scene order.
    #[serde(default)]
    pub camera: Option<Selector>,
    /// Animation name or index, `"all"` or `"none"`.
    #[serde(default = "default_animation")]
    pub animation: Selector,
}

fn default_animation() -> Selector {
    Selector::Name("all".into())
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RenderSection {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub max_depth: u32,
    pub shading: ShadingModel,
    pub background: [f32; 3],
    /// 0 = all cores.
    pub threads: usize,
}

impl Default for RenderSection {
    fn default() -> Self {
        RenderSection {
            width: 640,
            height: 360,
            spp: 4,
            max_depth: 8,
            shading: ShadingModel::CookTorrance,
            background: [0.0; 3],
            threads: 0,
        }
    }
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StereoSection {
    pub rig: Rig,
    pub interaxial: f32,
    pub convergence: f32,
}

impl Default for StereoSection {
    fn default() -> Self {
        StereoSection {
            rig: Rig::OffAxis,
            interaxial: 0.065,
            convergence: 3.0,
        }
    }
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FramesSection {
    pub start: u32,
    /// Inclusive.
    pub end: u32,
    pub fps: f32,
}

impl Default for FramesSection {
    fn default() -> Self {
        FramesSection {
            start: 0,
            end: 0,
            fps: 24.0,
        }
    }
}

#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "kebab-case")]
pub enum UpdateMode {
    Rebuild,
    Refit,
    #[default]
    Auto,
}

#[derive(Clone, Debug, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct AccelSection {
    pub split: SplitMethod,
    pub update: UpdateMode,
}

#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "kebab-case")]
pub enum ExrViews {
    /// One multi-view file holding every eye.
    #[default]
    Single,
    /// One file per eye (`{eye}` in the path).
    Separate,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum OutputSpec {
    Exr {
        path: String,
        #[serde(default)]
        half: bool,
        #[serde(default)]
        views: ExrViews,
    },
    Png {
        path: String,
        /// Stops.
        #[serde(default)]
        exposure: f32,
        #[serde(default)]
        tonemap: ToneMap,
    },
}

impl OutputSpec {
    pub fn path(&self) -> &str {
        match self {
            OutputSpec::Exr { path, .. } | OutputSpec::Png { path, .. } => path,
        }
    }

    pub fn display(&self) -> Display {
        match self {
            OutputSpec::Png {
                exposure, tonemap, ..
            } => Display {
                exposure: *exposure,
                tone_map: *tonemap,
            },
            OutputSpec::Exr { .. } => Display::default(),
        }
    }
}

/// A pipeline file read, checked and with its scene loaded: ready to render.
#[derive(Debug)]
pub struct LoadedPipeline {
    pub file: PathBuf,
    pub spec: Pipeline,
    pub scene: Scene,
    pub scene_path: PathBuf,
    pub templates: Vec<PathTemplate>,
    /// Index into `PosedScene::cameras` (scene traversal order), `None`: the default camera.
    pub camera_instance: Option<usize>,
    pub warnings: Vec<String>,
}

/// One segment of a key path (`output[2].path`), for locating a value in the source.
#[derive(Clone, Debug)]
pub enum Key<'a> {
    Name(&'a str),
    Index(usize),
}

/// A validation failure: the key it concerns and what is wrong.
struct Invalid<'a> {
    keys: Vec<Key<'a>>,
    message: String,
}

fn invalid<'a>(keys: &[Key<'a>], message: impl Into<String>) -> Invalid<'a> {
    Invalid {
        keys: keys.to_vec(),
        message: message.into(),
    }
}

/// 1-based line and column of a byte offset.
pub fn line_column(src: &str, offset: usize) -> (usize, usize) {
    let before = &src[..offset.min(src.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

/// Byte span of the value at a key path, if the source has it.
fn locate(src: &str, keys: &[Key]) -> Option<Range<usize>> {
    let doc = toml_edit::Document::parse(src).ok()?;
    let mut item = doc.as_item();
    let mut span = None;
    for k in keys {
        item = match k {
            Key::Name(n) => item.get(*n)?,
            Key::Index(i) => item.get(*i)?,
        };
        span = item.span().or(span);
    }
    span
}

impl Pipeline {
    /// Parses pipeline text; errors carry the file, line and column.
    pub fn parse(file: &Path, src: &str) -> Result<Pipeline> {
        toml::from_str::<Pipeline>(src).map_err(|e| {
            let (line, column) = e.span().map_or((1, 1), |s| line_column(src, s.start));
            Error::Pipeline {
                file: file.to_path_buf(),
                line,
                column,
                message: e.message().trim().to_string(),
            }
        })
    }
}

impl LoadedPipeline {
    /// Reads, parses and validates a pipeline file and loads its scene. No rendering happens and
    /// no file is written.
    pub fn load(file: &Path) -> Result<LoadedPipeline> {
        let src = std::fs::read_to_string(file).map_err(|e| Error::io(file, e))?;
        let spec = Pipeline::parse(file, &src)?;
        let at = |inv: Invalid| {
            let (line, column) =
                locate(&src, &inv.keys).map_or((1, 1), |s| line_column(&src, s.start));
            Error::Pipeline {
                file: file.to_path_buf(),
                line,
                column,
                message: inv.message,
            }
        };
        let templates = validate_values(&spec).map_err(at)?;
        let base = file.parent().unwrap_or(Path::new("."));
        let scene_path = base.join(&spec.scene.path);
        if !scene_path.is_file() {
            return Err(at(invalid(
                &[Key::Name("scene"), Key::Name("path")],
                format!("scene file '{}' does not exist", scene_path.display()),
            )));
        }
        let scene = Scene::load(&scene_path)?;
        let mut warnings = scene.warnings.clone();
        let camera_instance = resolve_camera(&spec, &scene, &mut warnings).map_err(at)?;
        if !scene.nodes.iter().any(|n| n.light.is_some()) {
            warnings.push(format!(
                "{}: the scene has no lights; using a head-light at the camera",
                scene_path.display()
            ));
        }
        check_animation(&spec, &scene, &mut warnings).map_err(at)?;
        Ok(LoadedPipeline {
            file: file.to_path_buf(),
            spec,
            scene,
            scene_path,
            templates,
            camera_instance,
            warnings,
        })
    }

    /// The eyes this pipeline renders.
    pub fn eyes(&self) -> Vec<crate::render::Eye> {
        use crate::render::Eye;
        if self.spec.stereo.rig == Rig::Mono {
            vec![Eye::Center]
        } else {
            vec![Eye::Left, Eye::Right]
        }
    }
}

/// Range checks that need no scene; returns the parsed output templates.
fn validate_values(p: &Pipeline) -> std::result::Result<Vec<PathTemplate>, Invalid<'static>> {
    use Key::Name as N;
    let r = &p.render;
    for (key, v) in [("width", r.width), ("height", r.height)] {
        if !(1..=16384).contains(&v) {
            return Err(invalid(
                &[N("render"), N(key)],
                format!("{key} must be between 1 and 16384, got {v}"),
            ));
        }
    }
    if !(1..=65536).contains(&r.spp) {
        return Err(invalid(
            &[N("render"), N("spp")],
            format!("spp must be between 1 and 65536, got {}", r.spp),
        ));
    }
    if !(1..=64).contains(&r.max_depth) {
        return Err(invalid(
            &[N("render"), N("max_depth")],
            format!("max_depth must be between 1 and 64, got {}", r.max_depth),
        ));
    }
    if r.background.iter().any(|c| !c.is_finite() || *c < 0.0) {
        return Err(invalid(
            &[N("render"), N("background")],
            "background must be three finite, non-negative numbers",
        ));
    }
    if r.threads > 1024 {
        return Err(invalid(
            &[N("render"), N("threads")],
            "threads must be between 0 (all cores) and 1024",
        ));
    }
    let s = &p.stereo;
    if !(s.interaxial.is_finite() && s.interaxial >= 0.0) {
        return Err(invalid(
            &[N("stereo"), N("interaxial")],
            format!(
                "interaxial must be a finite number >= 0, got {}",
                s.interaxial
            ),
        ));
    }
    if !(s.convergence.is_finite() && s.convergence > 0.0) {
        return Err(invalid(
            &[N("stereo"), N("convergence")],
            format!(
                "convergence must be a finite number > 0, got {}",
                s.convergence
            ),
        ));
    }
    let f = &p.frames;
    if f.end < f.start {
        return Err(invalid(
            &[N("frames"), N("end")],
            format!("end ({}) is before start ({})", f.end, f.start),
        ));
    }
    if !(f.fps.is_finite() && f.fps > 0.0 && f.fps <= 1000.0) {
        return Err(invalid(
            &[N("frames"), N("fps")],
            format!("fps must be in (0, 1000], got {}", f.fps),
        ));
    }
    let multi_frame = f.end > f.start;
    let stereo = s.rig != Rig::Mono;
    let mut templates = Vec::new();
    for (i, o) in p.outputs.iter().enumerate() {
        let keys = [N("output"), Key::Index(i), N("path")];
        let t = PathTemplate::parse(o.path()).map_err(|m| invalid(&keys, m))?;
        if multi_frame && !t.has_frame() {
            return Err(invalid(
                &keys,
                "several frames are rendered: the path needs {frame} so files do not overwrite each other",
            ));
        }
        let per_eye = match o {
            OutputSpec::Exr { views, .. } => *views == ExrViews::Separate,
            OutputSpec::Png { .. } => true,
        };
        if per_eye && stereo && !t.has_eye() {
            return Err(invalid(
                &keys,
                "this output writes one file per eye: the path needs {eye}",
            ));
        }
        if let OutputSpec::Png { exposure, .. } = o
            && !exposure.is_finite()
        {
            return Err(invalid(
                &[N("output"), Key::Index(i), N("exposure")],
                "exposure must be finite",
            ));
        }
        templates.push(t);
    }
    for (i, a) in templates.iter().enumerate() {
        for (j, b) in templates.iter().enumerate().skip(i + 1) {
            if a.render(f.start, "left") == b.render(f.start, "left") {
                return Err(invalid(
                    &[N("output"), Key::Index(j), N("path")],
                    format!("output {j} writes the same files as output {i}"),
                ));
            }
        }
    }
    Ok(templates)
}

fn resolve_camera(
    p: &Pipeline,
    scene: &Scene,
    warnings: &mut Vec<String>,
) -> std::result::Result<Option<usize>, Invalid<'static>> {
    use Key::Name as N;
    // Camera instances in the order `pose` lists them.
    let instances: Vec<(usize, usize)> = scene
        .traversal()
        .into_iter()
        .filter_map(|n| scene.nodes[n].camera.map(|c| (n, c)))
        .collect();
    let keys = [N("scene"), N("camera")];
    let chosen = match &p.scene.camera {
        None => {
            if instances.is_empty() {
                warnings.push(format!(
                    "{}: the scene has no camera; using a default camera that frames the scene's bounds",
                    scene.source.display()
                ));
                return Ok(None);
            }
            0
        }
        Some(Selector::Index(i)) => instances
            .iter()
            .position(|&(_, c)| c == *i)
            .ok_or_else(|| {
                invalid(&keys, format!("the scene has no instance of cameras[{i}] ({} camera(s) are placed in the scene)", instances.len()))
            })?,
        Some(Selector::Name(name)) => instances
            .iter()
            .position(|&(n, _)| scene.nodes[n].name.as_deref() == Some(name))
            .or_else(|| {
                instances
                    .iter()
                    .position(|&(_, c)| scene.cameras[c].name.as_deref() == Some(name))
            })
            .ok_or_else(|| {
                let names: Vec<String> = instances
                    .iter()
                    .map(|&(n, c)| {
                        scene.nodes[n].name.clone().or(scene.cameras[c].name.clone()).unwrap_or_else(|| format!("#{c}"))
                    })
                    .collect();
                invalid(&keys, format!("no camera named '{name}' in the scene (cameras: {})", names.join(", ")))
            })?,
    };
    let cam = &scene.cameras[instances[chosen].1];
    let aspect = p.render.width as f32 / p.render.height as f32;
    if let Some(a) = cam.aspect_ratio
        && (a - aspect).abs() > 0.01 * aspect
    {
        warnings.push(format!(
            "{}: camera aspect ratio {a:.3} differs from the output's {aspect:.3}; the vertical field of view is kept and the output's aspect used",
            scene.source.display()
        ));
    }
    Ok(Some(chosen))
}

fn check_animation(
    p: &Pipeline,
    scene: &Scene,
    warnings: &mut Vec<String>,
) -> std::result::Result<(), Invalid<'static>> {
    let keys = [Key::Name("scene"), Key::Name("animation")];
    match &p.scene.animation {
        Selector::Name(n) if n == "none" => return Ok(()),
        Selector::Name(n) if n == "all" => {}
        Selector::Name(n) => {
            if !scene
                .animations
                .iter()
                .any(|a| a.name.as_deref() == Some(n))
            {
                return Err(invalid(
                    &keys,
                    format!(
                        "no animation named '{n}' (the scene has {})",
                        scene.animations.len()
                    ),
                ));
            }
        }
        Selector::Index(i) => {
            if *i >= scene.animations.len() {
                return Err(invalid(
                    &keys,
                    format!(
                        "animation index {i} is out of range (the scene has {})",
                        scene.animations.len()
                    ),
                ));
            }
        }
    }
    if !scene.animations.is_empty() {
        warnings.push(format!(
            "{}: animation playback is not implemented yet; every frame renders the rest pose",
            scene.source.display()
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn minimal_pipeline_takes_the_documented_defaults() {
        let p = Pipeline::parse(Path::new("p.toml"), "[scene]\npath = \"s.gltf\"\n").unwrap();
        assert_eq!(
            (
                p.render.width,
                p.render.height,
                p.render.spp,
                p.render.max_depth
            ),
            (640, 360, 4, 8)
        );
        assert_eq!(p.stereo.rig, Rig::OffAxis);
        assert_eq!(p.stereo.interaxial, 0.065);
        assert_eq!(p.frames.fps, 24.0);
        assert_eq!(p.accel.split, SplitMethod::Sah);
        assert_eq!(p.scene.animation, Selector::Name("all".into()));
    }

    #[test]
    fn unknown_keys_are_reported_at_their_line() {
        let src = "[scene]\npath = \"s.gltf\"\n[render]\nwidht = 3\n";
        let e = Pipeline::parse(Path::new("p.toml"), src)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("p.toml:4:1:"), "{e}");
        assert!(e.contains("widht"), "{e}");
    }

    #[test]
    fn out_of_range_values_point_at_the_value() {
        let src = "[scene]\npath = \"s.gltf\"\n[render]\nwidth = 0\n";
        let p = Pipeline::parse(Path::new("p.toml"), src).unwrap();
        let inv = validate_values(&p).err().unwrap();
        let (line, col) = line_column(src, locate(src, &inv.keys).unwrap().start);
        assert_eq!((line, col), (4, 9));
    }

    #[test]
    fn output_keys_of_another_kind_are_unknown() {
        let src =
            "[scene]\npath = \"s\"\n[[output]]\nkind = \"exr\"\npath = \"a.exr\"\nexposure = 1\n";
        assert!(Pipeline::parse(Path::new("p.toml"), src).is_err());
    }
}
