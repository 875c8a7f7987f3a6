//! Regression clips: the project's scenes rendered by stereotrace and stored under
//! `tests/golden/`. Every run renders them again and compares each eye of each frame with a
//! threshold (never byte equality: other platforms may round differently). After an intended
//! change, regenerate with `STEREOTRACE_BLESS=1 cargo test --test golden` and commit the EXRs.

mod common;

use common::{repo, scratch};
use stereotrace::compare::{Thresholds, Verdict, compare_files};
use stereotrace::pipeline::LoadedPipeline;
use stereotrace::run::run;

#[test]
fn whitted_clip_matches_its_stored_frames() {
    let golden = repo().join("tests/golden");
    let pipeline = LoadedPipeline::load(&golden.join("whitted_clip.toml")).unwrap();
    let bless = std::env::var("STEREOTRACE_BLESS").as_deref() == Ok("1");
    let out = if bless {
        golden.clone()
    } else {
        scratch("golden-whitted")
    };
    let summary = run(&pipeline, &common::whole_range_into(&out)).unwrap();
    assert_eq!(summary.frames, 3);
    if bless {
        println!(
            "regenerated {} files under {}",
            summary.files,
            golden.display()
        );
        return;
    }
    // Half-float storage rounds to 2^-11 relative: 0.005 absolute leaves room for that and for
    // platform rounding, and still catches any visible change.
    let t = Thresholds {
        fail: 0.005,
        fail_percent: 0.05,
        warn: 0.005,
        ..Default::default()
    };
    for frame in 0..3 {
        let name = format!("whitted_clip_{frame:04}.exr");
        let r = compare_files(&out.join(&name), &golden.join(&name), &t).unwrap();
        assert_eq!(r.views.len(), 2, "{name}: both eyes");
        for (view, c) in &r.views {
            println!(
                "{name} {view}: mean {:.2e} max {:.2e} failing {}",
                c.mean_error, c.max_error, c.failures
            );
        }
        assert_eq!(
            r.verdict,
            Verdict::Pass,
            "{name} changed: {:?}",
            r.views
                .iter()
                .map(|(v, c)| (v, c.failures, c.max_error))
                .collect::<Vec<_>>()
        );
    }
}
