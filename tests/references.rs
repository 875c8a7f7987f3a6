//! Every reference scene in `../shared/refs/` (rendered by Mitsuba 3 under WHITTED.md) is rendered
//! with its own parameters and compared per eye with idiff's rule `--fail 0.02 --failpercent 0.5`.

mod common;

use common::{reference_dirs, render_reference};
use stereotrace::compare::difference;
use stereotrace::output::exr::read_views;

#[test]
fn static_references_match_within_idiff_thresholds() {
    let dirs = reference_dirs();
    assert!(
        !dirs.is_empty(),
        "no reference scenes found under ../shared/refs"
    );
    let mut failures = Vec::new();
    for dir in dirs {
        let name = dir.file_name().unwrap().to_string_lossy().to_string();
        let ours = render_reference(&dir);
        for (eye, image) in &ours {
            let reference = &read_views(&dir.join(format!("{eye}.exr"))).unwrap()[0].1;
            let d = difference(image, reference, 0.02).expect("sizes match");
            println!(
                "{name:>18} {eye:>5}: mean abs {:.5}  PSNR {:6.2} dB  over 0.02: {:.3}%  max {:.3} at {:?}",
                d.mean_abs_all(),
                d.psnr,
                d.percent_over(),
                d.max.iter().cloned().fold(0.0, f64::max),
                d.max_pixel
            );
            if d.percent_over() > 0.5 {
                failures.push(format!(
                    "{name} {eye}: {:.3}% of pixels over 0.02",
                    d.percent_over()
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
