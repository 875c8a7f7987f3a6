//! The per-frame acceleration update, doing no more than the frame needs. Each mesh node is an
//! object, classified once from the animations that play:
//! - static (nothing above it moves, it does not deform): one world-space tree for all static
//!   objects, built on the first frame and reused;
//! - rigid (it or an ancestor has animated TRS, no skin, no animated weights): an instance, its
//!   object-space tree built once and placed by the node's world matrix each frame;
//! - deforming (skinned with moving joints, or animated morph weights): its own tree, rebuilt on a
//!   frame where its triangles changed, reused where they did not.
//!
//! Every frame logs one row per object (the static ones as one row): action, reason, time.

use crate::accel::instances::{Part, PrimMap, TwoLevel};
use crate::accel::{BuildParams, KdTree};
use crate::scene::Scene;
use crate::scene::animation::{Animation, Property};
use crate::scene::pose::PosedScene;
use glam::Vec3;
use std::sync::Arc;
use std::time::Instant;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Static,
    Rigid,
    Deforming,
}

struct Object {
    node: usize,
    name: String,
    kind: Kind,
    /// Global triangle range of the object in the posed geometry.
    first: u32,
    count: u32,
}

/// One row of the frame log.
pub struct LogRow {
    pub object: String,
    pub action: &'static str,
    pub reason: &'static str,
    pub seconds: f64,
    /// SAH cost of a tree built or rebuilt this frame.
    pub sah_cost: Option<f64>,
}

pub struct Updater {
    params: BuildParams,
    objects: Vec<Object>,
    static_part: Option<Part>,
    /// Per object: its tree (object space for rigid, world space for deforming) and, for
    /// deforming ones, the world triangles it was built over.
    trees: Vec<Option<BuiltTree>>,
    /// Per rigid object: its triangles in object space, taken from the rest pose so that the
    /// instance tree does not depend on which frame a render starts at (a frame rendered alone
    /// must equal the same frame inside a range, bit for bit).
    object_space: Vec<Option<Vec<[Vec3; 3]>>>,
}

type BuiltTree = (Arc<KdTree>, Vec<[Vec3; 3]>);

impl Updater {
    pub fn new(scene: &Scene, animations: &[&Animation], params: BuildParams) -> Updater {
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
            let kind = match node.skin {
                Some(s) if scene.skins[s].joints.iter().any(|&j| moves(j)) => Kind::Deforming,
                _ if weights[n] => Kind::Deforming,
                Some(_) => Kind::Static,
                None if moves(n) => Kind::Rigid,
                None => Kind::Static,
            };
            let name = node.name.clone().unwrap_or_else(|| format!("node {n}"));
            objects.push(Object {
                node: n,
                name,
                kind,
                first,
                count,
            });
            first += count;
        }
        let trees = objects.iter().map(|_| None).collect();
        let rest = crate::scene::pose::pose(scene, &[]);
        let object_space = objects
            .iter()
            .map(|o| {
                (o.kind == Kind::Rigid).then(|| {
                    let inv = rest.node_world[o.node].inverse();
                    (o.first..o.first + o.count)
                        .map(|i| {
                            rest.geometry
                                .triangle(i as usize)
                                .map(|v| inv.transform_point3(v))
                        })
                        .collect()
                })
            })
            .collect();
        Updater {
            params,
            objects,
            static_part: None,
            trees,
            object_space,
        }
    }

    /// Brings the structure up to date with a posed frame.
    pub fn update(&mut self, posed: &PosedScene) -> (TwoLevel, Vec<LogRow>) {
        let g = &posed.geometry;
        let tri = |i: u32| g.triangle(i as usize);
        let mut rows = Vec::new();
        let mut parts = Vec::new();

        let t = Instant::now();
        let statics: Vec<&Object> = self
            .objects
            .iter()
            .filter(|o| o.kind == Kind::Static)
            .collect();
        if !statics.is_empty() {
            let (action, reason) = if self.static_part.is_none() {
                let ids: Vec<u32> = statics
                    .iter()
                    .flat_map(|o| o.first..o.first + o.count)
                    .collect();
                let tris = ids.iter().map(|&i| tri(i)).collect();
                let tree = Arc::new(KdTree::build(tris, self.params));
                self.static_part = Some(Part::world(tree, PrimMap::Table(Arc::new(ids))));
                ("build", "static geometry, built once for the whole range")
            } else {
                ("reuse", "static geometry")
            };
            let part = self.static_part.clone().expect("built above");
            let sah_cost = (action == "build").then(|| part.tree.stats().sah_cost);
            parts.push(part);
            rows.push(LogRow {
                object: "static".into(),
                action,
                reason,
                seconds: t.elapsed().as_secs_f64(),
                sah_cost,
            });
        }

        for ((o, slot), local) in self
            .objects
            .iter()
            .zip(self.trees.iter_mut())
            .zip(&self.object_space)
        {
            if o.kind == Kind::Static {
                continue;
            }
            let t = Instant::now();
            let (action, reason) = match o.kind {
                Kind::Rigid => {
                    let world = posed.node_world[o.node];
                    let reason = if slot.is_none() {
                        let local = local
                            .clone()
                            .expect("rigid objects have object-space triangles");
                        *slot = Some((Arc::new(KdTree::build(local, self.params)), Vec::new()));
                        "rigid motion: object-space tree built once"
                    } else {
                        "rigid motion: transform updated"
                    };
                    let tree = slot.as_ref().expect("built above").0.clone();
                    parts.push(Part::instance(tree, PrimMap::Offset(o.first), world));
                    ("instance", reason)
                }
                _ => {
                    let world_tris: Vec<[Vec3; 3]> =
                        (o.first..o.first + o.count).map(tri).collect();
                    let unchanged = slot.as_ref().is_some_and(|(_, built)| *built == world_tris);
                    let first = slot.is_none();
                    if !unchanged {
                        let tree = Arc::new(KdTree::build(world_tris.clone(), self.params));
                        *slot = Some((tree, world_tris));
                    }
                    let tree = slot.as_ref().expect("built above").0.clone();
                    parts.push(Part::world(tree, PrimMap::Offset(o.first)));
                    match (first, unchanged) {
                        (true, _) => ("build", "deforming mesh (skin or morph weights)"),
                        (false, true) => ("reuse", "deforming mesh did not change this frame"),
                        (false, false) => {
                            ("rebuild", "deforming mesh changed (refit not implemented)")
                        }
                    }
                }
            };
            let seconds = t.elapsed().as_secs_f64();
            let built = reason.contains("built once") || action == "build" || action == "rebuild";
            let sah_cost = built.then(|| {
                parts
                    .last()
                    .expect("a part was pushed")
                    .tree
                    .stats()
                    .sah_cost
            });
            rows.push(LogRow {
                object: o.name.clone(),
                action,
                reason,
                seconds,
                sah_cost,
            });
        }
        (TwoLevel { parts }, rows)
    }
}
