//! The animated references in `tests/data/refs/anim/` (a skinned, a morphed and an interpolation
//! test model, posed by an independent implementation and rendered by Mitsuba 3 under WHITTED.md
//! and DESIGN.md's animation conventions): every frame there, both eyes, must pass idiff's
//! `--fail 0.02 --failpercent 0.5`, on the CPU and (built with the `gpu` feature) on the GPU.

mod common;

use common::{data, scratch};
use stereotrace::compare::{Planes, Thresholds, Verdict, compare};
use stereotrace::output::exr::{read_view_planes, read_views};
use stereotrace::pipeline::LoadedPipeline;
use stereotrace::run::{RunOptions, run};

#[test]
fn every_animated_reference_frame_matches() {
    animated_references_match("cpu");
}

#[cfg(feature = "gpu")]
#[test]
fn every_animated_reference_frame_matches_on_the_gpu() {
    if common::gpu_adapter().is_some() {
        animated_references_match("gpu");
    }
}

fn animated_references_match(backend: &str) {
    let mut dirs: Vec<_> = std::fs::read_dir(data().join("refs/anim"))
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|d| d.join("params.json").is_file())
        .collect();
    dirs.sort();
    assert!(
        !dirs.is_empty(),
        "no animated references under tests/data/refs/anim"
    );
    let t = Thresholds {
        fail: 0.02,
        fail_percent: 0.5,
        ..Default::default()
    };
    let mut failures = Vec::new();
    for dir in dirs {
        let name = dir.file_name().unwrap().to_string_lossy().to_string();
        let params: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("params.json")).unwrap())
                .unwrap();
        let out = scratch(&format!("anim-{name}-{backend}"));
        let (res, bg) = (&params["resolution"], &params["background"]);
        let pipeline = out.join("p.toml");
        std::fs::write(
            &pipeline,
            format!(
                "[scene]\npath = {:?}\nanimation = \"all\"\n[render]\nbackend = {backend:?}\nwidth = {}\nheight = {}\nspp = {}\nmax_depth = {}\nbackground = [{}, {}, {}]\n[stereo]\ninteraxial = {}\nconvergence = {}\n[frames]\nfps = {}\n[[output]]\nkind = \"exr\"\npath = \"f_{{frame:04}}.exr\"\n",
                dir.join(params["gltf"].as_str().unwrap()).to_string_lossy(),
                res[0], res[1], params["spp"], params["max_depth"], bg[0], bg[1], bg[2],
                params["interaxial"], params["convergence"], params["fps"]
            ),
        )
        .unwrap();
        let p = LoadedPipeline::load(&pipeline).unwrap();
        for frame in params["frames"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| f.as_u64().unwrap() as u32)
        {
            let opts = RunOptions {
                frames: Some((frame, frame)),
                threads: None,
                out_dir: out.clone(),
                progress: false,
                shard: None,
                resume: false,
            };
            run(&p, &opts).unwrap();
            let ours = read_views(&out.join(format!("f_{frame:04}.exr"))).unwrap();
            for (eye, img) in &ours {
                let reference = &read_view_planes(&dir.join(format!("frame_{frame:04}_{eye}.exr")))
                    .unwrap()[0]
                    .1;
                let d = compare(&Planes::from_image(img), reference, &t);
                println!(
                    "{backend} {name:>26} frame {frame:>3} {eye:>5}: mean abs {:.5}  PSNR {:6.2} dB  over 0.02: {:.3}%  {:?}",
                    d.mean_error,
                    d.psnr,
                    d.percent_failed(),
                    d.verdict
                );
                if d.verdict == Verdict::Fail {
                    failures.push(format!(
                        "{backend} {name} frame {frame} {eye}: {:.3}% over 0.02",
                        d.percent_failed()
                    ));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
