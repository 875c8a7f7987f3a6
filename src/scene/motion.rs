//! How each mesh node moves under the animations that play, decided once for a render: static
//! (nothing above it moves and it does not deform), rigid (it or an ancestor has animated TRS, no
//! skin with moving joints, no animated weights) or deforming (a skin whose joints move, or
//! animated morph weights). The acceleration update keeps one kind of structure per class.

use super::Scene;
use super::animation::{Animation, Property};
use super::pose::PosedScene;
use glam::Vec3;
use std::ops::Range;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Motion {
    Static,
    Rigid,
    Deforming,
}

/// A mesh node and where its triangles sit in every posed frame's geometry.
#[derive(Clone, Debug)]
pub struct SceneObject {
    pub node: usize,
    /// The node's name, or `node N`.
    pub name: String,
    pub motion: Motion,
    /// Global triangle range in the posed geometry (the same on every frame).
    pub triangles: Range<u32>,
}

/// Every mesh node in scene traversal order (the order `pose` appends their triangles), classified.
pub fn classify(scene: &Scene, animations: &[&Animation]) -> Vec<SceneObject> {
    let mut parent = vec![None; scene.nodes.len()];
    for (i, n) in scene.nodes.iter().enumerate() {
        for &c in &n.children {
            parent[c] = Some(i);
        }
    }
    let mut trs = vec![false; scene.nodes.len()];
    let mut weights = vec![false; scene.nodes.len()];
    for c in animations.iter().flat_map(|a| &a.channels) {
        match c.property {
            Property::Weights => weights[c.node] = true,
            _ => trs[c.node] = true,
        }
    }
    let moves = |mut n: usize| loop {
        if trs[n] {
            return true;
        }
        match parent[n] {
            Some(p) => n = p,
            None => return false,
        }
    };
    let mut objects = Vec::new();
    let mut first = 0u32;
    for n in scene.traversal() {
        let node = &scene.nodes[n];
        let Some(mesh) = node.mesh else { continue };
        let count = scene.meshes[mesh].triangle_count() as u32;
        let motion = match node.skin {
            Some(s) if scene.skins[s].joints.iter().any(|&j| moves(j)) => Motion::Deforming,
            _ if weights[n] => Motion::Deforming,
            Some(_) => Motion::Static,
            None if moves(n) => Motion::Rigid,
            None => Motion::Static,
        };
        objects.push(SceneObject {
            node: n,
            name: node.name.clone().unwrap_or_else(|| format!("node {n}")),
            motion,
            triangles: first..first + count,
        });
        first += count;
    }
    objects
}

/// A rigid object's triangles in its node's own space, taken from the rest pose so that they do
/// not depend on which frame a render starts at (a frame rendered alone must equal the same
/// frame inside a range, bit for bit). `rest` is `pose(scene, &[])`.
pub fn object_space_triangles(rest: &PosedScene, object: &SceneObject) -> Vec<[Vec3; 3]> {
    let inv = rest.node_world[object.node].inverse();
    object
        .triangles
        .clone()
        .map(|i| {
            rest.geometry
                .triangle(i as usize)
                .map(|v| inv.transform_point3(v))
        })
        .collect()
}
