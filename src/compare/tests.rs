//! The difference metrics and verdicts on planes written by hand.

use super::*;

fn planes(w: usize, h: usize, v: &[[f32; 3]]) -> Planes {
    Planes {
        width: w,
        height: h,
        names: vec!["R".into(), "G".into(), "B".into()],
        data: (0..3).map(|c| v.iter().map(|p| p[c]).collect()).collect(),
    }
}

#[test]
fn a_png_difference_is_the_largest_channel_difference_in_grey() {
    let a = planes(2, 1, &[[0.0, 0.0, 0.0], [0.5, 0.5, 0.5]]);
    let b = planes(2, 1, &[[0.1, 0.4, 0.0], [0.5, 0.5, 0.5]]);
    let dir = std::env::temp_dir().join(format!("stereotrace-diff-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("d.png");
    let views = |p: Planes| vec![("left".to_string(), p)];
    let inputs = [Path::new("a.exr"), Path::new("b.exr")];
    let written = write_differences(&views(a), &views(b), &out, 2.0, inputs).unwrap();
    assert_eq!(written, vec![out.clone()]);
    let img = image::open(&out).unwrap().to_rgb8();
    // max(0.1, 0.4, 0) * 2 = 0.8 -> 204; identical pixel -> 0.
    assert_eq!(img.get_pixel(0, 0).0, [204, 204, 204]);
    assert_eq!(img.get_pixel(1, 0).0, [0, 0, 0]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn one_view_each_writes_its_difference_whatever_the_views_are_called() {
    // Our per-eye file (view "right") against a plain RGB reference: compared, so differenced.
    let a = planes(1, 1, &[[0.5, 0.5, 0.5]]);
    let b = planes(1, 1, &[[0.5, 0.25, 0.5]]);
    let dir = std::env::temp_dir().join(format!("stereotrace-diff1-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("d.png");
    let inputs = [Path::new("a.exr"), Path::new("b.exr")];
    let written = write_differences(
        &[("right".to_string(), a)],
        &[("RGB".to_string(), b)],
        &out,
        1.0,
        inputs,
    )
    .unwrap();
    assert_eq!(written, vec![out.clone()]);
    assert_eq!(
        image::open(&out).unwrap().to_rgb8().get_pixel(0, 0).0,
        [64; 3]
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_pixel_fails_once_however_many_channels_exceed() {
    let a = planes(2, 1, &[[0.0; 3], [0.0; 3]]);
    let b = planes(2, 1, &[[0.2, 0.3, 0.0], [0.0; 3]]);
    let t = Thresholds {
        fail: 0.1,
        warn: 0.05,
        ..Default::default()
    };
    let c = compare(&a, &b, &t);
    assert_eq!((c.failures, c.warnings), (1, 1));
    assert_eq!(c.max_at, (0, 0, 1));
    assert!((c.mean_error - 0.5 / 6.0).abs() < 1e-7);
    assert!((c.psnr - 16.642_078_7).abs() < 1e-5, "{}", c.psnr);
    assert_eq!(c.verdict, Verdict::Fail);
}

#[test]
fn nan_makes_the_max_infinite_without_counting_a_failure() {
    let a = planes(1, 1, &[[f32::NAN, 0.0, 0.0]]);
    let b = planes(1, 1, &[[0.0; 3]]);
    let t = Thresholds {
        hard_fail: 0.5,
        ..Default::default()
    };
    let c = compare(&a, &b, &t);
    assert_eq!(c.failures, 0);
    assert!(c.max_error.is_infinite());
    // No failures: idiff passes before it looks at hardfail.
    assert_eq!(c.verdict, Verdict::Pass);
    assert_eq!(compare(&a, &a, &t).max_error, 0.0);
}

#[test]
fn relative_threshold_uses_the_mean_magnitude() {
    let a = planes(1, 1, &[[1.0, 0.0, 0.0]]);
    let t = Thresholds {
        fail: 0.01,
        warn: 0.01,
        fail_relative: 0.1,
        warn_relative: 0.1,
        ..Default::default()
    };
    assert_eq!(
        compare(&a, &planes(1, 1, &[[1.105, 0.0, 0.0]]), &t).failures,
        0
    );
    assert_eq!(
        compare(&a, &planes(1, 1, &[[1.11, 0.0, 0.0]]), &t).failures,
        1
    );
}

#[test]
fn verdict_follows_idiffs_order() {
    let a = planes(4, 1, &[[0.0; 3]; 4]);
    let b = planes(4, 1, &[[0.5; 3]; 4]);
    let v = |t: Thresholds| compare(&a, &b, &t).verdict;
    assert_eq!(
        v(Thresholds {
            fail: 0.6,
            warn: 0.1,
            ..Default::default()
        }),
        Verdict::Pass
    );
    assert_eq!(
        v(Thresholds {
            fail: 0.1,
            fail_percent: 100.0,
            ..Default::default()
        }),
        Verdict::Warn
    );
    assert_eq!(
        v(Thresholds {
            fail: 0.1,
            fail_percent: 100.0,
            hard_fail: 0.4,
            ..Default::default()
        }),
        Verdict::Fail
    );
    assert_eq!(
        v(Thresholds {
            fail: 0.1,
            allow_failures: 4,
            ..Default::default()
        }),
        Verdict::Pass
    );
    assert_eq!(
        v(Thresholds {
            fail: 0.1,
            allow_failures: 3,
            ..Default::default()
        }),
        Verdict::Fail
    );
}

#[test]
fn different_sizes_compare_over_the_union_with_zeros() {
    let a = planes(1, 1, &[[0.5; 3]]);
    let b = planes(2, 1, &[[0.5; 3], [0.5; 3]]);
    let c = compare(&a, &b, &Thresholds::default());
    assert_eq!((c.width, c.failures), (2, 1));
    assert_eq!(c.verdict, Verdict::Fail);
}
