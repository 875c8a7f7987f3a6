//! One writer per `[[output]]`: it receives every stereo frame in order and turns it into files.
//! Writers keep state across frames where their kind needs it (pseudo-stereo's delayed frames, a
//! wobble GIF's frames, a video stream) and finish at the end of the range. The image work itself
//! lives in `output/`; this module only routes frames and paths.

use super::output_spec::{ExrViews, OutputSpec, PairLayout};
use super::template::PathTemplate;
use crate::error::{Error, Result};
use crate::output::{
    Display, Image, PseudoStereo, VideoEncoder, interlaced, make_anaglyph, side_by_side, to_srgb8,
    top_bottom, wobble_schedule, write_gif, write_multiview, write_png, write_rgb8,
    write_single_view,
};
use crate::render::View;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// The views of one frame, linear radiance.
pub struct StereoFrame {
    pub frame: u32,
    pub views: Vec<(View, Image)>,
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

pub struct Writer {
    spec: OutputSpec,
    template: PathTemplate,
    /// The rig's own views, for EXR and PNG.
    rig: Vec<View>,
    video: Option<VideoEncoder>,
    pseudo: Option<PseudoStereo>,
    gif_frames: Vec<Vec<u8>>,
    gif_size: (usize, usize),
    out_dir: PathBuf,
    /// Index of the next frame within the range.
    k: usize,
}

impl Writer {
    pub fn new(
        spec: &OutputSpec,
        template: &PathTemplate,
        rig: &[View],
        out_dir: &Path,
        fps: f32,
    ) -> Writer {
        let pseudo = match spec {
            OutputSpec::PseudoStereo {
                channels_now,
                delay,
                ..
            } => Some(PseudoStereo::new(*channels_now, *delay)),
            _ => None,
        };
        Writer {
            spec: spec.clone(),
            template: template.clone(),
            rig: rig.to_vec(),
            video: spec
                .video()
                .map(|v| VideoEncoder::new(out_dir.join(v), fps)),
            pseudo,
            gif_frames: Vec::new(),
            gif_size: (0, 0),
            out_dir: out_dir.to_path_buf(),
            k: 0,
        }
    }

    /// Writes (or stores) what this output makes of one frame; returns the files written.
    pub fn frame(&mut self, f: &StereoFrame) -> Result<Vec<PathBuf>> {
        let display = self.spec.display();
        let path = |eye: &str| self.template.path(&self.out_dir, f.frame, eye);
        let mut files = Vec::new();
        // Sequence outputs make one 8-bit image per frame: a PNG, and a video frame if asked.
        let sequence: Option<(usize, usize, Vec<u8>)> = match &self.spec {
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
                let img = f.view(View::Eye(*eye))?.clone();
                let out = self
                    .pseudo
                    .as_mut()
                    .expect("pseudo-stereo writers have state")
                    .push(img);
                Some(encode(&out, &display))
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
                let needed = self.spec.views(&self.rig, self.k);
                let order = if *per_frame {
                    wobble_schedule(*views, *mode)
                } else {
                    vec![0]
                };
                let mut frames = Vec::new();
                for &i in &order {
                    let (w, h, rgb) = encode(f.view(needed[i])?, &display);
                    self.gif_size = (w, h);
                    frames.push(rgb);
                }
                if *per_frame {
                    let p = path("");
                    write_gif(
                        &p,
                        self.gif_size.0,
                        self.gif_size.1,
                        &frames,
                        *delay_ms,
                        *loop_count,
                        *dither,
                    )?;
                    files.push(p);
                } else {
                    self.gif_frames.extend(frames);
                }
                None
            }
        };
        if let Some((w, h, rgb)) = sequence {
            let p = path("");
            write_rgb8(&p, w, h, &rgb)?;
            files.push(p);
            if let Some(v) = self.video.as_mut() {
                v.push(w, h, &rgb)?;
            }
        }
        self.k += 1;
        Ok(files)
    }

    /// Whether this output makes a file of the whole range (a video, a wobble GIF over the
    /// animation), written by `finish`.
    pub fn spans_range(&self) -> bool {
        self.video.is_some() || self.spec.single_file()
    }

    /// Completes outputs that span the range (a wobble GIF over the animation, videos).
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
