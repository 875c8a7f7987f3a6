//! One writer per `[[output]]`: it receives every stereo frame in order and turns it into files.
//! Writers keep state across frames where their kind needs it (pseudo-stereo's delayed frames, a
//! wobble GIF's frames, a video stream) in a `Sequence` and finish at the end of the range. The
//! image work itself lives in `output/`; this module only routes frames and paths.

use crate::error::{Error, Result};
use crate::output::{
    Display, Image, PseudoStereo, VideoEncoder, interlaced, make_anaglyph, pivot_shift,
    side_by_side, to_srgb8, top_bottom, wobble_schedule, write_gif, write_multiview, write_png,
    write_rgb8, write_single_view,
};
use crate::pipeline::LoadedPipeline;
use crate::pipeline::{ExrViews, OutputSpec, PairLayout};
use crate::pipeline::{PathTemplate, SEQUENCE_FRAMES};
use crate::render::View;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// The views of one frame, linear radiance.
pub struct StereoFrame {
    pub frame: u32,
    pub views: Vec<(View, Image)>,
    /// The parallax (pixels, right eye minus left) of each node a wobble GIF pivots on.
    pub pivots: Vec<(String, f32)>,
}

impl StereoFrame {
    pub fn view(&self, view: View) -> Result<&Image> {
        self.views
            .iter()
            .find(|(v, _)| *v == view)
            .map(|(_, img)| img)
            .ok_or_else(|| {
                Error::Internal(format!(
                    "view '{}' is needed by an output but was not traced",
                    view.name()
                ))
            })
    }
}

/// An 8-bit sRGB frame: width, height and RGB bytes.
pub type Rgb8 = (usize, usize, Vec<u8>);

/// What one output writes of each frame on its own: the files that depend on that frame alone.
/// What needs the frames before it (a video, pseudo-stereo's delayed channels, a GIF over the
/// range) is a `Sequence`'s, fed with the 8-bit frames this returns.
pub struct Writer {
    spec: OutputSpec,
    template: PathTemplate,
    /// The rig's own views, for EXR and PNG.
    rig: Vec<View>,
    out_dir: PathBuf,
    /// The output's number in the pipeline, from 1.
    number: usize,
    /// The pipeline's first frame: a frame's place in the range picks its wobble view.
    range_start: u32,
}

/// The files one frame of one output made, and the 8-bit frame its sequence takes.
pub struct FrameFiles {
    pub files: Vec<PathBuf>,
    pub sequence: Option<Rgb8>,
}

/// Whether an output makes files from the whole sequence of frames.
fn has_sequence(spec: &OutputSpec) -> bool {
    spec.video().is_some() || stores_frames(spec)
}

/// Whether the 8-bit frames a sequence takes are stored apart (pseudo-stereo's source eye, a
/// range GIF's view) rather than being the output's own per-frame files.
fn stores_frames(spec: &OutputSpec) -> bool {
    matches!(spec, OutputSpec::PseudoStereo { .. }) || spec.single_file()
}

impl Writer {
    /// One writer per output, numbered from 1.
    pub fn all(p: &LoadedPipeline, out_dir: &Path) -> Vec<Writer> {
        let rig = p.rig_views();
        p.spec
            .outputs
            .iter()
            .zip(&p.templates)
            .enumerate()
            .map(|(i, (o, t))| Writer::new(o, t, &rig, out_dir, i + 1, p.spec.frames.start))
            .collect()
    }

    pub fn new(
        spec: &OutputSpec,
        template: &PathTemplate,
        rig: &[View],
        out_dir: &Path,
        number: usize,
        range_start: u32,
    ) -> Writer {
        Writer {
            spec: spec.clone(),
            template: template.clone(),
            rig: rig.to_vec(),
            out_dir: out_dir.to_path_buf(),
            number,
            range_start,
        }
    }

    /// The file holding the 8-bit frame this output's sequence takes at `frame`, if it has a
    /// sequence.
    pub fn sequence_source(&self, frame: u32) -> Option<PathBuf> {
        if !has_sequence(&self.spec) {
            None
        } else if stores_frames(&self.spec) {
            Some(self.stored_frame(frame))
        } else {
            Some(self.template.path(&self.out_dir, frame, ""))
        }
    }

    fn stored_frame(&self, frame: u32) -> PathBuf {
        self.out_dir
            .join(SEQUENCE_FRAMES)
            .join(format!("output-{}", self.number))
            .join(format!("{frame:06}.png"))
    }

    /// Writes the files this output makes of one frame alone (and the stored sequence frame).
    pub fn frame(&self, f: &StereoFrame) -> Result<FrameFiles> {
        let display = self.spec.display();
        let path = |eye: &str| self.template.path(&self.out_dir, f.frame, eye);
        let mut files = Vec::new();
        // The kinds that make one 8-bit image per frame return it here.
        let image: Option<Rgb8> = match &self.spec {
            OutputSpec::Exr { half, views, .. } => {
                let eyes: Vec<(String, &Image)> = self
                    .rig
                    .iter()
                    .map(|&v| Ok((v.name(), f.view(v)?)))
                    .collect::<Result<_>>()?;
                match views {
                    ExrViews::Single => {
                        let named: Vec<(&str, &Image)> =
                            eyes.iter().map(|(n, img)| (n.as_str(), *img)).collect();
                        write_multiview(&path(""), &named, *half)?;
                        files.push(path(""));
                    }
                    ExrViews::Separate => {
                        for (name, img) in &eyes {
                            write_single_view(&path(name), name, img, *half)?;
                            files.push(path(name));
                        }
                    }
                }
                None
            }
            OutputSpec::Png { .. } => {
                // One PNG per eye, encoded in parallel (deflate is the slow part).
                let written: Vec<Result<PathBuf>> = self
                    .rig
                    .par_iter()
                    .map(|&v| {
                        let p = path(&v.name());
                        write_png(&p, f.view(v)?, &display)?;
                        Ok(p)
                    })
                    .collect();
                for p in written {
                    files.push(p?);
                }
                None
            }
            OutputSpec::Anaglyph {
                method,
                swap,
                space,
                ..
            } => {
                let (l, r) = (f.view(View::LEFT)?, f.view(View::RIGHT)?);
                Some((
                    l.width,
                    l.height,
                    make_anaglyph(l, r, *method, *swap, *space, &display),
                ))
            }
            OutputSpec::SideBySide(PairLayout {
                layout: order,
                half,
                ..
            }) => Some(encode(
                &side_by_side(f.view(View::LEFT)?, f.view(View::RIGHT)?, *order, *half),
                &display,
            )),
            OutputSpec::TopBottom(PairLayout {
                layout: order,
                half,
                ..
            }) => Some(encode(
                &top_bottom(f.view(View::LEFT)?, f.view(View::RIGHT)?, *order, *half),
                &display,
            )),
            OutputSpec::Interlaced { layout: order, .. } => Some(encode(
                &interlaced(f.view(View::LEFT)?, f.view(View::RIGHT)?, *order),
                &display,
            )),
            OutputSpec::PseudoStereo { eye, .. } => {
                Some(encode(f.view(View::Eye(*eye))?, &display))
            }
            OutputSpec::WobbleGif {
                views,
                mode,
                per_frame,
                delay_ms,
                loop_count,
                dither,
                ..
            } => {
                let k = f.frame.saturating_sub(self.range_start) as usize;
                let needed = self.spec.views(&self.rig, k);
                // A named pivot stays put: each view moves by its share of the node's parallax.
                let pivot = self.spec.pivot_node().map(|name| {
                    f.pivots
                        .iter()
                        .find(|(n, _)| n == name)
                        .map_or(0.0, |&(_, p)| p)
                });
                let view_image = |v: View| -> Result<std::borrow::Cow<Image>> {
                    let img = f.view(v)?;
                    Ok(match pivot {
                        Some(p) => std::borrow::Cow::Owned(pivot_shift(
                            img,
                            (-v.offset_fraction() * p).round() as i64,
                        )),
                        None => std::borrow::Cow::Borrowed(img),
                    })
                };
                if *per_frame {
                    let mut frames = Vec::new();
                    let mut size = (0, 0);
                    for &i in &wobble_schedule(*views, *mode) {
                        let (w, h, rgb) = encode(&*view_image(needed[i])?, &display);
                        size = (w, h);
                        frames.push(rgb);
                    }
                    let p = path("");
                    write_gif(&p, size.0, size.1, &frames, *delay_ms, *loop_count, *dither)?;
                    files.push(p);
                    None
                } else {
                    Some(encode(&*view_image(needed[0])?, &display))
                }
            }
        };
        let Some((w, h, rgb)) = image else {
            return Ok(FrameFiles {
                files,
                sequence: None,
            });
        };
        let p = if stores_frames(&self.spec) {
            self.stored_frame(f.frame)
        } else {
            path("")
        };
        write_rgb8(&p, w, h, &rgb)?;
        files.push(p);
        Ok(FrameFiles {
            files,
            sequence: has_sequence(&self.spec).then_some((w, h, rgb)),
        })
    }
}

/// The files one output makes of the whole sequence: a video, pseudo-stereo's composited
/// frames, a wobble GIF over the range. It takes the output's 8-bit frames in frame order,
/// straight from the frame loop or, in `assemble`, from the files the shards wrote.
pub struct Sequence {
    spec: OutputSpec,
    template: PathTemplate,
    out_dir: PathBuf,
    video: Option<VideoEncoder>,
    pseudo: Option<PseudoStereo>,
    gif_frames: Vec<Vec<u8>>,
    gif_size: (usize, usize),
}

impl Sequence {
    /// `None` for an output that makes nothing from the whole sequence.
    pub fn new(
        spec: &OutputSpec,
        template: &PathTemplate,
        out_dir: &Path,
        fps: f32,
    ) -> Option<Sequence> {
        if !has_sequence(spec) {
            return None;
        }
        let pseudo = match spec {
            OutputSpec::PseudoStereo {
                channels_now,
                delay,
                ..
            } => Some(PseudoStereo::new(*channels_now, *delay)),
            _ => None,
        };
        Some(Sequence {
            spec: spec.clone(),
            template: template.clone(),
            out_dir: out_dir.to_path_buf(),
            video: spec.video().map(|v| {
                VideoEncoder::new(out_dir.join(v), fps).with_stereo(spec.stereo_packing())
            }),
            pseudo,
            gif_frames: Vec::new(),
            gif_size: (0, 0),
        })
    }

    /// Takes the next frame; returns the files it made at once (pseudo-stereo's frames).
    pub fn push(&mut self, frame: u32, (w, h, rgb): Rgb8) -> Result<Vec<PathBuf>> {
        let mut files = Vec::new();
        let rgb = match self.pseudo.as_mut() {
            Some(pseudo) => {
                let out = pseudo.push(rgb);
                let p = self.template.path(&self.out_dir, frame, "");
                write_rgb8(&p, w, h, &out)?;
                files.push(p);
                out
            }
            None => rgb,
        };
        if let Some(v) = self.video.as_mut() {
            v.push(w, h, &rgb)?;
        }
        if self.spec.single_file() {
            self.gif_size = (w, h);
            self.gif_frames.push(rgb);
        }
        Ok(files)
    }

    /// Whether this sequence makes a file of the whole range (a video, a wobble GIF over the
    /// animation), written by `finish`.
    pub fn spans_range(&self) -> bool {
        self.video.is_some() || self.spec.single_file()
    }

    /// Completes the files that span the range.
    pub fn finish(self) -> Result<Vec<PathBuf>> {
        let mut files = Vec::new();
        if let OutputSpec::WobbleGif {
            per_frame: false,
            delay_ms,
            loop_count,
            dither,
            ..
        } = &self.spec
        {
            let p = self.template.path(&self.out_dir, 0, "");
            write_gif(
                &p,
                self.gif_size.0,
                self.gif_size.1,
                &self.gif_frames,
                *delay_ms,
                *loop_count,
                *dither,
            )?;
            files.push(p);
        }
        if let Some(v) = self.video {
            files.extend(v.finish()?);
        }
        Ok(files)
    }
}

fn encode(img: &Image, display: &Display) -> (usize, usize, Vec<u8>) {
    (img.width, img.height, to_srgb8(img, display))
}
