//! Checks of a glTF document's structure before the glTF crate reads it. The crate's own
//! validation, and its readers, panic on some invalid files (an index that resolves to nothing,
//! an animation path it does not know, indices stored as floats); these checks refuse such a
//! file with the object at fault instead. They follow the glTF 2.0 specification's rules for
//! what each index must resolve to and what type each accessor must have.

use crate::error::{Error, Result};
use serde_json::Value;
use std::path::Path;

/// GLB header and chunk type of the JSON chunk ("JSON" in ASCII, little-endian).
const GLB_MAGIC: &[u8; 4] = b"glTF";
const JSON_CHUNK: u32 = 0x4E4F_534A;

/// Component types (glTF 2.0, accessor.componentType): byte, unsigned byte, short, unsigned
/// short, unsigned int, float.
const COMPONENT_TYPES: [u64; 6] = [5120, 5121, 5122, 5123, 5125, 5126];
const UNSIGNED_INDEX_TYPES: [u64; 3] = [5121, 5123, 5125];
const FLOAT: u64 = 5126;
const ACCESSOR_TYPES: [&str; 7] = ["SCALAR", "VEC2", "VEC3", "VEC4", "MAT2", "MAT3", "MAT4"];
const ANIMATION_PATHS: [&str; 4] = ["translation", "rotation", "scale", "weights"];
const INTERPOLATIONS: [&str; 3] = ["LINEAR", "STEP", "CUBICSPLINE"];

/// Checks the document in `bytes` (a `.gltf` file or a GLB container).
pub(super) fn check(file: &Path, bytes: &[u8]) -> Result<()> {
    let json = if bytes.starts_with(GLB_MAGIC) {
        glb_json(file, bytes)?
    } else {
        bytes
    };
    let doc: Value = serde_json::from_slice(json).map_err(|e| {
        Error::scene(
            file,
            "",
            format!("not a readable glTF file: invalid JSON: {e}"),
        )
    })?;
    Document { file, doc: &doc }.check()
}

/// The JSON chunk of a GLB file, after checking that the header tells the truth.
fn glb_json<'a>(file: &Path, bytes: &'a [u8]) -> Result<&'a [u8]> {
    let word = |at: usize| {
        bytes
            .get(at..at + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    let fail = |m: String| Err(Error::scene(file, "", m));
    let (Some(version), Some(length)) = (word(4), word(8)) else {
        return fail("a GLB header is 12 bytes; the file is shorter".into());
    };
    if version != 2 {
        return fail(format!("GLB version {version}; only version 2 exists"));
    }
    if length as usize != bytes.len() {
        return fail(format!(
            "the GLB header gives a length of {length} bytes, but the file has {}",
            bytes.len()
        ));
    }
    match (word(12), word(16)) {
        (Some(n), Some(JSON_CHUNK)) if 20 + n as usize <= bytes.len() => {
            Ok(&bytes[20..20 + n as usize])
        }
        (Some(_), Some(JSON_CHUNK)) => fail("the JSON chunk runs past the end of the file".into()),
        _ => fail("the first GLB chunk must be the JSON chunk".into()),
    }
}

struct Document<'a> {
    file: &'a Path,
    doc: &'a Value,
}

impl Document<'_> {
    fn array(&self, key: &str) -> &[Value] {
        array_of(self.doc.get(key))
    }

    fn fail(&self, object: String, message: impl Into<String>) -> Error {
        Error::scene(self.file, object, message)
    }

    /// `v`, when present, must be an index into the document's `target` array.
    fn index(&self, v: Option<&Value>, target: &str, object: impl Fn() -> String) -> Result<()> {
        let Some(v) = v else { return Ok(()) };
        let n = self.array(target).len();
        match v.as_u64() {
            Some(i) if (i as usize) < n => Ok(()),
            _ => Err(self.fail(
                object(),
                format!("{v} is not an index into {target} (the file has {n})"),
            )),
        }
    }

    fn check(&self) -> Result<()> {
        let version = self.doc.get("asset").and_then(|a| a.get("version"));
        if version
            .and_then(Value::as_str)
            .is_none_or(|v| v.split('.').next() != Some("2"))
        {
            return Err(self.fail(
                "asset.version".into(),
                format!(
                    "this reader reads glTF 2.x; the file says {}",
                    version.map_or("nothing".into(), Value::to_string)
                ),
            ));
        }
        self.check_accessors()?;
        for (i, b) in self.array("bufferViews").iter().enumerate() {
            self.index(b.get("buffer"), "buffers", || {
                format!("bufferViews[{i}].buffer")
            })?;
        }
        for (i, n) in self.array("nodes").iter().enumerate() {
            let at = |k: &'static str| move || format!("nodes[{i}].{k}");
            self.index(n.get("mesh"), "meshes", at("mesh"))?;
            self.index(n.get("camera"), "cameras", at("camera"))?;
            self.index(n.get("skin"), "skins", at("skin"))?;
            for (k, c) in array_of(n.get("children")).iter().enumerate() {
                self.index(Some(c), "nodes", || format!("nodes[{i}].children[{k}]"))?;
            }
        }
        for (i, s) in self.array("scenes").iter().enumerate() {
            for (k, n) in array_of(s.get("nodes")).iter().enumerate() {
                self.index(Some(n), "nodes", || format!("scenes[{i}].nodes[{k}]"))?;
            }
        }
        self.index(self.doc.get("scene"), "scenes", || "scene".into())?;
        for (i, s) in self.array("skins").iter().enumerate() {
            let at = format!("skins[{i}]");
            self.index(s.get("inverseBindMatrices"), "accessors", || {
                format!("{at}.inverseBindMatrices")
            })?;
            self.require_kind(
                s.get("inverseBindMatrices"),
                format!("{at}.inverseBindMatrices"),
                &["MAT4"],
                &[FLOAT],
            )?;
            self.index(s.get("skeleton"), "nodes", || format!("{at}.skeleton"))?;
            for (k, j) in array_of(s.get("joints")).iter().enumerate() {
                self.index(Some(j), "nodes", || format!("{at}.joints[{k}]"))?;
            }
        }
        for (i, t) in self.array("textures").iter().enumerate() {
            self.index(t.get("source"), "images", || {
                format!("textures[{i}].source")
            })?;
            self.index(t.get("sampler"), "samplers", || {
                format!("textures[{i}].sampler")
            })?;
        }
        for (i, im) in self.array("images").iter().enumerate() {
            self.index(im.get("bufferView"), "bufferViews", || {
                format!("images[{i}].bufferView")
            })?;
            // glTF 2.0 "Images": exactly one of uri and bufferView, and a bufferView needs its
            // mimeType; the gltf crate unwraps both.
            let (uri, view) = (im.get("uri"), im.get("bufferView"));
            if uri.is_some() == view.is_some() {
                return Err(self.fail(
                    format!("images[{i}]"),
                    "must have exactly one of uri and bufferView",
                ));
            }
            if view.is_some() && im.get("mimeType").is_none() {
                return Err(self.fail(
                    format!("images[{i}].mimeType"),
                    "is required when the image is in a bufferView",
                ));
            }
        }
        self.check_meshes()?;
        self.check_animations()
    }

    fn check_accessors(&self) -> Result<()> {
        for (i, a) in self.array("accessors").iter().enumerate() {
            let at = |k: &str| format!("accessors[{i}].{k}");
            self.index(a.get("bufferView"), "bufferViews", || at("bufferView"))?;
            let component = a.get("componentType").and_then(Value::as_u64);
            if !component.is_some_and(|c| COMPONENT_TYPES.contains(&c)) {
                return Err(self.fail(
                    at("componentType"),
                    format!("must be one of {COMPONENT_TYPES:?}"),
                ));
            }
            let kind = a.get("type").and_then(Value::as_str);
            if !kind.is_some_and(|t| ACCESSOR_TYPES.contains(&t)) {
                return Err(self.fail(at("type"), format!("must be one of {ACCESSOR_TYPES:?}")));
            }
            if let Some(sparse) = a.get("sparse") {
                let s = |k: &str| sparse.get(k).and_then(|v| v.get("bufferView"));
                self.index(s("indices"), "bufferViews", || {
                    at("sparse.indices.bufferView")
                })?;
                self.index(s("values"), "bufferViews", || {
                    at("sparse.values.bufferView")
                })?;
            }
        }
        Ok(())
    }

    /// An accessor's component type and type, once `check_accessors` passed.
    fn accessor_kind(&self, i: u64) -> (u64, &str) {
        let a = &self.array("accessors")[i as usize];
        (
            a["componentType"].as_u64().unwrap_or(0),
            a["type"].as_str().unwrap_or(""),
        )
    }

    /// The accessor `index` (resolved already; absent: nothing to check) is one of `kinds` with
    /// one of `components`: the crate's readers assume it and panic on a mismatch.
    fn require_kind(
        &self,
        index: Option<&Value>,
        object: String,
        kinds: &[&str],
        components: &[u64],
    ) -> Result<()> {
        let Some(i) = index.and_then(Value::as_u64) else {
            return Ok(());
        };
        let (component, kind) = self.accessor_kind(i);
        if kinds.contains(&kind) && components.contains(&component) {
            return Ok(());
        }
        Err(self.fail(
            object,
            format!(
                "must be an accessor of {} with componentType {components:?}, not {kind} {component}",
                kinds.join(" or ")
            ),
        ))
    }

    /// What an attribute's accessor must be (glTF 2.0, "Meshes": attribute semantics);
    /// `None` for semantics the tool does not read.
    fn attribute_rule(semantic: &str) -> Option<(&'static [&'static str], &'static [u64])> {
        let base = semantic.split('_').next().unwrap_or("");
        Some(match base {
            "POSITION" | "NORMAL" => (&["VEC3"], &[FLOAT]),
            "TANGENT" => (&["VEC4"], &[FLOAT]),
            "TEXCOORD" => (&["VEC2"], &[FLOAT, 5121, 5123]),
            "COLOR" => (&["VEC3", "VEC4"], &[FLOAT, 5121, 5123]),
            "JOINTS" => (&["VEC4"], &[5121, 5123]),
            "WEIGHTS" => (&["VEC4"], &[FLOAT, 5121, 5123]),
            _ => return None,
        })
    }

    fn check_meshes(&self) -> Result<()> {
        for (m, mesh) in self.array("meshes").iter().enumerate() {
            for (p, prim) in array_of(mesh.get("primitives")).iter().enumerate() {
                let at = format!("meshes[{m}].primitives[{p}]");
                self.index(prim.get("material"), "materials", || {
                    format!("{at}.material")
                })?;
                if let Some(ix) = prim.get("indices") {
                    self.index(Some(ix), "accessors", || format!("{at}.indices"))?;
                    let (component, kind) = self.accessor_kind(ix.as_u64().unwrap_or(0));
                    if kind != "SCALAR" || !UNSIGNED_INDEX_TYPES.contains(&component) {
                        return Err(self.fail(
                            format!("{at}.indices"),
                            format!(
                                "indices must be SCALAR unsigned byte, short or int \
                                 (componentType 5121, 5123 or 5125), not {kind} {component}"
                            ),
                        ));
                    }
                }
                let targets = array_of(prim.get("targets"));
                let sets = std::iter::once(("attributes".to_string(), prim.get("attributes")))
                    .chain(
                        targets
                            .iter()
                            .enumerate()
                            .map(|(t, v)| (format!("targets[{t}]"), Some(v))),
                    );
                for (set, attributes) in sets {
                    let Some(map) = attributes.and_then(Value::as_object) else {
                        continue;
                    };
                    for (semantic, index) in map {
                        let object = format!("{at}.{set}.{semantic}");
                        self.index(Some(index), "accessors", || object.clone())?;
                        let (component, kind) = self.accessor_kind(index.as_u64().unwrap_or(0));
                        // Morph targets hold displacements: float or normalized, VEC3 for
                        // positions and normals, so only the type is checked there.
                        // A morph target's TANGENT displacement is a VEC3 (no handedness).
                        let rule = match Self::attribute_rule(semantic) {
                            Some(_) if set != "attributes" && semantic == "TANGENT" => {
                                Some((&["VEC3"][..], &[FLOAT][..]))
                            }
                            rule => rule,
                        };
                        if let Some((kinds, components)) = rule
                            && (!kinds.contains(&kind)
                                || (set == "attributes" && !components.contains(&component)))
                        {
                            return Err(self.fail(
                                object,
                                format!(
                                    "{semantic} must be {} with componentType {components:?}, not {kind} {component}",
                                    kinds.join(" or ")
                                ),
                            ));
                        }
                    }
                }
            }
        }
        Ok(())
    }

    fn check_animations(&self) -> Result<()> {
        for (a, anim) in self.array("animations").iter().enumerate() {
            let samplers = array_of(anim.get("samplers"));
            for (s, sampler) in samplers.iter().enumerate() {
                let at = |k: &str| format!("animations[{a}].samplers[{s}].{k}");
                for key in ["input", "output"] {
                    match sampler.get(key) {
                        None => return Err(self.fail(at(key), "is required")),
                        v => self.index(v, "accessors", || at(key))?,
                    }
                }
                // Key times are floats (glTF 2.0, "Animations").
                self.require_kind(sampler.get("input"), at("input"), &["SCALAR"], &[FLOAT])?;
                if let Some(i) = sampler.get("interpolation")
                    && !i.as_str().is_some_and(|i| INTERPOLATIONS.contains(&i))
                {
                    return Err(self.fail(
                        at("interpolation"),
                        format!("{i} is not one of {INTERPOLATIONS:?}"),
                    ));
                }
            }
            for (c, channel) in array_of(anim.get("channels")).iter().enumerate() {
                let at = |k: &str| format!("animations[{a}].channels[{c}].{k}");
                match channel.get("sampler").and_then(Value::as_u64) {
                    Some(i) if (i as usize) < samplers.len() => {}
                    _ => {
                        return Err(self.fail(
                            at("sampler"),
                            format!(
                                "must be an index into the animation's {} samplers",
                                samplers.len()
                            ),
                        ));
                    }
                }
                let target = channel.get("target");
                self.index(target.and_then(|t| t.get("node")), "nodes", || {
                    at("target.node")
                })?;
                let path = target.and_then(|t| t.get("path"));
                if !path
                    .and_then(Value::as_str)
                    .is_some_and(|p| ANIMATION_PATHS.contains(&p))
                {
                    return Err(self.fail(
                        at("target.path"),
                        format!(
                            "{} is not one of {ANIMATION_PATHS:?}",
                            path.map_or("nothing".into(), Value::to_string)
                        ),
                    ));
                }
                // The sampler's output as the path requires (glTF 2.0, "Animations": the
                // accessor types of each path); rotations and weights may be normalized integers.
                const NORMALIZED: [u64; 5] = [FLOAT, 5120, 5121, 5122, 5123];
                let (kinds, components): (&[&str], &[u64]) =
                    match path.and_then(Value::as_str).unwrap_or("") {
                        "rotation" => (&["VEC4"], &NORMALIZED),
                        "weights" => (&["SCALAR"], &NORMALIZED),
                        _ => (&["VEC3"], &[FLOAT]),
                    };
                let sampler = channel["sampler"].as_u64().unwrap_or(0) as usize;
                self.require_kind(
                    samplers[sampler].get("output"),
                    format!("animations[{a}].samplers[{sampler}].output"),
                    kinds,
                    components,
                )?;
            }
        }
        Ok(())
    }
}

fn array_of(v: Option<&Value>) -> &[Value] {
    v.and_then(Value::as_array).map_or(&[], Vec::as_slice)
}
