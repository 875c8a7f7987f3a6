//! The pipeline file's schema: serde structs whose defaults are the single source of every
//! default the guide documents (docs/guide/pipeline.md). Unknown keys are errors;
//! `Pipeline::parse` reports them (and every type error) at their line and column.

use super::location::line_column;
use super::output_spec::OutputSpec;
use crate::accel::{SplitMethod, UpdateMode};
use crate::error::{Error, Result};
use crate::render::{Backend, EyeReuse, FloatingWindow, Rig, ShadingModel};
use serde::Deserialize;
use std::path::Path;

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
    #[serde(deserialize_with = "three_numbers")]
    pub background: [f32; 3],
    /// 0 = all cores.
    pub threads: usize,
    pub eye_reuse: EyeReuse,
    pub backend: Backend,
}

/// Exactly three numbers (an RGB colour): a fourth would otherwise be dropped in silence.
fn three_numbers<'de, D: serde::Deserializer<'de>>(
    d: D,
) -> std::result::Result<[f32; 3], D::Error> {
    let v = Vec::<f32>::deserialize(d)?;
    <[f32; 3]>::try_from(v.as_slice()).map_err(|_| {
        serde::de::Error::custom(format!(
            "expected three numbers (red, green, blue), got {}",
            v.len()
        ))
    })
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
            eye_reuse: EyeReuse::Off,
            backend: Backend::Cpu,
        }
    }
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StereoSection {
    pub rig: Rig,
    /// Metres between the eyes, or `"auto"`: the largest the depth budget allows.
    pub interaxial: Metres,
    /// Metres to the zero-parallax plane, or `"auto"`: the subject's depth, or the median depth
    /// at the centre of the frame.
    pub convergence: Metres,
    /// A node whose origin `convergence = "auto"` puts at zero parallax.
    pub subject: Option<String>,
    /// Crossed parallax allowed, percent of the image width (points in front of the screen).
    pub budget_front: f32,
    /// Uncrossed parallax allowed, percent of the image width (points behind the screen).
    pub budget_behind: f32,
    /// Width of the screen the film is made for, metres: caps `budget_behind` at the parallax
    /// that makes a viewer's eyes diverge there.
    pub screen_width: Option<f32>,
    /// Frames on either side over which automatic choices are smoothed.
    pub smoothing: u32,
    pub floating_window: FloatingWindow,
}

impl Default for StereoSection {
    fn default() -> Self {
        StereoSection {
            rig: Rig::OffAxis,
            interaxial: Metres::Fixed(0.065),
            convergence: Metres::Fixed(3.0),
            subject: None,
            // Stereography practice for large screens: about 1% of the width in front of the
            // screen and 2% behind it (2.5 inches of eye separation on a 10-foot screen).
            budget_front: 1.0,
            budget_behind: 2.0,
            screen_width: None,
            // Half a second at 24 fps each way: slow enough not to pump with the action.
            smoothing: 12,
            floating_window: FloatingWindow::Off,
        }
    }
}

/// A distance the user fixes or leaves to the tool: a number of metres or `"auto"`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Metres {
    Fixed(f32),
    Auto,
}

impl Metres {
    pub fn fixed(self) -> Option<f32> {
        match self {
            Metres::Fixed(m) => Some(m),
            Metres::Auto => None,
        }
    }
}

impl<'de> Deserialize<'de> for Metres {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Metres, D::Error> {
        struct V;
        impl serde::de::Visitor<'_> for V {
            type Value = Metres;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a number of metres or \"auto\"")
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> std::result::Result<Metres, E> {
                Ok(Metres::Fixed(v as f32))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> std::result::Result<Metres, E> {
                Ok(Metres::Fixed(v as f32))
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> std::result::Result<Metres, E> {
                match v {
                    "auto" => Ok(Metres::Auto),
                    _ => Err(E::custom(format!(
                        "expected a number of metres or \"auto\", got \"{v}\""
                    ))),
                }
            }
        }
        d.deserialize_any(V)
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

impl Pipeline {
    /// Parses pipeline text; errors carry the file, line and column.
    pub fn parse(file: &Path, src: &str) -> Result<Pipeline> {
        toml::from_str::<Pipeline>(src).map_err(|e| {
            let at = e.span().map(|span| named_in(src, span, e.message()));
            let (line, column) = at.map_or((1, 1), |at| line_column(src, at));
            Error::Pipeline {
                file: file.to_path_buf(),
                line,
                column,
                message: e.message().trim().to_string(),
            }
        })
    }
}

/// Where an error inside a table points: serde reports a bad value of an `[[output]]` (whose
/// `kind` picks its keys) at the whole table, so the name the message quotes in backticks (the
/// unknown variant or key) is looked up in the table's text, as a quoted value or a key. The
/// table's start if it is not there.
fn named_in(src: &str, span: std::ops::Range<usize>, message: &str) -> usize {
    let quoted = message.split('`').nth(1).filter(|q| !q.is_empty());
    // The span may be the table's header alone: look up to the next table.
    let rest = src.get(span.start..).unwrap_or("");
    let end = rest
        .get(1..)
        .and_then(|r| r.find("\n[").map(|i| i + 1))
        .unwrap_or(rest.len())
        .max(span.len().min(rest.len()));
    let text = &rest[..end];
    quoted
        .and_then(|q| {
            [format!("\"{q}\""), format!("'{q}'"), format!("{q} =")]
                .iter()
                .find_map(|needle| text.find(needle.as_str()))
        })
        .map_or(span.start, |i| span.start + i)
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
        assert_eq!(p.stereo.interaxial, Metres::Fixed(0.065));
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
    fn output_keys_of_another_kind_are_unknown() {
        let src =
            "[scene]\npath = \"s\"\n[[output]]\nkind = \"exr\"\npath = \"a.exr\"\nexposure = 1\n";
        assert!(Pipeline::parse(Path::new("p.toml"), src).is_err());
    }

    #[test]
    fn layout_outputs_refuse_keys_they_do_not_have() {
        let ok = "[scene]\npath = \"s\"\n[[output]]\nkind = \"top-bottom\"\npath = \"a.png\"\nhalf = true\n";
        let p = Pipeline::parse(Path::new("p.toml"), ok).unwrap();
        assert!(matches!(&p.outputs[0], OutputSpec::TopBottom(l) if l.half));
        let bad = "[scene]\npath = \"s\"\n[[output]]\nkind = \"side-by-side\"\npath = \"a.png\"\nviews = 3\n";
        let e = Pipeline::parse(Path::new("p.toml"), bad)
            .unwrap_err()
            .to_string();
        assert!(e.contains("views"), "{e}");
    }
}
