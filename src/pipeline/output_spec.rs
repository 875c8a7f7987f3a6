//! The `[[output]]` tables: every output kind's keys and defaults, and every fact about a kind
//! the rest of the pipeline asks (its path, display transform, video, the views it needs, its
//! own validation rules) in one place. How a kind turns frames into files is `run/outputs.rs`.

use super::template::PathTemplate;
use crate::output::{
    AnaglyphMethod, AnaglyphSpace, Channels, Display, Order, StereoPacking, ToneMap, WobbleMode,
    check_video_path, wobble_schedule,
};
use crate::render::{Eye, View};
use serde::Deserialize;
use std::path::Path;

/// The folder under `--out` where a render keeps the 8-bit frames that pseudo-stereo and
/// whole-range wobble GIFs are made from, so that `assemble` can make them from a farm's shards.
pub const SEQUENCE_FRAMES: &str = "sequence-frames";

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
        method: AnaglyphMethod,
        #[serde(default)]
        swap: bool,
        #[serde(default)]
        space: AnaglyphSpace,
        #[serde(default)]
        exposure: f32,
        #[serde(default)]
        tonemap: ToneMap,
        video: Option<String>,
    },
    SideBySide(PairLayout),
    TopBottom(PairLayout),
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
        eye: Eye,
        #[serde(default)]
        channels_now: Channels,
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
        mode: WobbleMode,
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
        /// What stays still while the views swing: `"convergence"` (the zero-parallax plane) or
        /// the name of a node, whose origin each view is shifted to hold in place.
        #[serde(default = "default_pivot")]
        pivot: String,
        #[serde(default)]
        exposure: f32,
        #[serde(default)]
        tonemap: ToneMap,
    },
}

/// The keys of the two layouts that place both eyes in one image (side by side, top and bottom).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PairLayout {
    pub path: String,
    /// `parallel` (left eye first) or `cross`.
    #[serde(default)]
    pub layout: Order,
    /// Squeeze each eye to half the width (height for top-bottom).
    #[serde(default)]
    pub half: bool,
    #[serde(default)]
    pub exposure: f32,
    #[serde(default)]
    pub tonemap: ToneMap,
    pub video: Option<String>,
}

fn default_anaglyph() -> AnaglyphMethod {
    AnaglyphMethod::DuboisRedCyan
}
fn default_pseudo_eye() -> Eye {
    Eye::Left
}
fn default_delay() -> usize {
    1
}
fn default_pivot() -> String {
    "convergence".to_string()
}
fn default_views() -> usize {
    2
}
/// About 8 views a second, inside the 100-150 ms range wobble GIFs commonly use.
fn default_delay_ms() -> u32 {
    120
}

impl OutputSpec {
    /// The file format this output writes, as its file name extension.
    fn file_format(&self) -> &'static str {
        match self {
            OutputSpec::Exr { .. } => "exr",
            OutputSpec::WobbleGif { .. } => "gif",
            _ => "png",
        }
    }

    pub fn path(&self) -> &str {
        match self {
            OutputSpec::Exr { path, .. }
            | OutputSpec::Png { path, .. }
            | OutputSpec::Anaglyph { path, .. }
            | OutputSpec::SideBySide(PairLayout { path, .. })
            | OutputSpec::TopBottom(PairLayout { path, .. })
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
            | OutputSpec::SideBySide(PairLayout {
                exposure, tonemap, ..
            })
            | OutputSpec::TopBottom(PairLayout {
                exposure, tonemap, ..
            })
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
            | OutputSpec::SideBySide(PairLayout { video, .. })
            | OutputSpec::TopBottom(PairLayout { video, .. })
            | OutputSpec::Interlaced { video, .. }
            | OutputSpec::PseudoStereo { video, .. } => video.as_deref(),
            _ => None,
        }
    }

    /// How this output's frames hold both eyes, for a video's stereo signalling (`None`: a
    /// single picture per frame, such as an anaglyph or one eye).
    pub fn stereo_packing(&self) -> Option<StereoPacking> {
        let right_first = |order: &Order| *order == Order::Cross;
        match self {
            OutputSpec::SideBySide(l) => Some(StereoPacking::SideBySide {
                right_first: right_first(&l.layout),
            }),
            OutputSpec::TopBottom(l) => Some(StereoPacking::TopBottom {
                right_first: right_first(&l.layout),
            }),
            OutputSpec::Interlaced { layout, .. } => Some(StereoPacking::Rows {
                right_first: right_first(layout),
            }),
            _ => None,
        }
    }

    /// The node a wobble GIF pivots on, if it names one.
    pub fn pivot_node(&self) -> Option<&str> {
        match self {
            OutputSpec::WobbleGif { pivot, .. } if pivot != "convergence" => Some(pivot),
            _ => None,
        }
    }

    /// Outputs built from both eyes of a stereo pair.
    fn needs_stereo(&self) -> bool {
        matches!(
            self,
            OutputSpec::Anaglyph { .. }
                | OutputSpec::SideBySide(_)
                | OutputSpec::TopBottom(_)
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

    /// Whether the output writes one file per eye (its path needs `{eye}` in stereo).
    fn per_eye_files(&self) -> bool {
        match self {
            OutputSpec::Exr { views, .. } => *views == ExrViews::Separate,
            OutputSpec::Png { .. } => true,
            _ => false,
        }
    }

    /// The views this output needs for frame `k` of the range; `rig` is the rig's own views.
    pub fn views(&self, rig: &[View], k: usize) -> Vec<View> {
        match self {
            OutputSpec::Exr { .. } | OutputSpec::Png { .. } => rig.to_vec(),
            OutputSpec::Anaglyph { .. }
            | OutputSpec::SideBySide(_)
            | OutputSpec::TopBottom(_)
            | OutputSpec::Interlaced { .. } => vec![View::LEFT, View::RIGHT],
            OutputSpec::PseudoStereo { eye, .. } => vec![View::Eye(*eye)],
            OutputSpec::WobbleGif {
                views,
                mode,
                per_frame,
                ..
            } => {
                if *per_frame {
                    (0..*views)
                        .map(|i| View::along_baseline(i, *views))
                        .collect()
                } else {
                    let order = wobble_schedule(*views, *mode);
                    vec![View::along_baseline(order[k % order.len()], *views)]
                }
            }
        }
    }

    /// This output's own rules, given its parsed path: the key at fault and what is wrong.
    pub(super) fn check(
        &self,
        path: &PathTemplate,
        stereo: bool,
        multi_frame: bool,
    ) -> Result<(), (&'static str, String)> {
        let fail = |key: &'static str, m: &str| Err((key, m.to_string()));
        let format = self.file_format();
        let ext = Path::new(self.path())
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        if ext.as_deref() != Some(format) {
            return fail(
                "path",
                &format!(
                    "this output writes {} files: the path must end in .{format}",
                    format.to_ascii_uppercase()
                ),
            );
        }
        if multi_frame && !path.has_frame() && !self.single_file() {
            return fail(
                "path",
                "several frames are rendered: the path needs {frame} so files do not overwrite each other",
            );
        }
        if self.per_eye_files() && stereo && !path.has_eye() {
            return fail(
                "path",
                "this output writes one file per eye: the path needs {eye}",
            );
        }
        if self.needs_stereo() && !stereo {
            return fail(
                "kind",
                "this output needs both eyes: set [stereo] rig to a stereo rig, not \"mono\"",
            );
        }
        if !self.display().exposure.is_finite() {
            return fail("exposure", "exposure must be finite");
        }
        match self {
            OutputSpec::PseudoStereo { eye, delay, .. } => {
                if *eye != Eye::Center && !stereo {
                    return fail("eye", "a mono rig renders only the \"center\" eye");
                }
                if *delay > 1000 {
                    return fail(
                        "delay",
                        &format!("delay must be at most 1000 frames, got {delay}"),
                    );
                }
            }
            OutputSpec::WobbleGif {
                views,
                delay_ms,
                per_frame,
                ..
            } => {
                if !(2..=64).contains(views) {
                    return fail(
                        "views",
                        &format!("views must be between 2 and 64, got {views}"),
                    );
                }
                if !(10..=60_000).contains(delay_ms) {
                    return fail(
                        "delay_ms",
                        &format!("delay_ms must be between 10 and 60000, got {delay_ms}"),
                    );
                }
                if *per_frame && multi_frame && !path.has_frame() {
                    return fail(
                        "path",
                        "per_frame = true writes one GIF per frame: the path needs {frame}",
                    );
                }
            }
            _ => {}
        }
        if let Some(v) = self.video() {
            let vt = PathTemplate::parse(v).map_err(|m| ("video", m))?;
            if vt.has_frame() || vt.has_eye() {
                return fail(
                    "video",
                    "a video is one file: no {frame} or {eye} in its path",
                );
            }
            check_video_path(Path::new(v)).map_err(|m| ("video", m))?;
        }
        Ok(())
    }
}
