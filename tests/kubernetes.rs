//! The Kubernetes manifest of `deploy/kubernetes/render.yaml`, as far as a machine without a
//! cluster can check it: every resource validates against Kubernetes' published schemas in
//! strict mode (no unknown field) with `kubernetes-validate`, the settings a render farm relies
//! on are there, and the shard count agrees with the Job's completions.

mod common;

use common::repo;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The Kubernetes version the manifest is checked against: the first in which every field it
/// uses is generally available (`backoffLimitPerIndex`: 1.33, `podReplacementPolicy`: 1.34).
const KUBERNETES: &str = "1.34.0";

fn manifest() -> PathBuf {
    repo().join("deploy/kubernetes/render.yaml")
}

/// `kubernetes-validate` from `target/tools` (scripts/test.sh) or the PATH.
fn validator() -> Option<PathBuf> {
    let provisioned = repo().join("target/tools/bin/kubernetes-validate");
    let found = if provisioned.is_file() {
        Some(provisioned)
    } else {
        std::env::var_os("PATH").and_then(|paths| {
            std::env::split_paths(&paths)
                .map(|d| d.join("kubernetes-validate"))
                .find(|p| p.is_file())
        })
    };
    if found.is_none() {
        common::missing_tool("kubernetes-validate", "STEREOTRACE_SKIP_K8S");
    }
    found
}

fn validate(tool: &Path, file: &Path) -> (bool, String) {
    let o = Command::new(tool)
        .args(["--strict", "-k", KUBERNETES])
        .arg(file)
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    (o.status.success(), text)
}

#[test]
fn the_job_manifest_validates_strictly_and_a_misspelt_one_does_not() {
    let Some(tool) = validator() else {
        return;
    };
    let (ok, said) = validate(&tool, &manifest());
    assert!(ok, "{said}");
    for resource in [
        "job/stereotrace-render",
        "job/stereotrace-assemble",
        "serviceaccount/stereotrace-assemble",
        "role/stereotrace-read-jobs",
        "rolebinding/stereotrace-assemble-reads-jobs",
    ] {
        assert!(
            said.contains(&format!("passed for resource {resource}")),
            "{said}"
        );
    }
    // The check can fail: one misspelt key is refused.
    let text = std::fs::read_to_string(manifest()).unwrap();
    let bad = common::scratch("kubernetes").join("misspelt.yaml");
    std::fs::write(
        &bad,
        text.replace("podReplacementPolicy:", "podReplacePolicy:"),
    )
    .unwrap();
    let (ok, said) = validate(&tool, &bad);
    assert!(!ok && said.contains("podReplacePolicy"), "{said}");
}

#[test]
fn the_render_job_is_indexed_retries_per_index_and_never_runs_an_index_twice() {
    let text = std::fs::read_to_string(manifest()).unwrap();
    for setting in [
        "completionMode: Indexed",
        "backoffLimitPerIndex: 2",
        "maxFailedIndexes: 0",
        "podReplacementPolicy: Failed",
        "restartPolicy: Never",
        "- --resume",
    ] {
        assert!(text.contains(setting), "missing: {setting}");
    }
    let value = |key: &str| -> String {
        text.lines()
            .find_map(|l| l.trim().strip_prefix(key))
            .unwrap_or_else(|| panic!("no {key}"))
            .trim()
            .to_string()
    };
    let completions = value("completions:");
    assert_eq!(
        value("- auto/"),
        completions,
        "--shard auto/N with N = completions"
    );
    assert_eq!(value("parallelism:"), completions);
}
