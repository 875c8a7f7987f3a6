//! EXR files written by other tools from ours read as the reference library reads them. The
//! files in `tests/data/exr/` were made once by OpenEXR 3.1.5's `exrmultiview` (Debian's
//! `openexr` package) from `ours_left.exr` and `ours_right.exr`, so the suite needs no OpenEXR
//! tools to run.

mod common;

use std::process::Command;

fn compare(a: &str, b: &str) -> (Option<i32>, serde_json::Value, String) {
    let dir = common::data().join("exr");
    let o = Command::new(env!("CARGO_BIN_EXE_stereotrace"))
        .args(["compare", "--json"])
        .arg(dir.join(a))
        .arg(dir.join(b))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    let report = serde_json::from_slice(&o.stdout).unwrap_or(serde_json::Value::Null);
    (o.status.code(), report, stderr)
}

/// `exrmultiview` copies its first input's `chunkCount` while it changes the compression (PIZ:
/// 2 chunks for 40 rows, not ZIP's 3; none: 40), and keeps the last input's `view` in a
/// multi-view header. Both files hold exactly our two views: `compare` finds them equal to our
/// own stereo file, view by view.
#[test]
fn stereo_files_joined_by_exrmultiview_equal_ours() {
    for joined in ["exrmultiview_piz.exr", "exrmultiview_none.exr"] {
        let (code, report, stderr) = compare(joined, "ours_stereo.exr");
        assert_eq!(code, Some(0), "{joined}: {stderr} {report}");
        let views: Vec<&str> = report["views"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v[0].as_str().unwrap())
            .collect();
        assert_eq!(views, ["left", "right"], "{joined}");
        assert_eq!(report["missing_views"], serde_json::json!([]), "{joined}");
        for v in report["views"].as_array().unwrap() {
            assert_eq!(v[1]["max_error"], 0.0, "{joined}: {}", v[0]);
        }
    }
    // The eyes differ, so a view read under the other's name would not pass.
    let (code, _, _) = compare("ours_left.exr", "ours_right.exr");
    assert_eq!(code, Some(2));
}
