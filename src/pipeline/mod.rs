//! Pipeline files: the TOML schema (serde structs are the single source of defaults), validation
//! with `file:line:column` errors, and the frame loop that drives a render (`run.rs`).

pub mod outputs;
pub mod run;
pub mod template;
pub mod trace;
pub mod update;

use crate::accel::SplitMethod;
use crate::error::{Error, Result};
use crate::output::color::{Display, ToneMap};
use crate::output::layout::Order;
use crate::output::{anaglyph, pseudo, video, wobble};
use crate::render::{Rig, ShadingModel};
use crate::scene::Scene;
use serde::Deserialize;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;
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

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AccelSection {
    pub split: SplitMethod,
    /// How deforming meshes follow their animation.
    pub update: UpdateMode,
    /// `auto` rebuilds when the refitted tree's SAH cost exceeds this multiple of the last fresh
    /// build's SAH cost. 1.3 (a 30% drift) is a starting point, not a measured optimum: the
    /// frame log's costs and times show where a scene's break-even lies.
    pub auto_threshold: f32,
}

impl Default for AccelSection {
    fn default() -> Self {
        AccelSection {
            split: SplitMethod::Sah,
            update: UpdateMode::Auto,
            auto_threshold: 1.3,
        }
    }
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
    /// Multi-view OpenEXR, linear radiance.
    Exr {
        path: String,
        #[serde(default)]
        half: bool,
        #[serde(default)]
        views: ExrViews,
    },
    /// 8-bit sRGB, one file per eye.
    Png {
        path: String,
        /// Stops.
        #[serde(default)]
        exposure: f32,
        #[serde(default)]
        tonemap: ToneMap,
    },
    Anaglyph {
        path: String,
        #[serde(default = "default_anaglyph")]
        method: anaglyph::Method,
        #[serde(default)]
        swap: bool,
        #[serde(default)]
        space: anaglyph::Space,
        #[serde(default)]
        exposure: f32,
        #[serde(default)]
        tonemap: ToneMap,
        video: Option<String>,
    },
    SideBySide {
        path: String,
        #[serde(default)]
        layout: Order,
        #[serde(default)]
        half: bool,
        #[serde(default)]
        exposure: f32,
        #[serde(default)]
        tonemap: ToneMap,
        video: Option<String>,
    },
    TopBottom {
        path: String,
        #[serde(default)]
        layout: Order,
        #[serde(default)]
        half: bool,
        #[serde(default)]
        exposure: f32,
        #[serde(default)]
        tonemap: ToneMap,
        video: Option<String>,
    },
    Interlaced {
        path: String,
        #[serde(default)]
        layout: Order,
        #[serde(default)]
        exposure: f32,
        #[serde(default)]
        tonemap: ToneMap,
        video: Option<String>,
    },
    PseudoStereo {
        path: String,
        /// Which eye's sequence; "center" is the mono camera.
        #[serde(default = "default_pseudo_eye")]
        eye: crate::render::Eye,
        #[serde(default)]
        channels_now: pseudo::Channels,
        /// Frames.
        #[serde(default = "default_delay")]
        delay: usize,
        #[serde(default)]
        exposure: f32,
        #[serde(default)]
        tonemap: ToneMap,
        video: Option<String>,
    },
    WobbleGif {
        path: String,
        /// Views along the baseline, left to right (2 = the two eyes).
        #[serde(default = "default_views")]
        views: usize,
        #[serde(default)]
        mode: wobble::Mode,
        #[serde(default = "default_delay_ms")]
        delay_ms: u32,
        /// Repetitions; 0 = forever.
        #[serde(default, rename = "loop")]
        loop_count: u16,
        /// One GIF per frame (path needs {frame}); otherwise one GIF over the whole range.
        #[serde(default)]
        per_frame: bool,
        #[serde(default)]
        dither: bool,
        #[serde(default)]
        exposure: f32,
        #[serde(default)]
        tonemap: ToneMap,
    },
}

fn default_anaglyph() -> anaglyph::Method {
    anaglyph::Method::DuboisRedCyan
}
fn default_pseudo_eye() -> crate::render::Eye {
    crate::render::Eye::Left
}
fn default_delay() -> usize {
    1
}
fn default_views() -> usize {
    2
}
/// About 8 views a second, inside the 100-150 ms range wobble GIFs commonly use.
fn default_delay_ms() -> u32 {
    120
}

impl OutputSpec {
    pub fn path(&self) -> &str {
        match self {
            OutputSpec::Exr { path, .. }
            | OutputSpec::Png { path, .. }
            | OutputSpec::Anaglyph { path, .. }
            | OutputSpec::SideBySide { path, .. }
            | OutputSpec::TopBottom { path, .. }
            | OutputSpec::Interlaced { path, .. }
            | OutputSpec::PseudoStereo { path, .. }
            | OutputSpec::WobbleGif { path, .. } => path,
        }
    }

    pub fn display(&self) -> Display {
        let (exposure, tone_map) = match self {
            OutputSpec::Exr { .. } => return Display::default(),
            OutputSpec::Png {
                exposure, tonemap, ..
            }
            | OutputSpec::Anaglyph {
                exposure, tonemap, ..
            }
            | OutputSpec::SideBySide {
                exposure, tonemap, ..
            }
            | OutputSpec::TopBottom {
                exposure, tonemap, ..
            }
            | OutputSpec::Interlaced {
                exposure, tonemap, ..
            }
            | OutputSpec::PseudoStereo {
                exposure, tonemap, ..
            }
            | OutputSpec::WobbleGif {
                exposure, tonemap, ..
            } => (*exposure, *tonemap),
        };
        Display { exposure, tone_map }
    }

    pub fn video(&self) -> Option<&str> {
        match self {
            OutputSpec::Anaglyph { video, .. }
            | OutputSpec::SideBySide { video, .. }
            | OutputSpec::TopBottom { video, .. }
            | OutputSpec::Interlaced { video, .. }
            | OutputSpec::PseudoStereo { video, .. } => video.as_deref(),
            _ => None,
        }
    }

    /// Outputs built from both eyes of a stereo pair.
    fn needs_stereo(&self) -> bool {
        matches!(
            self,
            OutputSpec::Anaglyph { .. }
                | OutputSpec::SideBySide { .. }
                | OutputSpec::TopBottom { .. }
                | OutputSpec::Interlaced { .. }
                | OutputSpec::WobbleGif { .. }
        )
    }

    /// Whether the output writes one file for the whole range (a wobble GIF over the animation).
    pub(crate) fn single_file(&self) -> bool {
        matches!(
            self,
            OutputSpec::WobbleGif {
                per_frame: false,
                ..
            }
        )
    }
}

/// Sets `key` (dotted, with `[i]` for an array element: `output[0].method`) to `value`, parsed as
/// a TOML value, or taken as a string when it is not one (`sah`, `cook-torrance`).
fn set_key(doc: &mut toml_edit::DocumentMut, key: &str, value: &str) -> Result<(), String> {
    use toml_edit::{Item, Table, TableLike, Value};
    let parsed = value
        .parse::<Value>()
        .unwrap_or_else(|_| Value::from(value));
    let segments: Vec<&str> = key.split('.').collect();
    let (last, path) = segments
        .split_last()
        .expect("split yields at least one part");
    if last.is_empty() || last.contains('[') {
        return Err(format!("key '{key}' must end in a key name"));
    }
    let mut table: &mut dyn TableLike = doc.as_table_mut();
    for segment in path {
        let (name, index) = match segment.split_once('[') {
            Some((n, rest)) => {
                let i = rest
                    .strip_suffix(']')
                    .and_then(|r| r.parse::<usize>().ok())
                    .ok_or_else(|| format!("key '{key}': bad index in '{segment}'"))?;
                (n, Some(i))
            }
            None => (*segment, None),
        };
        if name.is_empty() {
            return Err(format!("key '{key}' has an empty part"));
        }
        if index.is_none() && table.get(name).is_none() {
            table.insert(name, Item::Table(Table::new()));
        }
        let item = table
            .get_mut(name)
            .ok_or_else(|| format!("key '{key}': the pipeline has no '{name}'"))?;
        table = match (item, index) {
            (Item::ArrayOfTables(a), Some(i)) => {
                let len = a.len();
                a.get_mut(i)
                    .map(|t| t as &mut dyn TableLike)
                    .ok_or_else(|| format!("key '{key}': '{name}' has {len} entries, no [{i}]"))?
            }
            (Item::Value(Value::Array(a)), Some(i)) => {
                let len = a.len();
                a.get_mut(i)
                    .and_then(|v| v.as_inline_table_mut())
                    .map(|t| t as &mut dyn TableLike)
                    .ok_or_else(|| {
                        format!("key '{key}': '{name}' has {len} entries, no table at [{i}]")
                    })?
            }
            (item, None) => item
                .as_table_like_mut()
                .ok_or_else(|| format!("key '{key}': '{name}' is not a table"))?,
            (_, Some(_)) => return Err(format!("key '{key}': '{name}' is not an array")),
        };
    }
    table.insert(last, Item::Value(parsed));
    Ok(())
}

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
        if let Some(i) = spec.outputs.iter().position(|o| o.video().is_some())
            && !video::ffmpeg_available()
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
    pub fn selected_animations(&self) -> Vec<&crate::scene::animation::Animation> {
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
    let a = &p.accel.auto_threshold;
    if !(a.is_finite() && *a >= 1.0) {
        return Err(invalid(
            &[N("accel"), N("auto_threshold")],
            format!("auto_threshold must be a finite number >= 1, got {a}"),
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
        let key = |k: &'static str| [N("output"), Key::Index(i), N(k)];
        let t = PathTemplate::parse(o.path()).map_err(|m| invalid(&key("path"), m))?;
        if multi_frame && !t.has_frame() && !o.single_file() {
            return Err(invalid(
                &key("path"),
                "several frames are rendered: the path needs {frame} so files do not overwrite each other",
            ));
        }
        let per_eye = match o {
            OutputSpec::Exr { views, .. } => *views == ExrViews::Separate,
            OutputSpec::Png { .. } => true,
            _ => false,
        };
        if per_eye && stereo && !t.has_eye() {
            return Err(invalid(
                &key("path"),
                "this output writes one file per eye: the path needs {eye}",
            ));
        }
        if o.needs_stereo() && !stereo {
            return Err(invalid(
                &key("kind"),
                "this output needs both eyes: set [stereo] rig to a stereo rig, not \"mono\"",
            ));
        }
        if !o.display().exposure.is_finite() {
            return Err(invalid(&key("exposure"), "exposure must be finite"));
        }
        match o {
            OutputSpec::PseudoStereo { eye, delay, .. } => {
                if *eye != crate::render::Eye::Center && !stereo {
                    return Err(invalid(
                        &key("eye"),
                        "a mono rig renders only the \"center\" eye",
                    ));
                }
                if *delay > 1000 {
                    return Err(invalid(
                        &key("delay"),
                        format!("delay must be at most 1000 frames, got {delay}"),
                    ));
                }
            }
            OutputSpec::WobbleGif {
                views,
                delay_ms,
                per_frame,
                ..
            } => {
                if !(2..=64).contains(views) {
                    return Err(invalid(
                        &key("views"),
                        format!("views must be between 2 and 64, got {views}"),
                    ));
                }
                if !(10..=60_000).contains(delay_ms) {
                    return Err(invalid(
                        &key("delay_ms"),
                        format!("delay_ms must be between 10 and 60000, got {delay_ms}"),
                    ));
                }
                if *per_frame && multi_frame && !t.has_frame() {
                    return Err(invalid(
                        &key("path"),
                        "per_frame = true writes one GIF per frame: the path needs {frame}",
                    ));
                }
            }
            _ => {}
        }
        if let Some(v) = o.video() {
            let vt = PathTemplate::parse(v).map_err(|m| invalid(&key("video"), m))?;
            if vt.has_frame() || vt.has_eye() {
                return Err(invalid(
                    &key("video"),
                    "a video is one file: no {frame} or {eye} in its path",
                ));
            }
            video::check_path(Path::new(v)).map_err(|m| invalid(&key("video"), m))?;
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

fn check_animation(p: &Pipeline, scene: &Scene) -> std::result::Result<(), Invalid<'static>> {
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
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_are_set_by_path_in_tables_and_arrays_of_tables() {
        let src = "[scene]\npath = \"s.gltf\"\n[render]\nspp = 4\n[[output]]\nkind = \"anaglyph\"\npath = \"a.png\"\n";
        let mut doc = src.parse::<toml_edit::DocumentMut>().unwrap();
        set_key(&mut doc, "render.spp", "16").unwrap();
        set_key(&mut doc, "accel.split", "center").unwrap(); // a table the file lacks
        set_key(&mut doc, "output[0].method", "gray").unwrap();
        set_key(&mut doc, "stereo.interaxial", "0.1").unwrap();
        let p = Pipeline::parse(Path::new("p.toml"), &doc.to_string()).unwrap();
        assert_eq!(p.render.spp, 16);
        assert_eq!(p.accel.split, SplitMethod::Center);
        assert_eq!(p.stereo.interaxial, 0.1);
        assert!(doc.to_string().contains("method = \"gray\""));
        for (key, why) in [
            ("output[3].method", "has 1 entries"),
            ("render[0].spp", "not an array"),
            ("render.", "must end in a key name"),
            ("output[x].path", "bad index"),
        ] {
            let err = set_key(&mut doc, key, "1").unwrap_err();
            assert!(err.contains(why), "{key}: {err}");
        }
    }

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
