//! `stereotrace info`: what a scene holds, and with `--accel` the kd-tree built over its rest pose.

mod materials;

pub use materials::{MaterialInputs, material_inputs};

use crate::accel::TreeStats;
use crate::accel::{BuildParams, KdTree, SplitMethod};
use crate::error::{Error, Result};
use crate::run::{BYTES_PER_TRIANGLE, Bytes};
use crate::scene::Scene;
use crate::scene::animation::AnimationSummary;
use crate::scene::light::LightKind;
use crate::scene::pose;
use serde::Serialize;
use std::fmt;

#[derive(Debug, Serialize)]
pub struct SceneInfo {
    pub file: String,
    pub nodes: usize,
    pub meshes: usize,
    pub primitives: usize,
    /// Triangles of the posed (flattened) scene: mesh reuse counts once per instance.
    pub triangles: usize,
    pub materials: usize,
    pub textures_decoded: usize,
    /// Each material's inputs and what the renderer does with them.
    pub material_inputs: Vec<MaterialInputs>,
    pub point_lights: usize,
    pub spot_lights: usize,
    pub directional_lights: usize,
    /// Each placed camera as `[scene] camera` takes it: its node or camera name, else its index
    /// into the glTF cameras (with the node it is on).
    pub cameras: Vec<String>,
    pub skins: usize,
    pub morph_targets: usize,
    pub animations: Vec<AnimationSummary>,
    pub warnings: Vec<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub accel: Option<TreeStats>,
}

/// What `scene` holds; with `accel`, the kd-tree built over its rest pose, refused (bad input)
/// when its triangles would need more than `memory_limit`.
pub fn scene_info(
    scene: &Scene,
    accel: Option<SplitMethod>,
    memory_limit: Option<u64>,
) -> Result<SceneInfo> {
    let triangles = scene.placed_triangle_count();
    let count = |f: fn(&LightKind) -> bool| scene.lights.iter().filter(|l| f(&l.kind)).count();
    let accel = match accel {
        Some(m) => {
            let need = (triangles as u64).saturating_mul(BYTES_PER_TRIANGLE);
            if let Some(limit) = memory_limit.filter(|&l| need > l) {
                return Err(Error::input(
                    &scene.source,
                    format!(
                        "building the kd-tree of {triangles} triangles (after instancing) would need about {}, over the limit of {}; raise it with --max-memory",
                        Bytes(need),
                        Bytes(limit)
                    ),
                ));
            }
            let posed = pose::pose(scene, &[]);
            Some(KdTree::build(posed.geometry.triangle_list(), BuildParams::with_method(m)).stats())
        }
        None => None,
    };
    Ok(SceneInfo {
        file: scene.source.display().to_string(),
        nodes: scene.nodes.len(),
        meshes: scene.meshes.len(),
        primitives: scene.meshes.iter().map(|m| m.primitives.len()).sum(),
        triangles,
        materials: scene.materials.len() - 1,
        textures_decoded: scene.textures.len(),
        material_inputs: material_inputs(scene),
        point_lights: count(|k| matches!(k, LightKind::Point)),
        spot_lights: count(|k| matches!(k, LightKind::Spot { .. })),
        directional_lights: count(|k| matches!(k, LightKind::Directional)),
        cameras: scene
            .placed_cameras()
            .into_iter()
            .map(|(node, camera)| {
                scene.camera_label(node, camera).map_or_else(
                    || format!("{camera} (unnamed, on node {node})"),
                    str::to_owned,
                )
            })
            .collect(),
        skins: scene.skins.len(),
        morph_targets: scene
            .meshes
            .iter()
            .flat_map(|m| m.primitives.iter().map(|p| p.morph_targets.len()))
            .max()
            .unwrap_or(0),
        animations: scene.animations.iter().map(|a| a.summary()).collect(),
        warnings: scene.warnings.clone(),
        accel,
    })
}

impl fmt::Display for SceneInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "scene       {}", self.file)?;
        writeln!(f, "nodes       {}", self.nodes)?;
        writeln!(
            f,
            "meshes      {} ({} primitives)",
            self.meshes, self.primitives
        )?;
        writeln!(f, "triangles   {}", self.triangles)?;
        writeln!(
            f,
            "materials   {} ({} textures decoded)",
            self.materials, self.textures_decoded
        )?;
        for m in &self.material_inputs {
            let name = m
                .name
                .as_deref()
                .map_or("(unnamed)".into(), |n| format!("{n:?}"));
            writeln!(f, "  {}: {name}", m.index)?;
            for input in &m.inputs {
                writeln!(f, "      {input}")?;
            }
        }
        writeln!(
            f,
            "lights      {} point, {} spot, {} directional",
            self.point_lights, self.spot_lights, self.directional_lights
        )?;
        if self.point_lights + self.spot_lights + self.directional_lights == 0 {
            writeln!(
                f,
                "            (none: a render lights the scene with a head-light)"
            )?;
        }
        if self.cameras.is_empty() {
            writeln!(
                f,
                "cameras     none (a render frames the scene with a default camera)"
            )?;
        } else {
            writeln!(f, "cameras     {}", self.cameras.join(", "))?;
        }
        writeln!(f, "skins       {}", self.skins)?;
        writeln!(
            f,
            "morph targets {} (the most on one primitive)",
            self.morph_targets
        )?;
        if self.animations.is_empty() {
            writeln!(f, "animations  none")?;
        } else {
            writeln!(
                f,
                "animations  {} (index: name, length, what it animates)",
                self.animations.len()
            )?;
        }
        for (i, a) in self.animations.iter().enumerate() {
            let channels: Vec<String> = [
                (a.translation_channels, "translation"),
                (a.rotation_channels, "rotation"),
                (a.scale_channels, "scale"),
                (a.weight_channels, "morph weight"),
            ]
            .iter()
            .filter(|(n, _)| *n > 0)
            .map(|(n, what)| format!("{n} {what}"))
            .collect();
            writeln!(
                f,
                "  {i}: {} {:.2} s; channels: {}; {}",
                a.name
                    .as_deref()
                    .map_or("(unnamed)".to_string(), |n| format!("{n:?}")),
                a.duration,
                channels.join(", "),
                a.interpolations.join(" ").to_lowercase()
            )?;
        }
        if let Some(s) = &self.accel {
            writeln!(f, "kd-tree")?;
            writeln!(
                f,
                "  nodes {} ({} leaves, {} empty)",
                s.nodes, s.leaves, s.empty_leaves
            )?;
            writeln!(
                f,
                "  depth max {} mean {:.1}",
                s.max_depth, s.mean_leaf_depth
            )?;
            writeln!(
                f,
                "  refs/triangle {:.2}, triangles/leaf {:.2}",
                s.references_per_triangle, s.triangles_per_nonempty_leaf
            )?;
            writeln!(
                f,
                "  SAH cost {:.1}, {} bytes, built in {:.3} s",
                s.sah_cost, s.bytes, s.build_seconds
            )?;
        }
        Ok(())
    }
}
