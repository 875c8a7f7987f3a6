//! Validation of a parsed pipeline: value ranges, output paths and each output's own rules
//! (before any scene is read), then what needs the scene (the camera, the animation). Every
//! failure names the key it concerns, so the error points at its line and column.

use super::collisions::check_collisions;
use super::location::{Invalid, Key, invalid};
use super::schema::{Metres, Pipeline, Selector};
use super::template::PathTemplate;
use crate::render::{Backend, FloatingWindow, NOT_BUILT, Rig};
use crate::scene::Scene;

/// Range checks that need no scene; returns the parsed output templates.
pub(super) fn validate_values(
    p: &Pipeline,
) -> std::result::Result<Vec<PathTemplate>, Invalid<'static>> {
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
    if !r.backend.built() {
        return Err(invalid(&[N("render"), N("backend")], NOT_BUILT));
    }
    if r.backend == Backend::Gpu && r.eye_reuse.reprojects() {
        return Err(invalid(
            &[N("render"), N("eye_reuse")],
            "the GPU backend traces every view itself: eye_reuse must be \"off\" or \"paired\" with backend = \"gpu\"",
        ));
    }
    let s = &p.stereo;
    if let Some(ia) = s.interaxial.fixed()
        && !(ia.is_finite() && ia >= 0.0)
    {
        return Err(invalid(
            &[N("stereo"), N("interaxial")],
            format!("interaxial must be a finite number >= 0 or \"auto\", got {ia}"),
        ));
    }
    if let Some(c) = s.convergence.fixed()
        && !(c.is_finite() && c > 0.0)
    {
        return Err(invalid(
            &[N("stereo"), N("convergence")],
            format!("convergence must be a finite number > 0 or \"auto\", got {c}"),
        ));
    }
    if s.convergence == Metres::Auto && s.rig == Rig::Parallel {
        return Err(invalid(
            &[N("stereo"), N("convergence")],
            "a parallel rig converges at infinity: convergence = \"auto\" needs an \"off-axis\" or \"toe-in\" rig",
        ));
    }
    let budget = [
        ("budget_front", s.budget_front),
        ("budget_behind", s.budget_behind),
    ];
    for (key, pct) in budget {
        if !(pct.is_finite() && pct > 0.0 && pct <= 100.0) {
            return Err(invalid(
                &[N("stereo"), N(key)],
                format!("{key} is a percentage of the image width in (0, 100], got {pct}"),
            ));
        }
    }
    if let Some(w) = s.screen_width
        && !(w.is_finite() && w > 0.0 && w <= 1000.0)
    {
        return Err(invalid(
            &[N("stereo"), N("screen_width")],
            format!("screen_width must be in metres, in (0, 1000], got {w}"),
        ));
    }
    if s.smoothing > 1000 {
        return Err(invalid(
            &[N("stereo"), N("smoothing")],
            format!("smoothing must be at most 1000 frames, got {}", s.smoothing),
        ));
    }
    if s.rig == Rig::Mono
        && (s.floating_window == FloatingWindow::Auto
            || s.interaxial == Metres::Auto
            || s.convergence == Metres::Auto)
    {
        return Err(invalid(
            &[N("stereo"), N("rig")],
            "a mono rig has no parallax: floating_window, interaxial = \"auto\" and convergence = \"auto\" need a stereo rig",
        ));
    }
    // Reprojection looks for a sample's hit on its own film row and pixel window; a toe-in
    // rig's vertical parallax and keystone move points between rows.
    if r.eye_reuse.reprojects() && s.rig == Rig::ToeIn {
        return Err(invalid(
            &[N("render"), N("eye_reuse")],
            "eye_reuse = \"reproject\" and \"reproject-radiance\" need an \"off-axis\", \"parallel\" or \"mono\" rig \
             (toe-in has vertical parallax); use \"paired\" or \"off\" with toe-in",
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
    if p.outputs.is_empty() {
        return Err(invalid(
            &[],
            "the pipeline has no [[output]]: nothing would be written. Add one, for example\n\
             [[output]]\nkind = \"png\"\npath = \"out/frame_{frame:04}_{eye}.png\"",
        ));
    }
    let multi_frame = f.end > f.start;
    let stereo = s.rig != Rig::Mono;
    let mut templates = Vec::new();
    for (i, o) in p.outputs.iter().enumerate() {
        let key = |k: &'static str| [N("output"), Key::Index(i), N(k)];
        let t = PathTemplate::parse(o.path()).map_err(|m| invalid(&key("path"), m))?;
        o.check(&t, stereo, multi_frame)
            .map_err(|(k, m)| invalid(&key(k), m))?;
        templates.push(t);
    }
    check_collisions(p, &templates)?;
    Ok(templates)
}

/// Every node a pipeline names (`[stereo] subject`, a wobble GIF's `pivot`) exists in the scene.
pub(super) fn check_named_nodes(
    p: &Pipeline,
    scene: &Scene,
) -> std::result::Result<(), Invalid<'static>> {
    use Key::Name as N;
    let exists = |name: &str| scene.nodes.iter().any(|n| n.name.as_deref() == Some(name));
    let missing = |name: &str| {
        let mut names: Vec<&str> = scene
            .nodes
            .iter()
            .filter_map(|n| n.name.as_deref())
            .collect();
        names.truncate(20);
        format!(
            "the scene has no node named \"{name}\" (named nodes: {})",
            names.join(", ")
        )
    };
    if let Some(name) = &p.stereo.subject
        && !exists(name)
    {
        return Err(invalid(&[N("stereo"), N("subject")], missing(name)));
    }
    for (i, o) in p.outputs.iter().enumerate() {
        if let Some(name) = o.pivot_node()
            && !exists(name)
        {
            return Err(invalid(
                &[N("output"), Key::Index(i), N("pivot")],
                missing(name),
            ));
        }
    }
    Ok(())
}

pub(super) fn resolve_camera(
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
                    "{}: the scene has no camera; using a default camera that frames the scene's \
                     bounds over frames {}..{} (one camera for every frame of the range)",
                    scene.source.display(),
                    p.frames.start,
                    p.frames.end
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

pub(super) fn check_animation(
    p: &Pipeline,
    scene: &Scene,
) -> std::result::Result<(), Invalid<'static>> {
    let keys = [Key::Name("scene"), Key::Name("animation")];
    // What there is to choose from, for the messages.
    let names: Vec<String> = scene
        .animations
        .iter()
        .enumerate()
        .map(|(i, a)| match &a.name {
            Some(n) => format!("{i}: {n:?}"),
            None => format!("{i}: unnamed"),
        })
        .collect();
    let choices = if names.is_empty() {
        "the scene has no animation".to_string()
    } else {
        format!("the scene has {}, or \"all\" or \"none\"", names.join(", "))
    };
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
                    format!("no animation named '{n}' ({choices})"),
                ));
            }
        }
        Selector::Index(i) => {
            if *i >= scene.animations.len() {
                return Err(invalid(
                    &keys,
                    format!("animation index {i} is out of range ({choices})"),
                ));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::location::{line_column, locate};
    use super::*;
    use std::path::Path;

    #[test]
    fn out_of_range_values_point_at_the_value() {
        let src = "[scene]\npath = \"s.gltf\"\n[render]\nwidth = 0\n";
        let p = Pipeline::parse(Path::new("p.toml"), src).unwrap();
        let inv = validate_values(&p).err().unwrap();
        let (line, col) = line_column(src, locate(src, &inv.keys).unwrap().start);
        assert_eq!((line, col), (4, 9));
    }
}
