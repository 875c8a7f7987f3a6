//! `scene/` turns a glTF 2.0 file into a [`Scene`]: nodes, meshes, materials, lights, cameras and
//! what is animated. It is the only module that knows glTF. It never sees a ray, a kd-tree or an
//! output file; [`pose`] turns a scene into world-space geometry for one frame.

pub mod animation;
mod buffers;
mod camera;
mod document;
pub mod light;
pub mod material;
mod mesh;
pub mod motion;
pub mod pose;
pub mod texture;

pub use animation::{Animation, overlapping_animations};
pub use camera::{CameraDef, distance_to_bounds, framing_camera};
pub use light::{Light, LightKind};
pub use mesh::{Mesh, MorphTarget, Primitive};
pub use pose::PosedScene;

use crate::error::{Error, Result};
use glam::{Mat4, Quat, Vec3};
use light::LightDef;
use material::Material;
use std::path::{Path, PathBuf};
use texture::Texture;

/// Extensions whose meaning stereotrace renders (or, for the lights, reads).
const SUPPORTED_EXTENSIONS: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_transmission",
    "KHR_materials_ior",
    "KHR_materials_emissive_strength",
    "KHR_texture_transform",
];

/// A node's local transform as stored: animation targets TRS, a matrix stays a matrix.
#[derive(Clone, Copy, Debug)]
pub enum Transform {
    Matrix(Mat4),
    Trs {
        translation: Vec3,
        rotation: Quat,
        scale: Vec3,
    },
}

impl Transform {
    pub fn matrix(&self) -> Mat4 {
        match *self {
            Transform::Matrix(m) => m,
            Transform::Trs {
                translation,
                rotation,
                scale,
            } => Mat4::from_scale_rotation_translation(scale, rotation, translation),
        }
    }
}

#[derive(Clone, Debug)]
pub struct Node {
    pub name: Option<String>,
    pub transform: Transform,
    pub children: Vec<usize>,
    pub mesh: Option<usize>,
    pub camera: Option<usize>,
    pub light: Option<usize>,
    pub skin: Option<usize>,
    /// `node.weights`: morph weights overriding the mesh's.
    pub weights: Option<Vec<f32>>,
}

/// A skin: its joint nodes and their inverse bind matrices.
#[derive(Clone, Debug)]
pub struct Skin {
    pub joints: Vec<usize>,
    pub inverse_bind: Vec<Mat4>,
}

fn load_skin(path: &Path, buffers: &[Vec<u8>], sk: &gltf::Skin, node_count: usize) -> Result<Skin> {
    let object = format!("skins[{}]", sk.index());
    let joints: Vec<usize> = sk.joints().map(|j| j.index()).collect();
    let inverse_bind = match sk.inverse_bind_matrices() {
        Some(acc) => {
            buffers::check_accessor(
                path,
                buffers,
                &acc,
                &format!("{object}.inverseBindMatrices"),
            )?;
            let reader = sk.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
            let m: Vec<Mat4> = reader
                .read_inverse_bind_matrices()
                .ok_or_else(|| Error::scene(path, &object, "inverseBindMatrices cannot be read"))?
                .map(|a| Mat4::from_cols_array_2d(&a))
                .collect();
            if m.len() != joints.len() || m.iter().any(|x| !x.is_finite()) {
                return Err(Error::scene(
                    path,
                    &object,
                    "inverseBindMatrices must hold one finite matrix per joint",
                ));
            }
            m
        }
        None => vec![Mat4::IDENTITY; joints.len()],
    };
    if joints.iter().any(|&j| j >= node_count) {
        return Err(Error::scene(path, &object, "a joint is not a node"));
    }
    Ok(Skin {
        joints,
        inverse_bind,
    })
}

#[derive(Clone, Debug)]
pub struct Scene {
    pub source: PathBuf,
    /// Every file the scene is made of: `source`, then the buffers and images its URIs name
    /// (what a render farm's fingerprint hashes).
    pub files: Vec<PathBuf>,
    pub nodes: Vec<Node>,
    /// Root nodes of the rendered glTF scene.
    pub roots: Vec<usize>,
    pub meshes: Vec<Mesh>,
    /// The document's materials followed by the glTF default material.
    pub materials: Vec<Material>,
    /// Decoded textures: each glTF texture some material samples, once per transfer function
    /// it is sampled with (`TextureRef::texture` indexes this).
    pub textures: Vec<Texture>,
    pub lights: Vec<LightDef>,
    pub cameras: Vec<CameraDef>,
    pub animations: Vec<Animation>,
    pub skins: Vec<Skin>,
    /// Things the loader skipped or approximated; the command line prints them.
    pub warnings: Vec<String>,
}

/// Every joint a skinned mesh's vertices weigh (JOINTS_n with a non-zero weight) is one of the
/// skin's joints: an index past them would leave the vertex unplaced.
fn check_skinned_joints(scene: &Scene) -> Result<()> {
    for (n, node) in scene.nodes.iter().enumerate() {
        let (Some(mesh), Some(skin)) = (node.mesh, node.skin) else {
            continue;
        };
        let count = scene.skins[skin].joints.len();
        for (p, prim) in scene.meshes[mesh].primitives.iter().enumerate() {
            for (set, (joints, weights)) in prim.skin_sets.iter().enumerate() {
                let bad = joints
                    .iter()
                    .zip(weights)
                    .enumerate()
                    .find_map(|(v, (j, w))| {
                        (0..4)
                            .find(|&k| w[k] != 0.0 && j[k] as usize >= count)
                            .map(|k| (v, j[k]))
                    });
                if let Some((v, joint)) = bad {
                    return Err(Error::scene(
                        &scene.source,
                        format!("meshes[{mesh}].primitives[{p}].attributes.JOINTS_{set}"),
                        format!(
                            "vertex {v} weighs joint {joint}, but nodes[{n}] is skinned by \
                             skins[{skin}], which has {count} joints"
                        ),
                    ));
                }
            }
        }
    }
    Ok(())
}

/// The scene file and the files its buffer and image URIs name (`data:` URIs are inside it).
fn scene_files(path: &Path, document: &gltf::Document) -> Result<Vec<PathBuf>> {
    let buffers = document.buffers().filter_map(|b| match b.source() {
        gltf::buffer::Source::Uri(uri) => Some((format!("buffers[{}]", b.index()), uri)),
        gltf::buffer::Source::Bin => None,
    });
    let images = document.images().filter_map(|i| match i.source() {
        gltf::image::Source::Uri { uri, .. } => Some((format!("images[{}]", i.index()), uri)),
        gltf::image::Source::View { .. } => None,
    });
    let mut files = vec![path.to_path_buf()];
    for (object, uri) in buffers.chain(images) {
        if !uri.starts_with("data:") {
            files.push(buffers::resolve_relative(path, &object, uri)?);
        }
    }
    Ok(files)
}

impl Scene {
    /// The name `[scene] camera` can choose a placed camera by: its node's name, else its
    /// camera's name.
    pub fn camera_name(&self, camera: &pose::PosedCamera) -> Option<&str> {
        self.camera_label(camera.node, camera.camera)
    }

    /// `camera_name` of camera `camera` placed on node `node`.
    pub fn camera_label(&self, node: usize, camera: usize) -> Option<&str> {
        self.nodes[node]
            .name
            .as_deref()
            .or(self.cameras[camera].name.as_deref())
    }

    /// Cameras as the scene places them, `(node, camera)` in traversal order, without posing.
    pub fn placed_cameras(&self) -> Vec<(usize, usize)> {
        self.traversal()
            .into_iter()
            .filter_map(|n| self.nodes[n].camera.map(|c| (n, c)))
            .collect()
    }

    /// Loads a `.gltf` or `.glb` file and everything it references.
    pub fn load(path: &Path) -> Result<Scene> {
        let bytes = crate::paths::read_regular(path)?;
        // Before the glTF crate, which panics on some invalid documents.
        document::check(path, &bytes)?;
        let gltf = gltf::Gltf::from_slice(&bytes).map_err(|e| gltf_error(path, e))?;
        for ext in gltf.document.extensions_required() {
            if !SUPPORTED_EXTENSIONS.contains(&ext) {
                return Err(Error::scene(
                    path,
                    "extensionsRequired",
                    format!("requires extension {ext}, which stereotrace does not support"),
                ));
            }
        }
        let mut warnings = Vec::new();
        let unsupported: Vec<&str> = gltf
            .document
            .extensions_used()
            .filter(|e| !SUPPORTED_EXTENSIONS.contains(e))
            .collect();
        if !unsupported.is_empty() {
            warnings.push(format!(
                "{}: extensions ignored: {}",
                path.display(),
                unsupported.join(", ")
            ));
        }
        let buffers = buffers::load_buffers(path, &gltf.document, gltf.blob.as_deref())?;
        let document = &gltf.document;
        let (materials, textures) =
            material::load_materials(path, document, &buffers, &mut warnings)?;
        let meshes = document
            .meshes()
            .map(|m| mesh::load_mesh(path, &buffers, &m, &materials, &mut warnings))
            .collect::<Result<Vec<_>>>()?;
        let nodes: Vec<Node> = document.nodes().map(load_node).collect();
        let nodes_len = nodes.len();
        let roots = scene_roots(path, document)?;
        check_hierarchy(path, &nodes, &roots)?;
        let lights = document
            .lights()
            .map(|ls| ls.map(|l| load_light(path, l)).collect::<Result<Vec<_>>>())
            .transpose()?
            .unwrap_or_default();
        let mut cameras = Vec::new();
        for c in document.cameras() {
            match c.projection() {
                gltf::camera::Projection::Perspective(p) => cameras.push(CameraDef {
                    name: c.name().map(str::to_owned),
                    yfov: p.yfov(),
                    aspect_ratio: p.aspect_ratio(),
                    znear: p.znear(),
                    zfar: p.zfar(),
                }),
                gltf::camera::Projection::Orthographic(_) => {
                    warnings.push(format!(
                        "{}: cameras[{}] is orthographic, which stereo rigs do not support; it is treated as a 45-degree perspective camera if selected",
                        path.display(),
                        c.index()
                    ));
                    cameras.push(CameraDef {
                        name: c.name().map(str::to_owned),
                        yfov: std::f32::consts::FRAC_PI_4,
                        aspect_ratio: None,
                        znear: 0.01,
                        zfar: None,
                    });
                }
            }
        }
        if let Some(bad) = cameras
            .iter()
            .position(|c| !(c.yfov > 0.0 && c.yfov < std::f32::consts::PI && c.znear > 0.0))
        {
            return Err(Error::scene(
                path,
                format!("cameras[{bad}].perspective"),
                "yfov must be in (0, pi) and znear > 0",
            ));
        }
        let scene = Scene {
            source: path.to_path_buf(),
            files: scene_files(path, document)?,
            nodes,
            roots,
            meshes,
            materials,
            textures,
            lights,
            cameras,
            animations: document
                .animations()
                .map(|a| animation::load_animation(path, &buffers, &a))
                .collect::<Result<_>>()?,
            skins: document
                .skins()
                .map(|sk| load_skin(path, &buffers, &sk, nodes_len))
                .collect::<Result<_>>()?,
            warnings,
        };
        check_skinned_joints(&scene)?;
        Ok(scene)
    }

    /// The scene at time `t` (seconds) under `animations` (none: the rest pose).
    pub fn pose_at(&self, animations: &[&Animation], t: f32) -> PosedScene {
        let overrides = if animations.is_empty() {
            Vec::new()
        } else {
            animation::sample(animations, self.nodes.len(), t)
        };
        pose::pose(self, &overrides)
    }

    /// Triangles of the posed scene, counted without posing it: a mesh counts once per node
    /// that places it (a small file can place one big mesh thousands of times).
    pub fn placed_triangle_count(&self) -> usize {
        self.traversal()
            .into_iter()
            .filter_map(|n| self.nodes[n].mesh)
            .map(|m| self.meshes[m].triangle_count())
            .sum()
    }

    /// Node indices in depth-first order from the roots (each node once).
    pub fn traversal(&self) -> Vec<usize> {
        let mut order = Vec::new();
        let mut stack: Vec<usize> = self.roots.iter().rev().copied().collect();
        while let Some(n) = stack.pop() {
            order.push(n);
            stack.extend(self.nodes[n].children.iter().rev());
        }
        order
    }
}

fn load_node(n: gltf::Node) -> Node {
    let transform = match n.transform() {
        gltf::scene::Transform::Matrix { matrix } => {
            Transform::Matrix(Mat4::from_cols_array_2d(&matrix))
        }
        gltf::scene::Transform::Decomposed {
            translation,
            rotation,
            scale,
        } => Transform::Trs {
            translation: Vec3::from(translation),
            // DESIGN.md: every quaternion is normalized before use.
            rotation: Quat::from_array(rotation).normalize(),
            scale: Vec3::from(scale),
        },
    };
    Node {
        name: n.name().map(str::to_owned),
        transform,
        children: n.children().map(|c| c.index()).collect(),
        mesh: n.mesh().map(|m| m.index()),
        camera: n.camera().map(|c| c.index()),
        light: n.light().map(|l| l.index()),
        skin: n.skin().map(|s| s.index()),
        weights: n.weights().map(<[f32]>::to_vec),
    }
}

/// A light, its values checked against KHR_lights_punctual's schema (colour in [0, 1],
/// intensity >= 0, range > 0), so that no light gives infinite, NaN or negative radiance.
fn load_light(path: &Path, l: gltf::khr_lights_punctual::Light) -> Result<LightDef> {
    use gltf::khr_lights_punctual::Kind;
    let object = |key: &str| format!("extensions.KHR_lights_punctual.lights[{}].{key}", l.index());
    let color = Vec3::from(l.color());
    if !(color.cmpge(Vec3::ZERO).all() && color.cmple(Vec3::ONE).all()) {
        return Err(Error::scene(
            path,
            object("color"),
            format!("must be three numbers in [0, 1], got {color:?}"),
        ));
    }
    let intensity = l.intensity();
    if !(intensity >= 0.0 && (color * intensity).is_finite()) {
        return Err(Error::scene(
            path,
            object("intensity"),
            format!("must be a finite number >= 0, got {intensity}"),
        ));
    }
    if let Some(r) = l.range()
        && !(r.is_finite() && r > 0.0)
    {
        return Err(Error::scene(
            path,
            object("range"),
            format!("must be a finite number > 0, got {r}"),
        ));
    }
    let kind = match l.kind() {
        Kind::Point => LightKind::Point,
        Kind::Directional => LightKind::Directional,
        Kind::Spot {
            inner_cone_angle,
            outer_cone_angle,
        } => LightKind::Spot {
            inner_cone: inner_cone_angle,
            outer_cone: outer_cone_angle,
        },
    };
    Ok(LightDef {
        name: l.name().map(str::to_owned),
        kind,
        color,
        intensity,
        range: l.range(),
    })
}

/// The nodes to render: the default scene, else the first scene, else every parentless node.
fn scene_roots(path: &Path, document: &gltf::Document) -> Result<Vec<usize>> {
    if let Some(s) = document
        .default_scene()
        .or_else(|| document.scenes().next())
    {
        return Ok(s.nodes().map(|n| n.index()).collect());
    }
    let mut has_parent = vec![false; document.nodes().len()];
    for n in document.nodes() {
        for c in n.children() {
            has_parent[c.index()] = true;
        }
    }
    let roots: Vec<usize> = (0..has_parent.len()).filter(|&i| !has_parent[i]).collect();
    if roots.is_empty() && !has_parent.is_empty() {
        return Err(Error::scene(
            path,
            "nodes",
            "every node has a parent: the hierarchy is a cycle",
        ));
    }
    Ok(roots)
}

/// glTF requires the node hierarchy to be a forest; a file that breaks that would loop forever.
fn check_hierarchy(path: &Path, nodes: &[Node], roots: &[usize]) -> Result<()> {
    let mut seen = vec![false; nodes.len()];
    let mut stack: Vec<usize> = roots.to_vec();
    while let Some(n) = stack.pop() {
        if std::mem::replace(&mut seen[n], true) {
            return Err(Error::scene(
                path,
                format!("nodes[{n}]"),
                "is reached twice from the scene's roots: the node hierarchy must be a tree",
            ));
        }
        stack.extend(&nodes[n].children);
    }
    Ok(())
}

fn gltf_error(path: &Path, e: gltf::Error) -> Error {
    match e {
        gltf::Error::Validation(list) => {
            let parts: Vec<String> = list
                .iter()
                .take(5)
                .map(|(p, err)| format!("{}: {err}", p.as_str()))
                .collect();
            Error::scene(path, "", format!("invalid glTF: {}", parts.join("; ")))
        }
        other => Error::scene(path, "", format!("not a readable glTF file: {other}")),
    }
}
