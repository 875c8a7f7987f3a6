//! Every reference scene in `tests/data/refs/` (rendered by Mitsuba 3 under WHITTED.md) is rendered
//! with its own parameters and compared per eye with idiff's rule `--fail 0.02 --failpercent 0.5`,
//! on the CPU and (built with the `gpu` feature) on the GPU.

mod common;

use common::{reference_dirs, render_reference_on};
use stereotrace::compare::{Planes, Thresholds, Verdict, compare};
use stereotrace::output::exr::read_view_planes;

#[test]
fn static_references_match_within_idiff_thresholds() {
    static_references_match("cpu");
}

#[cfg(feature = "gpu")]
#[test]
fn static_references_match_on_the_gpu() {
    if common::gpu_adapter().is_some() {
        static_references_match("gpu");
    }
}

fn static_references_match(backend: &str) {
    let dirs = reference_dirs();
    assert!(
        !dirs.is_empty(),
        "no reference scenes found under tests/data/refs"
    );
    // WHITTED.md section 6: idiff --fail 0.02 --failpercent 0.5 per eye.
    let t = Thresholds {
        fail: 0.02,
        fail_percent: 0.5,
        ..Default::default()
    };
    let mut failures = Vec::new();
    for dir in dirs {
        let name = dir.file_name().unwrap().to_string_lossy().to_string();
        let ours = render_reference_on(&dir, backend);
        for (eye, image) in &ours {
            let reference = &read_view_planes(&dir.join(format!("{eye}.exr"))).unwrap()[0].1;
            let d = compare(&Planes::from_image(image), reference, &t);
            println!(
                "{backend} {name:>18} {eye:>5}: mean abs {:.5}  PSNR {:6.2} dB  over 0.02: {:.3}%  max {:.3} at {:?}  {:?}",
                d.mean_error,
                d.psnr,
                d.percent_failed(),
                d.max_error,
                d.max_at,
                d.verdict
            );
            if d.verdict == Verdict::Fail {
                failures.push(format!(
                    "{backend} {name} {eye}: {:.3}% of pixels over 0.02",
                    d.percent_failed()
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
