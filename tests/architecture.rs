//! The shape DESIGN.md asks of the code, checked on the source itself so that it stays true:
//! small files, a thin `main.rs`, no module that imports from a module importing it back,
//! `pipeline/` and `run/` reaching the other folders only through their front doors (`mod.rs`),
//! and the pipeline file never importing the run.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Every `.rs` file under `src/` by module path (`accel::tree`, `pipeline`, `` for lib.rs).
fn modules() -> BTreeMap<String, PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(&p, out);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    walk(&src, &mut files);
    files
        .into_iter()
        .map(|p| {
            let rel = p.strip_prefix(&src).unwrap().with_extension("");
            let mut parts: Vec<String> = rel
                .components()
                .map(|c| c.as_os_str().to_string_lossy().into_owned())
                .collect();
            if matches!(
                parts.last().map(String::as_str),
                Some("mod" | "lib" | "main")
            ) {
                parts.pop();
            }
            (parts.join("::"), p)
        })
        .collect()
}

/// The code of a file without its `#[cfg(test)]` tail (tests may import anything).
fn code(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    match text.find("#[cfg(test)]\nmod tests") {
        Some(i) => text[..i].to_string(),
        None => text,
    }
}

/// `crate::`/`super::` paths a file names, brace groups expanded one level
/// (`crate::output::{exr, png}` gives `crate::output::exr` and `crate::output::png`).
fn paths_named(code: &str) -> Vec<String> {
    let mut out = Vec::new();
    let bytes = code.as_bytes();
    for start in ["crate::", "super::"] {
        let mut from = 0;
        while let Some(i) = code[from..].find(start).map(|i| i + from) {
            from = i + start.len();
            if i > 0 && (bytes[i - 1].is_ascii_alphanumeric() || b"_:".contains(&bytes[i - 1])) {
                continue;
            }
            let end = code[i..]
                .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_' || c == ':'))
                .map_or(code.len(), |e| e + i);
            let path = code[i..end].trim_end_matches(':').to_string();
            if code[end..].starts_with('{') {
                let close = code[end..].find('}').map_or(code.len(), |c| c + end);
                for name in code[end + 1..close].split([',', ' ', '\n']) {
                    let name = name.split("::").next().unwrap_or("").trim();
                    if !name.is_empty() && name != "self" {
                        out.push(format!("{path}::{name}"));
                    }
                }
            }
            out.push(path);
        }
    }
    out
}

/// The longest module prefix of a path, relative to the module that names it.
fn resolve(from: &str, path: &str, mods: &BTreeMap<String, PathBuf>) -> Option<String> {
    let mut parts: Vec<&str> = path.split("::").collect();
    let mut base: Vec<&str> = if from.is_empty() {
        Vec::new()
    } else {
        from.split("::").collect()
    };
    if parts[0] == "crate" {
        base.clear();
        parts.remove(0);
    } else {
        while parts.first() == Some(&"super") {
            base.pop();
            parts.remove(0);
        }
    }
    (0..=parts.len()).rev().find_map(|k| {
        let m = base
            .iter()
            .chain(&parts[..k])
            .copied()
            .collect::<Vec<_>>()
            .join("::");
        mods.contains_key(&m).then_some(m)
    })
}

/// For each module, the other modules it imports from (parents and children excluded: a
/// `mod.rs` declares its children, and a child may use what its parent re-exports).
fn imports() -> BTreeMap<String, BTreeSet<String>> {
    let mods = modules();
    mods.iter()
        .map(|(m, p)| {
            let deps = paths_named(&code(p))
                .iter()
                .filter_map(|path| resolve(m, path, &mods))
                .filter(|d| {
                    let related =
                        |a: &str, b: &str| b.is_empty() || a.starts_with(&format!("{b}::"));
                    d != m && !related(m, d) && !related(d, m)
                })
                .collect();
            (m.clone(), deps)
        })
        .collect()
}

#[test]
fn no_source_file_is_longer_than_600_lines_and_main_stays_thin() {
    for (m, p) in modules() {
        let lines = std::fs::read_to_string(&p).unwrap().lines().count();
        let limit = if p.ends_with("main.rs") { 250 } else { 600 };
        assert!(
            lines <= limit,
            "{m} ({}) has {lines} lines, over {limit}",
            p.display()
        );
    }
}

#[test]
fn no_module_imports_from_a_module_that_imports_it_back() {
    let graph = imports();
    let reaches = |from: &str, to: &str| {
        let mut stack = vec![from.to_string()];
        let mut seen = BTreeSet::new();
        while let Some(m) = stack.pop() {
            if m == to {
                return true;
            }
            if seen.insert(m.clone()) {
                stack.extend(graph.get(&m).into_iter().flatten().cloned());
            }
        }
        false
    };
    let mut cycles = Vec::new();
    for (a, deps) in &graph {
        for b in deps {
            if reaches(b, a) {
                cycles.push(format!("{a} -> {b} -> ... -> {a}"));
            }
        }
    }
    assert!(cycles.is_empty(), "import cycles: {cycles:#?}");
}

#[test]
fn pipeline_and_run_reach_other_folders_only_through_their_front_doors() {
    let mods = modules();
    let mut back_doors = Vec::new();
    for (m, p) in &mods {
        let own = m.split("::").next().unwrap_or("");
        if !["pipeline", "run"].contains(&own) {
            continue;
        }
        for path in paths_named(&code(p)) {
            let Some(d) = resolve(m, &path, &mods) else {
                continue;
            };
            let top = d.split("::").next().unwrap_or("");
            let folders = ["scene", "accel", "render", "output", "pipeline", "run"];
            if top != own && folders.contains(&top) && d.contains("::") {
                back_doors.push(format!("{m} uses {path}"));
            }
        }
    }
    assert!(back_doors.is_empty(), "{back_doors:#?}");
}

/// The pipeline file is what a user asks; the run is how frames are made of it. The file side
/// never depends on the run (`check`, `new` and `info` need no frame loop).
#[test]
fn the_pipeline_file_never_imports_the_run() {
    let mods = modules();
    let mut uses = Vec::new();
    for (m, p) in mods.iter().filter(|(m, _)| m.starts_with("pipeline")) {
        for path in paths_named(&code(p)) {
            if resolve(m, &path, &mods).is_some_and(|d| d == "run" || d.starts_with("run::")) {
                uses.push(format!("{m} uses {path}"));
            }
        }
    }
    assert!(uses.is_empty(), "{uses:#?}");
}

#[test]
fn the_checker_sees_imports_through_braces_and_super() {
    let mods: BTreeMap<String, PathBuf> = ["", "a", "a::b", "c"]
        .iter()
        .map(|m| (m.to_string(), PathBuf::new()))
        .collect();
    let named = paths_named("use crate::a::{b::X, Y};\nuse super::super::c;\nlet v = acrate::z;");
    let resolved: BTreeSet<_> = named
        .iter()
        .filter_map(|p| resolve("a::b", p, &mods))
        .collect();
    assert_eq!(
        resolved,
        ["a", "a::b", "c"].iter().map(|s| s.to_string()).collect()
    );
}

/// ARCHITECTURE.md names every folder of `src/`, and every `src/` path it names exists.
#[test]
fn the_architecture_page_names_every_folder_and_only_what_exists() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let page = std::fs::read_to_string(root.join("ARCHITECTURE.md")).unwrap();
    let folders: Vec<String> = std::fs::read_dir(root.join("src"))
        .unwrap()
        .flatten()
        .filter(|e| e.path().is_dir())
        .map(|e| format!("src/{}/", e.file_name().to_string_lossy()))
        .collect();
    assert!(folders.len() >= 8, "{folders:?}");
    for f in &folders {
        assert!(
            page.contains(f.as_str()),
            "ARCHITECTURE.md does not name {f}"
        );
    }
    let named: Vec<&str> = page
        .split(|c: char| c.is_whitespace() || "`(),;:".contains(c))
        .filter(|w| w.starts_with("src/"))
        .collect();
    assert!(named.len() >= 10, "{named:?}");
    for path in named {
        assert!(
            root.join(path.trim_end_matches('.')).exists(),
            "ARCHITECTURE.md names {path}, which does not exist"
        );
    }
}
