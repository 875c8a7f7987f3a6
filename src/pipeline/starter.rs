//! `stereotrace new SCENE`: a commented pipeline for a scene, with its cameras, animations and
//! frame range filled in and every output kind present (all but one commented out), so that
//! nobody writes a pipeline from the guide by hand.

use crate::error::{Error, Result};
use crate::output::write_atomic;
use crate::scene::{Scene, distance_to_bounds, framing_camera, overlapping_animations};
use glam::Vec3;
use std::fmt::Write;
use std::io::Write as _;
use std::path::{Path, PathBuf};

/// Frames per second of the written frame range (the pipeline's default).
const FPS: f32 = 24.0;

/// The stereographers' 1/30 rule of thumb: an interaxial of about a thirtieth of the distance to
/// the nearest subject keeps its parallax comfortable.
const INTERAXIAL_PER_DISTANCE: f32 = 1.0 / 30.0;

/// Writes the starter pipeline for `scene` to `output` (which must not exist yet), or returns
/// it for standard output. The scene path in it is relative to the output's folder, or
/// absolute on standard output (where the pipeline will be saved is unknown).
pub fn new_pipeline(scene_file: &Path, output: Option<&Path>) -> Result<Option<String>> {
    let scene = Scene::load(scene_file)?;
    let scene_path = match output {
        Some(out) => relative_to(scene_file, out.parent().unwrap_or(Path::new("")))?,
        None => std::fs::canonicalize(scene_file).map_err(|e| Error::io(scene_file, e))?,
    };
    let text = starter_text(&scene, &scene_path.to_string_lossy());
    match output {
        None => Ok(Some(text)),
        Some(out) if out.exists() => Err(Error::input(
            out,
            "exists already; `new` does not overwrite a pipeline (choose another name)",
        )),
        Some(out) => {
            write_atomic(out, |w| w.write_all(text.as_bytes()))?;
            Ok(None)
        }
    }
}

/// `file` as a path relative to the folder `dir` (both taken from the current directory).
fn relative_to(file: &Path, dir: &Path) -> Result<PathBuf> {
    let abs = |p: &Path| {
        let p = if p.as_os_str().is_empty() {
            Path::new(".")
        } else {
            p
        };
        std::path::absolute(p).map_err(|e| Error::io(p, e))
    };
    let (file, dir) = (abs(file)?, abs(dir)?);
    let (f, d): (Vec<_>, Vec<_>) = (file.components().collect(), dir.components().collect());
    let common = f.iter().zip(&d).take_while(|(a, b)| a == b).count();
    let mut rel: PathBuf = d[common..].iter().map(|_| "..").collect();
    rel.extend(&f[common..]);
    Ok(rel)
}

/// The pipeline text for `scene`, whose file is `scene_path` from the pipeline's folder.
pub fn starter_text(scene: &Scene, scene_path: &str) -> String {
    let posed = scene.pose_at(&[], 0.0);
    let (lo, hi) = posed
        .geometry
        .bounds()
        .unwrap_or((Vec3::splat(-1.0), Vec3::splat(1.0)));
    // As `[scene] camera` takes them: a name in quotes, or an index into the glTF cameras.
    let cameras: Vec<String> = posed
        .cameras
        .iter()
        .map(|c| {
            scene
                .camera_name(c)
                .map_or_else(|| c.camera.to_string(), |n| format!("{n:?}"))
        })
        .collect();
    // Where the eyes will be: the first camera, or the default camera that frames the scene.
    let eye = posed.cameras.first().map_or_else(
        || framing_camera(lo, hi).1.transform_point3(Vec3::ZERO),
        |c| c.world.transform_point3(Vec3::ZERO),
    );
    let centre = eye.distance((lo + hi) * 0.5).max(1e-3);
    let nearest = distance_to_bounds(eye, (lo, hi));
    // Clips that drive the same nodes (a walk and a run) are alternatives: the first plays.
    let alternatives = !overlapping_animations(&scene.animations).is_empty();
    let duration = scene
        .animations
        .iter()
        .take(if alternatives { 1 } else { usize::MAX })
        .map(|a| a.summary().duration)
        .fold(0.0f32, f32::max);
    let end = (duration * FPS).round() as u32;
    let lit = !posed.lights.is_empty();

    let mut t = String::new();
    let file_name = Path::new(scene_path)
        .file_name()
        .map_or(scene_path.into(), |n| n.to_string_lossy());
    let _ = writeln!(
        t,
        "# A pipeline for {file_name}, written by `stereotrace new`. Render it with\n\
         #   stereotrace render THIS_FILE --out out\n\
         # Paths in [scene] are relative to this file; output paths to --out. Every key is in\n\
         # docs/guide/pipeline.md of stereotrace; a key left out takes its default.\n"
    );
    let _ = writeln!(t, "[scene]\npath = {scene_path:?}");
    match cameras.as_slice() {
        [] => t.push_str(
            "# The scene has no camera: a default camera frames the scene's bounds over the\n\
             # frame range (one camera for every frame).\n",
        ),
        [only] => {
            let _ = writeln!(t, "camera = {only}");
        }
        [first, ..] => {
            let _ = writeln!(
                t,
                "camera = {first}   # the scene's cameras: {}",
                cameras.join(", ")
            );
        }
    }
    let names: Vec<String> = scene
        .animations
        .iter()
        .enumerate()
        .map(|(i, a)| {
            let s = a.summary();
            format!(
                "{} ({:.2} s)",
                s.name.map_or(i.to_string(), |n| format!("{n:?}")),
                s.duration
            )
        })
        .collect();
    if names.is_empty() {
        t.push_str("animation = \"none\"   # the scene has no animation\n");
    } else if alternatives {
        let first = match &scene.animations[0].name {
            Some(n) => format!("{n:?}"),
            None => "0".into(),
        };
        let _ = writeln!(
            t,
            "# The clips drive the same nodes, so one plays (\"all\" would play them over each\n\
             # other); by name or index: {names}, or \"none\".\nanimation = {first}",
            names = names.join(", ")
        );
    } else {
        let _ = writeln!(
            t,
            "animation = \"all\"    # \"all\", \"none\", or one by name or index: {}",
            names.join(", ")
        );
    }
    let _ = writeln!(
        t,
        "\n[render]\nwidth = 960\nheight = 540\nspp = 4                  # samples per pixel\n\
         max_depth = 8            # mirror and glass recursion\n\
         shading = \"cook-torrance\"  # or \"phong\"\n\
         background = [0.05, 0.05, 0.06]\n\
         # eye_reuse = \"off\"      # \"paired\" | \"reproject\" | \"reproject-radiance\" (docs/guide/stereo-reuse.md)\n\
         # threads = 0            # 0 = all cores"
    );
    if !lit {
        t.push_str("# The scene has no lights: a head-light at the camera lights it.\n");
    }
    let _ = writeln!(
        t,
        "\n[stereo]\nrig = \"off-axis\"         # \"off-axis\" | \"parallel\" | \"toe-in\" | \"mono\"\n\
         interaxial = {:.4}      # metres; a thirtieth of the distance to the nearest point ({nearest:.3} m)\n\
         convergence = {centre:.3}      # metres to the zero-parallax plane: here the scene's centre\n\
         # interaxial = \"auto\"     # the largest interaxial within the depth budget below\n\
         # convergence = \"auto\"    # the subject's depth, or the median depth at the frame's centre\n\
         # subject = \"NODE\"        # a node \"auto\" convergence holds at zero parallax\n\
         # budget_front = 1.0      # parallax allowed in front of the screen, % of the width\n\
         # budget_behind = 2.0     # and behind it (check --depth shows every frame's)\n\
         # floating_window = \"auto\" # black borders where near objects cross the frame edges",
        nearest * INTERAXIAL_PER_DISTANCE
    );
    let _ = writeln!(
        t,
        "\n[frames]\nstart = 0\nend = {end}                 # inclusive{}\nfps = {FPS}",
        if end > 0 {
            format!(
                ": {}, {duration:.2} s",
                if alternatives {
                    "the animation"
                } else {
                    "the longest animation"
                }
            )
        } else {
            String::new()
        }
    );
    t.push_str(
        "\n[[output]]\nkind = \"png\"             # 8-bit sRGB, one file per eye\n\
         path = \"{frame:04}_{eye}.png\"\n",
    );
    for (comment, body) in OTHER_OUTPUTS {
        let _ = write!(t, "\n# {comment}\n");
        for line in body.lines() {
            let _ = writeln!(t, "# {line}");
        }
    }
    t
}

/// Every other output kind with its main keys (defaults shown), for the user to uncomment.
const OTHER_OUTPUTS: [(&str, &str); 7] = [
    (
        "Multi-view OpenEXR, linear radiance (both eyes in one file).",
        "[[output]]\nkind = \"exr\"\npath = \"{frame:04}.exr\"\nhalf = false",
    ),
    (
        "Anaglyph, with an optional video of the sequence (needs ffmpeg).",
        "[[output]]\nkind = \"anaglyph\"\nmethod = \"dubois-red-cyan\"\npath = \"anaglyph_{frame:04}.png\"\nvideo = \"anaglyph.mp4\"",
    ),
    (
        "Both eyes side by side (\"cross\" puts the right eye first, for cross-eyed viewing).",
        "[[output]]\nkind = \"side-by-side\"\nlayout = \"parallel\"\nhalf = false\npath = \"sbs_{frame:04}.png\"",
    ),
    (
        "Both eyes one above the other.",
        "[[output]]\nkind = \"top-bottom\"\npath = \"tb_{frame:04}.png\"",
    ),
    (
        "Row-interlaced (even rows the first eye), for line-interleaved displays.",
        "[[output]]\nkind = \"interlaced\"\npath = \"interlaced_{frame:04}.png\"",
    ),
    (
        "Delayed-channel pseudo-stereo from one eye's sequence.",
        "[[output]]\nkind = \"pseudo-stereo\"\neye = \"left\"\nchannels_now = \"red\"\ndelay = 1\npath = \"pseudo_{frame:04}.png\"",
    ),
    (
        "Wobble GIF: the views along the baseline in turn.",
        "[[output]]\nkind = \"wobble-gif\"\nviews = 2\nmode = \"bounce\"\ndelay_ms = 120\npath = \"wobble.gif\"",
    ),
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_relative_path_climbs_out_of_the_pipeline_folder() {
        assert_eq!(
            relative_to(Path::new("models/a.glb"), Path::new("pipelines")).unwrap(),
            Path::new("../models/a.glb")
        );
        assert_eq!(
            relative_to(Path::new("a.glb"), Path::new("")).unwrap(),
            Path::new("a.glb")
        );
    }
}
