//! `[render] eye_reuse = "reproject"`: the right eye takes the left eye's camera hits where the
//! rule of `render/reproject.rs` allows and traces the rest. It is approximate, so these tests
//! bound its error: every Mitsuba reference still passes on both eyes, a scene built to break
//! reuse (thin bars in front of a chequered wall, a mirror at the convergence plane) keeps the
//! right eye within the documented bound of its own full trace, the left eye is untouched, the
//! reused hits of the diffuse scene at 16 spp are those of its full trace, and the images do not
//! depend on the thread count.

mod common;

use common::{position_buffers, quad, reference_dirs, reference_pipeline, repo, scratch};
use serde_json::json;
use std::path::{Path, PathBuf};
use stereotrace::compare::{Comparison, Planes, Thresholds, Verdict, compare};
use stereotrace::output::Image;
use stereotrace::output::exr::{read_view_planes, read_views};
use stereotrace::pipeline::LoadedPipeline;
use stereotrace::run::{RunOptions, run};

/// The two approximate modes: hits reused, and hits with the radiance of rough surfaces.
const MODES: [&str; 2] = ["reproject", "reproject-radiance"];

/// What a render left: each eye's image and the frame log's reuse counts (reused, traced).
struct Render {
    eyes: Vec<(String, Image)>,
    reused: u64,
    traced: u64,
}

/// Renders `pipeline` (whose only EXR output is `ours.exr` or `out/*.exr`) with `eye_reuse`.
fn render(pipeline: &Path, eye_reuse: &str, threads: usize, name: &str) -> Render {
    let text = std::fs::read_to_string(pipeline).unwrap();
    let out = scratch(name);
    let edited = out.join("pipeline.toml");
    let dir = pipeline.parent().unwrap();
    let text = text
        .replace(
            "[render]",
            &format!("[render]\neye_reuse = \"{eye_reuse}\""),
        )
        .replace("\"../scenes/", &format!("\"{}/../scenes/", dir.display()));
    std::fs::write(&edited, text).unwrap();
    let p = LoadedPipeline::load(&edited).unwrap();
    run(
        &p,
        &RunOptions {
            frames: None,
            threads: Some(threads),
            out_dir: out.clone(),
            progress: false,
            shard: None,
            resume: false,
        },
    )
    .unwrap();
    let exr = std::fs::read_dir(&out)
        .unwrap()
        .chain(std::fs::read_dir(out.join("out")).into_iter().flatten())
        .filter_map(|e| e.ok().map(|e| e.path()))
        .find(|p| p.extension().is_some_and(|x| x == "exr"))
        .expect("an EXR output");
    // Per frame (repeated on each object's row): samples that reused a hit, samples traced.
    let mut log = csv::Reader::from_path(out.join("frame-log.csv")).unwrap();
    let header = log.headers().unwrap().clone();
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    let (mut reused, mut traced, mut last_frame) = (0u64, 0u64, None);
    for row in log.records() {
        let row = row.unwrap();
        if last_frame == Some(row[0].to_string()) {
            continue;
        }
        last_frame = Some(row[0].to_string());
        reused += row[col("reused_samples")].parse::<u64>().unwrap();
        traced += row[col("traced_samples")].parse::<u64>().unwrap();
    }
    Render {
        eyes: read_views(&exr).unwrap(),
        reused,
        traced,
    }
}

/// `pipelines/diffuse.toml` with each `(from, to)` of `edits` replaced, written into the
/// scratch folder `name`, its scene read from the repository.
fn diffuse_pipeline(name: &str, edits: &[(&str, &str)]) -> PathBuf {
    let mut text = std::fs::read_to_string(repo().join("pipelines/diffuse.toml")).unwrap();
    for (from, to) in edits {
        assert!(
            text.contains(from),
            "pipelines/diffuse.toml has no {from:?}"
        );
        text = text.replace(from, to);
    }
    let text = text.replace("\"../scenes/", &format!("\"{}/scenes/", repo().display()));
    let path = scratch(name).join("diffuse.toml");
    std::fs::write(&path, text).unwrap();
    path
}

fn eye<'a>(r: &'a Render, name: &str) -> &'a Image {
    &r.eyes.iter().find(|(n, _)| n == name).unwrap().1
}

fn diff(a: &Image, b: &Image) -> Comparison {
    let t = Thresholds {
        fail: 0.02,
        fail_percent: 0.5,
        ..Default::default()
    };
    compare(&Planes::from_image(a), &Planes::from_image(b), &t)
}

#[test]
fn reprojection_passes_every_mitsuba_reference_on_both_eyes() {
    let dirs = reference_dirs();
    assert!(
        !dirs.is_empty(),
        "no reference scenes under tests/data/refs"
    );
    // WHITTED.md section 6: idiff --fail 0.02 --failpercent 0.5 per eye.
    let t = Thresholds {
        fail: 0.02,
        fail_percent: 0.5,
        ..Default::default()
    };
    let mut failures = Vec::new();
    for (dir, mode) in dirs.iter().flat_map(|d| MODES.iter().map(move |m| (d, *m))) {
        let name = dir.file_name().unwrap().to_string_lossy().to_string();
        let pipeline = reference_pipeline(dir, &scratch(&format!("reproject-{name}")));
        let ours = render(&pipeline, mode, 2, &format!("{mode}-{name}-run"));
        for (eye, image) in &ours.eyes {
            let reference = &read_view_planes(&dir.join(format!("{eye}.exr"))).unwrap()[0].1;
            let d = compare(&Planes::from_image(image), reference, &t);
            println!(
                "{mode:>18} {name:>18} {eye:>5}: PSNR {:6.2} dB  over 0.02: {:.3}%  reused {} traced {}",
                d.psnr,
                d.percent_failed(),
                ours.reused,
                ours.traced
            );
            if d.verdict == Verdict::Fail {
                failures.push(format!(
                    "{name} {eye}: {:.3}% over 0.02",
                    d.percent_failed()
                ));
            }
        }
        if name == "parallax_markers" {
            // A diffuse scene: reuse must happen. About 40% of its frame is background, which
            // never reuses (misses are traced), and the bottom rows are too close to the edge
            // strip; 30% of the right eye's samples reuse today.
            let right_samples = (ours.traced + ours.reused) / 2;
            assert!(
                ours.reused * 4 > right_samples,
                "{mode} {name}: only {} right-eye samples reused",
                ours.reused
            );
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// The scene built to break reuse, seen from (0, 0, 5) looking down -Z: a chequered wall at depth
/// 6 (two materials), twelve bars two pixels wide at depth 2 (they shift 9 pixels against the
/// wall between the eyes, so each hides a different strip of wall from each eye), a mirror at
/// the convergence plane (depth 3) and a point light that casts the bars' shadows on the wall.
fn breaker_scene(dir: &Path) -> std::path::PathBuf {
    let mut parts: Vec<(Vec<[f32; 3]>, usize)> = vec![(Vec::new(), 0), (Vec::new(), 1)];
    let (nx, ny) = (16, 10);
    for i in 0..nx {
        for j in 0..ny {
            let (x0, y0) = (
                -4.0 + 8.0 * i as f32 / nx as f32,
                -2.5 + 5.0 * j as f32 / ny as f32,
            );
            let (x1, y1) = (x0 + 8.0 / nx as f32, y0 + 5.0 / ny as f32);
            let square = quad([
                [x0, y0, -1.0],
                [x1, y0, -1.0],
                [x1, y1, -1.0],
                [x0, y1, -1.0],
            ]);
            parts[(i + j) % 2].0.extend(square);
        }
    }
    let mut bars = Vec::new();
    for k in 0..12 {
        let x = -1.5 + 0.25 * k as f32;
        bars.extend(quad([
            [x, -1.2, 3.0],
            [x + 0.01, -1.2, 3.0],
            [x + 0.01, 1.2, 3.0],
            [x, 1.2, 3.0],
        ]));
    }
    parts.push((bars, 2));
    parts.push((
        quad([
            [1.0, -0.6, 2.0],
            [1.8, -0.6, 2.2],
            [1.8, 0.6, 2.2],
            [1.0, 0.6, 2.0],
        ]),
        3,
    ));
    let positions: Vec<&[[f32; 3]]> = parts.iter().map(|(p, _)| p.as_slice()).collect();
    let (views, accessors, buffers) = position_buffers(&positions);
    let primitives: Vec<_> = parts
        .iter()
        .enumerate()
        .map(|(k, (_, material))| json!({"attributes": {"POSITION": k}, "material": material}))
        .collect();
    let material = |name: &str, color: [f32; 3], metallic: f32, roughness: f32| {
        json!({"name": name, "pbrMetallicRoughness": {"baseColorFactor": [color[0], color[1], color[2], 1.0],
            "metallicFactor": metallic, "roughnessFactor": roughness}})
    };
    let g = json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 60.0}]}},
        "scene": 0,
        "scenes": [{"nodes": [0, 1, 2]}],
        "nodes": [
            {"mesh": 0},
            {"name": "Cam", "camera": 0, "translation": [0.0, 0.0, 5.0]},
            {"extensions": {"KHR_lights_punctual": {"light": 0}}, "translation": [2.0, 2.0, 4.0]}
        ],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}],
        "meshes": [{"primitives": primitives}],
        "materials": [
            material("light squares", [0.9, 0.85, 0.8], 0.0, 0.8),
            material("dark squares", [0.1, 0.12, 0.2], 0.0, 0.8),
            material("bars", [0.9, 0.3, 0.1], 0.0, 0.5),
            material("mirror", [0.95, 0.95, 0.95], 1.0, 0.0)
        ],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": buffers
    });
    let scene = dir.join("breaker.gltf");
    std::fs::write(&scene, serde_json::to_string(&g).unwrap()).unwrap();
    let pipeline = dir.join("breaker.toml");
    std::fs::write(
        &pipeline,
        format!(
            "[scene]\npath = {:?}\ncamera = \"Cam\"\n[render]\nwidth = 320\nheight = 180\nspp = 4\n\
             [stereo]\nrig = \"off-axis\"\ninteraxial = 0.065\nconvergence = 3.0\n\
             [[output]]\nkind = \"exr\"\npath = \"ours.exr\"\n",
            scene.to_string_lossy()
        ),
    )
    .unwrap();
    pipeline
}

/// The documented bounds (README, "Stereo reuse") of the right eye against its own full trace
/// on that scene, per mode: (least PSNR in dB, most percent of pixels off by more than 0.02).
const BOUNDS: [(f64, f64); 2] = [(50.0, 0.1), (60.0, 0.02)];

#[test]
fn a_scene_built_to_break_reuse_stays_within_the_bound_and_the_left_eye_is_untouched() {
    let dir = scratch("breaker-scene");
    let pipeline = breaker_scene(&dir);
    let off = render(&pipeline, "off", 2, "reproject-breaker-off");
    for (mode, (min_psnr, max_over)) in MODES.iter().zip(BOUNDS) {
        let reuse = render(&pipeline, mode, 2, &format!("{mode}-breaker"));
        assert!(
            eye(&off, "left").pixels == eye(&reuse, "left").pixels,
            "{mode}: the left eye changed"
        );
        let d = diff(eye(&reuse, "right"), eye(&off, "right"));
        let right_samples = (reuse.traced + reuse.reused) / 2;
        println!(
            "{mode} breaker right eye: PSNR {:.2} dB, {:.3}% over 0.02, {} of {} samples reused",
            d.psnr,
            d.percent_failed(),
            reuse.reused,
            right_samples
        );
        assert!(reuse.reused > 0, "{mode}: nothing was reused");
        assert!(
            d.psnr >= min_psnr && d.percent_failed() <= max_over,
            "{mode}: right eye PSNR {:.2} dB, {:.3}% of pixels over 0.02",
            d.psnr,
            d.percent_failed()
        );
    }
}

/// On the diffuse scene at 200x150 and 16 spp, `reproject`'s reused hits are those of the
/// full trace (a hit a last bit apart at a shared edge leaves it above 100 dB). Two pixels of
/// the blue sphere's lowest row hold it only as long as the rules read 5 pixels along a row:
/// with 3 their rays passed the sphere triangles the left eye hit and met the floor behind
/// them, and the right eye gave 82.6 dB (`docs/guide/stereo-reuse.md`, tried and dropped).
#[test]
fn reused_hits_at_16_spp_are_those_of_the_full_trace() {
    let path = diffuse_pipeline(
        "reproject-diffuse-16spp",
        &[
            ("width = 640", "width = 200"),
            ("height = 360", "height = 150"),
            ("spp = 4", "spp = 16"),
        ],
    );
    let off = render(&path, "off", 2, "reproject-16spp-off");
    let reuse = render(&path, "reproject", 2, "reproject-16spp-reuse");
    let d = diff(eye(&reuse, "right"), eye(&off, "right"));
    println!(
        "16 spp right eye against its full trace: {:.2} dB, {} samples reused",
        d.psnr, reuse.reused
    );
    assert!(reuse.reused > 0, "nothing was reused");
    assert!(
        d.psnr >= 100.0,
        "right eye {:.2} dB against its full trace",
        d.psnr
    );
}

#[test]
fn reprojection_does_not_depend_on_the_thread_count() {
    let pipeline = repo().join("pipelines/diffuse.toml");
    let one = render(&pipeline, "reproject", 1, "reproject-diffuse-1");
    let two = render(&pipeline, "reproject", 2, "reproject-diffuse-2");
    for ((name, a), (_, b)) in one.eyes.iter().zip(&two.eyes) {
        assert!(
            a.pixels == b.pixels,
            "{name} differs between 1 and 2 threads"
        );
    }
    assert_eq!((one.reused, one.traced), (two.reused, two.traced));
}

#[test]
fn reprojection_refuses_a_toe_in_rig() {
    let path = diffuse_pipeline(
        "reproject-toe-in",
        &[
            ("[render]", "[render]\neye_reuse = \"reproject\""),
            ("rig = \"off-axis\"", "rig = \"toe-in\""),
        ],
    );
    let err = match LoadedPipeline::load(&path) {
        Ok(_) => panic!("reproject with toe-in was accepted"),
        Err(e) => e.to_string(),
    };
    assert!(err.contains("eye_reuse") && err.contains("toe-in"), "{err}");
}
