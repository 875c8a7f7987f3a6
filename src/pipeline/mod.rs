//! Pipeline files: what a user asks a render to do. `schema` (the TOML structs and their
//! defaults), `output_spec` (every output kind's keys and facts), `location` (key paths to line
//! and column), `validate` (the rules), `collisions` (outputs that would overwrite each other or
//! an input), `edit` (setting keys by path for `bench sweep`), `template` (output paths) and
//! `starter` (the commented pipeline `new` writes for a scene). How frames are made from a
//! pipeline is `run/`. `LoadedPipeline` is the front door: a file read, checked and with its
//! scene loaded.

mod collisions;
mod edit;
mod location;
mod output_spec;
mod schema;
mod starter;
mod template;
mod validate;

pub use collisions::{Written, check_inputs_untouched, written};
pub use location::{Key, line_column};
pub use output_spec::{ExrViews, OutputSpec, PairLayout, SEQUENCE_FRAMES};
pub use schema::{
    AccelSection, FramesSection, Metres, Pipeline, RenderSection, SceneSection, Selector,
    StereoSection,
};
pub use starter::new_pipeline;
pub use template::PathTemplate;

use crate::error::{Error, Result};
use crate::output::ffmpeg_available;
use crate::render::{Rig, View};
use crate::scene::{Animation, Scene, overlapping_animations};
use edit::set_key;
use location::{Invalid, invalid, locate};
use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use validate::{check_animation, check_named_nodes, resolve_camera, validate_values};

/// A pipeline file read, checked and with its scene loaded: ready to render.
#[derive(Debug)]
pub struct LoadedPipeline {
    pub file: PathBuf,
    /// The pipeline text the spec was parsed from (`bench sweep` edits it key by key).
    pub source: String,
    pub spec: Pipeline,
    /// Shared, so that pipelines derived by `with_overrides` reuse the loaded scene.
    pub scene: Arc<Scene>,
    pub scene_path: PathBuf,
    pub templates: Vec<PathTemplate>,
    /// Index into `PosedScene::cameras` (scene traversal order), `None`: the default camera.
    pub camera_instance: Option<usize>,
    pub warnings: Vec<String>,
}

/// A pipeline file's text. A glTF scene given where a pipeline is expected (the likeliest
/// mistake), or any file that is not UTF-8 text, is refused with what to do instead.
fn pipeline_text(file: &Path, bytes: Vec<u8>) -> Result<String> {
    let ext = file
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    let gltf = bytes.starts_with(b"glTF") || matches!(ext.as_deref(), Some("glb" | "gltf"));
    if gltf {
        return Err(Error::input(
            file,
            "this is a glTF scene, not a pipeline: a pipeline is a TOML file that names the scene, \
             the frames, the stereo rig and the outputs. `stereotrace new SCENE > my.toml` writes \
             one for this scene; then `stereotrace render my.toml`",
        ));
    }
    String::from_utf8(bytes).map_err(|e| {
        Error::input(
            file,
            format!(
                "not a pipeline: a pipeline is a UTF-8 TOML text file, and byte {} is not UTF-8",
                e.utf8_error().valid_up_to()
            ),
        )
    })
}

impl LoadedPipeline {
    /// Reads, parses and validates a pipeline file and loads its scene. No rendering happens and
    /// no file is written.
    pub fn load(file: &Path) -> Result<LoadedPipeline> {
        let bytes = crate::paths::read_regular(file)?;
        let src = pipeline_text(file, bytes)?;
        Self::from_source(file, src, None)
    }

    /// The same pipeline with keys set by path (`accel.split`, `render.spp`,
    /// `output[0].method`), each value written as in the TOML file (a bare word is a string).
    /// The edited pipeline is validated like a file; the scene is reused unless a key changes it.
    pub fn with_overrides(&self, overrides: &[(String, String)]) -> Result<LoadedPipeline> {
        let mut doc = self
            .source
            .parse::<toml_edit::DocumentMut>()
            .map_err(|e| Error::input(&self.file, format!("cannot edit the pipeline: {e}")))?;
        for (key, value) in overrides {
            set_key(&mut doc, key, value).map_err(|m| Error::input(&self.file, m))?;
        }
        let described = overrides
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect::<Vec<_>>()
            .join(" ");
        Self::from_source(&self.file, doc.to_string(), Some(self)).map_err(|e| {
            // Line numbers of the edited text would point at nothing the user wrote.
            let why = match e {
                Error::Pipeline { message, .. } => message,
                other => other.to_string(),
            };
            Error::input(&self.file, format!("with {described}: {why}"))
        })
    }

    /// Parses and validates pipeline text; `previous` lends its scene when the path is the same.
    fn from_source(
        file: &Path,
        src: String,
        previous: Option<&LoadedPipeline>,
    ) -> Result<LoadedPipeline> {
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
        let scene = match previous {
            Some(p) if p.scene_path == scene_path => Arc::clone(&p.scene),
            _ => Arc::new(Scene::load(&scene_path)?),
        };
        let mut warnings = scene.warnings.clone();
        let camera_instance = resolve_camera(&spec, &scene, &mut warnings).map_err(at)?;
        if !scene.nodes.iter().any(|n| n.light.is_some()) {
            warnings.push(format!(
                "{}: the scene has no lights; using a head-light at the camera",
                scene_path.display()
            ));
        }
        check_animation(&spec, &scene).map_err(at)?;
        if matches!(&spec.scene.animation, Selector::Name(n) if n == "all") {
            warn_overlapping(&scene, &mut warnings);
        }
        check_named_nodes(&spec, &scene).map_err(at)?;
        if let Some(i) = spec.outputs.iter().position(|o| o.video().is_some())
            && !ffmpeg_available()
        {
            return Err(at(invalid(
                &[Key::Name("output"), Key::Index(i), Key::Name("video")],
                "video output needs the ffmpeg executable on the PATH (e.g. apt-get install ffmpeg)",
            )));
        }
        Ok(LoadedPipeline {
            file: file.to_path_buf(),
            source: src,
            spec,
            scene,
            scene_path,
            templates,
            camera_instance,
            warnings,
        })
    }

    /// The animations `[scene] animation` plays.
    pub fn selected_animations(&self) -> Vec<&Animation> {
        let all = &self.scene.animations;
        match &self.spec.scene.animation {
            Selector::Name(n) if n == "none" => Vec::new(),
            Selector::Name(n) if n == "all" => all.iter().collect(),
            Selector::Name(n) => all
                .iter()
                .filter(|a| a.name.as_deref() == Some(n.as_str()))
                .take(1)
                .collect(),
            Selector::Index(i) => all.get(*i).into_iter().collect(),
        }
    }

    /// The first node called `name` (names are checked when the pipeline loads).
    pub fn node_named(&self, name: &str) -> Option<usize> {
        self.scene
            .nodes
            .iter()
            .position(|n| n.name.as_deref() == Some(name))
    }

    /// The views of the rig itself: left and right, or the centre for a mono rig.
    pub fn rig_views(&self) -> Vec<View> {
        if self.spec.stereo.rig == Rig::Mono {
            vec![View::CENTER]
        } else {
            vec![View::LEFT, View::RIGHT]
        }
    }
}

/// `animation = "all"` plays clips that drive the same nodes (a walk and a run): the later
/// overwrites the earlier, which is rarely what a user means.
fn warn_overlapping(scene: &Scene, warnings: &mut Vec<String>) {
    let name = |i: usize| {
        scene.animations[i]
            .name
            .as_ref()
            .map_or(i.to_string(), |n| format!("{n:?}"))
    };
    let pairs: Vec<String> = overlapping_animations(&scene.animations)
        .into_iter()
        .map(|(a, b)| format!("{} over {}", name(b), name(a)))
        .collect();
    if !pairs.is_empty() {
        warnings.push(format!(
            "{}: animation = \"all\" plays clips that drive the same nodes, each later one over \
             the earlier where they meet ({}); name one with [scene] animation",
            scene.source.display(),
            pairs.join(", ")
        ));
    }
}

/// `check`'s report: the pipeline is valid, and what it holds.
impl fmt::Display for LoadedPipeline {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}: ok ({} triangles after instancing, {} output(s), frames {}..{})",
            self.file.display(),
            self.scene.placed_triangle_count(),
            self.spec.outputs.len(),
            self.spec.frames.start,
            self.spec.frames.end
        )
    }
}

/// Parses a command-line frame range `A..B` (inclusive), or a single frame `N`.
pub fn parse_frame_range(s: &str) -> std::result::Result<(u32, u32), String> {
    // A single frame N is N..N.
    let (a, b) = s.split_once("..").unwrap_or((s, s));
    let a: u32 = a
        .trim()
        .parse()
        .map_err(|_| format!("'{a}' is not a frame number"))?;
    let b: u32 = b
        .trim()
        .parse()
        .map_err(|_| format!("'{b}' is not a frame number"))?;
    if b < a {
        return Err(format!("{a}..{b} is empty"));
    }
    Ok((a, b))
}
