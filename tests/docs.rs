//! The documentation stays true: the README is short, every relative link in it, in
//! ARCHITECTURE.md and in `docs/` resolves (anchors included), every TOML snippet with a pipeline
//! in it passes `stereotrace check`, and every command in a shell snippet exists with the flags
//! shown.

mod common;

use common::{repo, scratch};
use std::path::PathBuf;
use std::process::Command;

/// The Markdown pages of the project's documentation.
fn pages() -> Vec<PathBuf> {
    let mut pages = vec![repo().join("README.md"), repo().join("ARCHITECTURE.md")];
    let mut dirs = vec![repo().join("docs")];
    while let Some(dir) = dirs.pop() {
        for e in std::fs::read_dir(&dir).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                dirs.push(p);
            } else if p.extension().is_some_and(|x| x == "md") {
                pages.push(p);
            }
        }
    }
    pages.sort();
    assert!(pages.len() >= 10, "{pages:?}");
    pages
}

/// GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens.
fn anchor(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || *c == ' ' || *c == '-' || *c == '_')
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

/// Fenced blocks of `lang` in a page, each as its text.
fn blocks(text: &str, lang: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut current: Option<String> = None;
    for line in text.lines() {
        match &mut current {
            None if line.trim_start() == format!("```{lang}") => current = Some(String::new()),
            Some(b) if line.trim_start() == "```" => {
                out.push(std::mem::take(b));
                current = None;
            }
            Some(b) => {
                b.push_str(line);
                b.push('\n');
            }
            None => {}
        }
    }
    out
}

#[test]
fn the_readme_is_short() {
    let lines = std::fs::read_to_string(repo().join("README.md"))
        .unwrap()
        .lines()
        .count();
    assert!(lines < 200, "README.md has {lines} lines");
}

#[test]
fn every_relative_link_resolves() {
    let mut broken = Vec::new();
    for page in pages() {
        let text = std::fs::read_to_string(&page).unwrap();
        let mut rest = text.as_str();
        while let Some(i) = rest.find("](") {
            rest = &rest[i + 2..];
            let Some(end) = rest.find(')') else { break };
            let target = &rest[..end];
            if target.contains("://") || target.starts_with("mailto:") {
                continue;
            }
            let (file, fragment) = target.split_once('#').unwrap_or((target, ""));
            let path = if file.is_empty() {
                page.clone()
            } else {
                page.parent().unwrap().join(file)
            };
            if !path.exists() {
                broken.push(format!("{}: {target}", page.display()));
                continue;
            }
            if !fragment.is_empty() {
                let headings = std::fs::read_to_string(&path).unwrap_or_default();
                let found = headings
                    .lines()
                    .filter_map(|l| l.strip_prefix('#'))
                    .any(|h| anchor(h.trim_start_matches('#')) == fragment);
                if !found {
                    broken.push(format!("{}: {target} (no such heading)", page.display()));
                }
            }
        }
    }
    assert!(broken.is_empty(), "{broken:#?}");
}

#[test]
fn every_pipeline_snippet_passes_check() {
    if !common::ffmpeg() {
        return; // the outputs' snippet names a video, which needs ffmpeg
    }
    let dir = scratch("docs-snippets");
    let scene = repo().join("scenes/whitted.gltf");
    let mut checked = 0;
    for page in pages() {
        for (k, block) in blocks(&std::fs::read_to_string(&page).unwrap(), "toml")
            .iter()
            .enumerate()
        {
            // A snippet of outputs alone gets the scene it needs.
            let text = if block.contains("[scene]") {
                block.replace("\"../scenes/whitted.gltf\"", &format!("{scene:?}"))
            } else {
                format!("[scene]\npath = {scene:?}\n\n{block}")
            };
            let file = dir.join(format!(
                "{}-{k}.toml",
                page.file_stem().unwrap().to_string_lossy()
            ));
            std::fs::write(&file, &text).unwrap();
            let o = Command::new(env!("CARGO_BIN_EXE_stereotrace"))
                .arg("check")
                .arg(&file)
                .output()
                .unwrap();
            assert!(
                o.status.success(),
                "{} snippet {k}: {}",
                page.display(),
                String::from_utf8_lossy(&o.stderr)
            );
            checked += 1;
        }
    }
    assert!(checked >= 2, "only {checked} TOML snippets");
}

/// The command and its arguments in a line of a shell snippet, when it runs stereotrace.
fn stereotrace_args(line: &str) -> Option<Vec<String>> {
    let line = line.split(" #").next().unwrap_or(line).trim();
    let args = if let Some(rest) = line.strip_prefix("stereotrace ") {
        rest
    } else if line.starts_with("cargo run") {
        line.split_once(" -- ")?.1
    } else {
        return None;
    };
    Some(args.split_whitespace().map(str::to_owned).collect())
}

#[test]
fn every_command_shown_exists_with_its_flags() {
    let mut shown = 0;
    for page in pages() {
        for block in blocks(&std::fs::read_to_string(&page).unwrap(), "sh") {
            let joined = block.replace("\\\n", " ");
            for line in joined.lines() {
                let Some(args) = stereotrace_args(line) else {
                    continue;
                };
                let words = if args.first().map(String::as_str) == Some("bench") {
                    2
                } else {
                    1
                };
                let command: Vec<&str> = args.iter().take(words).map(String::as_str).collect();
                let o = Command::new(env!("CARGO_BIN_EXE_stereotrace"))
                    .args(&command)
                    .arg("--help")
                    .output()
                    .unwrap();
                let help = String::from_utf8_lossy(&o.stdout);
                assert!(o.status.success(), "{}: {line}", page.display());
                for flag in args.iter().filter(|a| a.starts_with("--")) {
                    let flag = flag.split('=').next().unwrap();
                    assert!(
                        help.contains(flag),
                        "{}: `{line}`: {flag} is not an option of {command:?}",
                        page.display()
                    );
                }
                for flag in args.iter().filter(|a| a.len() == 2 && a.starts_with('-')) {
                    assert!(
                        help.contains(&format!("{flag},")) || help.contains(&format!("{flag} ")),
                        "{}: `{line}`: {flag} is not an option of {command:?}",
                        page.display()
                    );
                }
                shown += 1;
            }
        }
    }
    assert!(shown >= 10, "only {shown} commands in shell snippets");
}

#[test]
fn the_guide_index_answers_each_question() {
    let guide = std::fs::read_to_string(repo().join("docs/guide/README.md")).unwrap();
    for question in [
        "render my own model",
        "anaglyph",
        "depth budget",
        "Slurm",
        "use the GPU",
        "frame log",
    ] {
        assert!(
            guide.contains(question),
            "the guide's index lacks {question:?}"
        );
    }
}
