//! `stereotrace info`: what a scene holds, and with `--accel` the kd-tree built over its rest pose.

use crate::accel::TreeStats;
use crate::accel::{BuildParams, KdTree, SplitMethod};
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
    pub point_lights: usize,
    pub spot_lights: usize,
    pub directional_lights: usize,
    pub cameras: Vec<String>,
    pub skins: usize,
    pub morph_targets: usize,
    pub animations: Vec<AnimationSummary>,
    pub warnings: Vec<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub accel: Option<TreeStats>,
}

pub fn scene_info(scene: &Scene, accel: Option<SplitMethod>) -> SceneInfo {
    let posed = pose::pose(scene, &[]);
    let count = |f: fn(&LightKind) -> bool| scene.lights.iter().filter(|l| f(&l.kind)).count();
    let accel = accel.map(|m| {
        KdTree::build(posed.geometry.triangle_list(), BuildParams::with_method(m)).stats()
    });
    SceneInfo {
        file: scene.source.display().to_string(),
        nodes: scene.nodes.len(),
        meshes: scene.meshes.len(),
        primitives: scene.meshes.iter().map(|m| m.primitives.len()).sum(),
        triangles: posed.geometry.triangles.len(),
        materials: scene.materials.len() - 1,
        textures_decoded: scene.textures.iter().filter(|t| t.is_some()).count(),
        point_lights: count(|k| matches!(k, LightKind::Point)),
        spot_lights: count(|k| matches!(k, LightKind::Spot { .. })),
        directional_lights: count(|k| matches!(k, LightKind::Directional)),
        cameras: posed
            .cameras
            .iter()
            .map(|c| {
                scene.nodes[c.node]
                    .name
                    .clone()
                    .or_else(|| scene.cameras[c.camera].name.clone())
                    .unwrap_or_else(|| format!("node {}", c.node))
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
    }
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
        writeln!(
            f,
            "lights      {} point, {} spot, {} directional",
            self.point_lights, self.spot_lights, self.directional_lights
        )?;
        writeln!(f, "cameras     {} {:?}", self.cameras.len(), self.cameras)?;
        writeln!(f, "skins       {}", self.skins)?;
        writeln!(
            f,
            "morph targets (max per primitive) {}",
            self.morph_targets
        )?;
        writeln!(f, "animations  {}", self.animations.len())?;
        for a in &self.animations {
            writeln!(
                f,
                "  {:<20} T{} R{} S{} W{} {:?} {:.2}s",
                a.name.as_deref().unwrap_or("(unnamed)"),
                a.translation_channels,
                a.rotation_channels,
                a.scale_channels,
                a.weight_channels,
                a.interpolations,
                a.duration
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
