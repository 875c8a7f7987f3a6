//! Outputs that would write over each other or over the run's own inputs,
//! found before anything is traced. Paths are compared after lexical normalisation (`./a`,
//! `sub/../a` and `a//b` name what `a` and `a/b` name), for every frame and eye the outputs
//! write, and at run time with the output folder's links resolved.

use super::LoadedPipeline;
use super::location::{Invalid, Key, invalid};
use super::output_spec::SEQUENCE_FRAMES;
use super::schema::Pipeline;
use super::template::PathTemplate;
use crate::error::{Error, Result};
use crate::render::Rig;
use std::collections::HashMap;
use std::path::{Component, Path, PathBuf};

/// Frames whose files are listed when a range is longer than this: its first and last
/// `FRAMES_LISTED / 2` frames. A clash between a fixed name and a frame's name shows within
/// the first frames (frame numbers are what differ), and ten thousand frames of a few outputs
/// are listed in milliseconds.
const FRAMES_LISTED: u32 = 10_000;

/// One file an output writes: its path relative to `--out`, normalised, and the key naming it.
pub struct Written {
    pub path: String,
    output: usize,
    key: &'static str,
}

/// `a/./b/../c//d` as `a/c/d`.
fn normalise(path: &str) -> String {
    let mut parts: Vec<&str> = Vec::new();
    for part in path.split('/') {
        match part {
            "" | "." => {}
            ".." => {
                parts.pop();
            }
            p => parts.push(p),
        }
    }
    parts.join("/")
}

/// Every file the outputs write over the frames `start..=end`.
pub fn written(p: &Pipeline, templates: &[PathTemplate], start: u32, end: u32) -> Vec<Written> {
    let eyes: &[&str] = if p.stereo.rig == Rig::Mono {
        &["center"]
    } else {
        &["left", "right"]
    };
    let frames: Vec<u32> = if end - start < FRAMES_LISTED {
        (start..=end).collect()
    } else {
        (start..start + FRAMES_LISTED / 2)
            .chain(end - FRAMES_LISTED / 2 + 1..=end)
            .collect()
    };
    let mut out = Vec::new();
    for (i, (o, t)) in p.outputs.iter().zip(templates).enumerate() {
        let mut add = |path: String, key| {
            out.push(Written {
                path: normalise(&path),
                output: i,
                key,
            })
        };
        if o.single_file() {
            // A whole-range file is named from frame 0 (`Writer::finish`).
            add(t.render(0, ""), "path");
        } else {
            for &f in &frames {
                if t.has_eye() {
                    for eye in eyes {
                        add(t.render(f, eye), "path");
                    }
                } else {
                    add(t.render(f, ""), "path");
                }
                if !t.has_frame() {
                    break;
                }
            }
        }
        if let Some(v) = o.video() {
            add(v.to_string(), "video");
        }
    }
    out
}

/// Refuses outputs that write the same file as another output (or as another output's video),
/// and outputs inside the folder of stored sequence frames. (No output can write the frame
/// log or a manifest: their names end in .png, .exr, .gif or a video's.)
pub(super) fn check_collisions(
    p: &Pipeline,
    templates: &[PathTemplate],
) -> std::result::Result<(), Invalid<'static>> {
    for (i, o) in p.outputs.iter().enumerate() {
        let named = std::iter::once(("path", o.path())).chain(o.video().map(|v| ("video", v)));
        for (key, raw) in named {
            if let Some(why) = unwritable(raw) {
                return Err(invalid(
                    &[Key::Name("output"), Key::Index(i), Key::Name(key)],
                    why,
                ));
            }
        }
    }
    let all = written(p, templates, p.frames.start, p.frames.end);
    let mut seen: HashMap<String, (usize, &'static str)> = HashMap::new();
    for w in &all {
        seen.entry(w.path.clone()).or_insert((w.output, w.key));
    }
    for w in &all {
        let key = [Key::Name("output"), Key::Index(w.output), Key::Name(w.key)];
        if let Some(part) = w.path.split('/').find(|c| c.len() > NAME_MAX) {
            return Err(invalid(
                &key,
                format!(
                    "the name '{}...' is {} bytes long; file systems allow {NAME_MAX}",
                    &part[..part.floor_char_boundary(40)],
                    part.len()
                ),
            ));
        }
        // A folder of this file that another output writes as a file.
        let mut folder = String::new();
        for part in w
            .path
            .split('/')
            .collect::<Vec<_>>()
            .split_last()
            .map_or(&[][..], |l| l.1)
        {
            if !folder.is_empty() {
                folder.push('/');
            }
            folder.push_str(part);
            if let Some(&(other, _)) = seen.get(&folder) {
                return Err(invalid(
                    &key,
                    format!(
                        "[[output]] number {} writes into the folder {folder}, which [[output]] \
                         number {} writes as a file",
                        w.output + 1,
                        other + 1
                    ),
                ));
            }
        }
    }
    let mut seen: HashMap<String, (usize, &'static str)> = HashMap::new();
    for w in all {
        let key = [Key::Name("output"), Key::Index(w.output), Key::Name(w.key)];
        if w.path.split('/').next() == Some(SEQUENCE_FRAMES) {
            return Err(invalid(
                &key,
                format!(
                    "{SEQUENCE_FRAMES}/ is where a render keeps the frames of its sequence outputs: \
                     choose another folder"
                ),
            ));
        }
        match seen.get(&w.path) {
            Some(&(other, other_key)) if other != w.output || other_key != w.key => {
                let what = |k: &str| if k == "video" { "the video of " } else { "" };
                return Err(invalid(
                    &key,
                    format!(
                        "{}[[output]] number {} writes {}, which {}[[output]] number {} writes too",
                        what(w.key),
                        w.output + 1,
                        w.path,
                        what(other_key),
                        other + 1
                    ),
                ));
            }
            Some(_) => {}
            None => {
                seen.insert(w.path, (w.output, w.key));
            }
        }
    }
    Ok(())
}

/// The longest file or folder name Linux file systems take, in bytes (`NAME_MAX` of
/// `<linux/limits.h>`; ext4, XFS and tmpfs alike).
const NAME_MAX: usize = 255;

/// Why an output path as written can never be a file's name, if it cannot.
fn unwritable(raw: &str) -> Option<String> {
    if raw.ends_with('/') || raw.ends_with("/.") || raw.ends_with("/..") {
        return Some(format!("'{raw}' names a folder, not a file"));
    }
    if raw.contains('\0') {
        return Some("the path holds a NUL character, which no file name can".into());
    }
    None
}

/// A path made absolute, with the links of its folder resolved where that folder exists.
fn resolved(path: &Path) -> PathBuf {
    let abs = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut clean = PathBuf::new();
    for c in abs.components() {
        match c {
            Component::ParentDir => {
                clean.pop();
            }
            Component::CurDir => {}
            c => clean.push(c),
        }
    }
    match (clean.parent(), clean.file_name()) {
        (Some(dir), Some(name)) => std::fs::canonicalize(dir)
            .map(|d| d.join(name))
            .unwrap_or(clean),
        _ => clean,
    }
}

/// Refuses a run whose outputs (for `start..=end`, under `out_dir`) would overwrite its
/// pipeline, its scene file or a buffer or image file of the scene.
pub fn check_inputs_untouched(
    p: &LoadedPipeline,
    out_dir: &Path,
    start: u32,
    end: u32,
) -> Result<()> {
    // The pipeline, the scene file and every buffer and image file the scene names.
    let inputs: Vec<PathBuf> = std::iter::once(&p.file)
        .chain(&p.scene.files)
        .filter_map(|f| std::fs::canonicalize(f).ok())
        .collect();
    for w in written(&p.spec, &p.templates, start, end) {
        let target = resolved(&out_dir.join(&w.path));
        if inputs.contains(&target) {
            return Err(Error::input(
                &p.file,
                format!(
                    "[[output]] number {} would overwrite {}, an input of this run",
                    w.output + 1,
                    target.display()
                ),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_that_name_the_same_file_normalise_alike() {
        for p in [
            "a/b.png",
            "./a/b.png",
            "a//b.png",
            "a/c/../b.png",
            "a/./b.png",
        ] {
            assert_eq!(normalise(p), "a/b.png", "{p}");
        }
    }
}
