//! The per-frame acceleration update, doing no more than the frame needs. Each mesh node is an
//! object, classified once from the animations that play:
//! - static (nothing above it moves, it does not deform): one world-space tree for all static
//!   objects, built on the first frame and reused;
//! - rigid (it or an ancestor has animated TRS, no skin, no animated weights): an instance, its
//!   object-space tree built once and placed by the node's world matrix each frame;
//! - deforming (skinned with moving joints, or animated morph weights): its own tree, reused on a
//!   frame where its triangles did not change; otherwise, by `[accel] update`: `rebuild`, `refit`
//!   (the topology kept, bounded-kd-tree planes refitted), or `auto` (refit, and rebuild once the
//!   refitted SAH cost exceeds `auto_threshold` times the last fresh build's cost). Refitted
//!   planes bound whole triangles where the perfect-split build referenced clipped pieces, so a
//!   refit costs tree quality at once, not only as the mesh drifts; `auto` measures exactly that.
//!
//! Every frame logs one row per object (the static ones as one row): action, reason, time.

use super::UpdateMode;
use crate::accel::instances::{Part, PrimMap, TwoLevel};
use crate::accel::refit::RefitTree;
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
#[derive(Clone, Debug)]
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
    mode: UpdateMode,
    auto_threshold: f64,
    /// Per deforming object: the topology last built, its fresh SAH cost (the baseline `auto`
    /// measures drift against), and the part in use.
    deforming: Vec<Option<Deforming>>,
    objects: Vec<Object>,
    static_part: Option<Part>,
    /// Per rigid object: its object-space tree.
    trees: Vec<Option<Arc<KdTree>>>,
    /// Per rigid object: its triangles in object space, taken from the rest pose so that the
    /// instance tree does not depend on which frame a render starts at (a frame rendered alone
    /// must equal the same frame inside a range, bit for bit).
    object_space: Vec<Option<Vec<[Vec3; 3]>>>,
}

struct Deforming {
    topology: Arc<KdTree>,
    baseline: f64,
    triangles: Vec<[Vec3; 3]>,
    part: Part,
}

impl Updater {
    pub fn new(
        scene: &Scene,
        animations: &[&Animation],
        params: BuildParams,
        mode: UpdateMode,
        auto_threshold: f32,
    ) -> Updater {
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
        let deforming = objects.iter().map(|_| None).collect();
        Updater {
            params,
            mode,
            auto_threshold: auto_threshold as f64,
            deforming,
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
            let (action, reason, sah_cost) = if self.static_part.is_none() {
                let ids: Vec<u32> = statics
                    .iter()
                    .flat_map(|o| o.first..o.first + o.count)
                    .collect();
                let tris = ids.iter().map(|&i| tri(i)).collect();
                let tree = Arc::new(KdTree::build(tris, self.params));
                let cost = tree.stats().sah_cost;
                self.static_part = Some(Part::world(tree, PrimMap::Table(Arc::new(ids))));
                (
                    "build",
                    "static geometry, built once for the whole range",
                    Some(cost),
                )
            } else {
                ("reuse", "static geometry", None)
            };
            let part = self.static_part.clone().expect("built above");
            parts.push(part);
            rows.push(LogRow {
                object: "static".into(),
                action,
                reason,
                seconds: t.elapsed().as_secs_f64(),
                sah_cost,
            });
        }

        let (params, mode, threshold) = (self.params, self.mode, self.auto_threshold);
        for (((o, slot), local), deforming) in self
            .objects
            .iter()
            .zip(self.trees.iter_mut())
            .zip(&self.object_space)
            .zip(self.deforming.iter_mut())
        {
            if o.kind == Kind::Static {
                continue;
            }
            let t = Instant::now();
            let (part, action, reason, sah_cost) = if o.kind == Kind::Rigid {
                let world = posed.node_world[o.node];
                let (reason, cost) = if slot.is_none() {
                    let local = local
                        .clone()
                        .expect("rigid objects have object-space triangles");
                    let tree = Arc::new(KdTree::build(local, params));
                    let cost = tree.stats().sah_cost;
                    *slot = Some(tree);
                    ("rigid motion: object-space tree built once", Some(cost))
                } else {
                    ("rigid motion: transform updated", None)
                };
                let tree = slot.clone().expect("built above");
                (
                    Part::instance(tree, PrimMap::Offset(o.first), world),
                    "instance",
                    reason,
                    cost,
                )
            } else {
                let tris: Vec<[Vec3; 3]> = (o.first..o.first + o.count).map(tri).collect();
                deform(deforming, tris, o.first, params, mode, threshold)
            };
            parts.push(part);
            rows.push(LogRow {
                object: o.name.clone(),
                action,
                reason,
                seconds: t.elapsed().as_secs_f64(),
                sah_cost,
            });
        }
        (TwoLevel { parts }, rows)
    }
}

/// One deforming object's update: build, reuse, refit or rebuild (see the module comment).
/// Returns the part, the action and reason for the log, and the SAH cost of the tree used.
fn deform(
    slot: &mut Option<Deforming>,
    tris: Vec<[Vec3; 3]>,
    first: u32,
    params: BuildParams,
    mode: UpdateMode,
    threshold: f64,
) -> (Part, &'static str, &'static str, Option<f64>) {
    let build = |tris: Vec<[Vec3; 3]>| {
        let topology = Arc::new(KdTree::build(tris.clone(), params));
        let baseline = topology.stats().sah_cost;
        let part = Part::world(topology.clone(), PrimMap::Offset(first));
        Deforming {
            topology,
            baseline,
            triangles: tris,
            part,
        }
    };
    let Some(d) = slot.as_mut() else {
        let d = build(tris);
        let cost = d.baseline;
        let part = d.part.clone();
        *slot = Some(d);
        return (
            part,
            "build",
            "deforming mesh (skin or morph weights): first frame",
            Some(cost),
        );
    };
    if d.triangles == tris {
        return (
            d.part.clone(),
            "reuse",
            "deforming mesh did not change this frame",
            None,
        );
    }
    if mode != UpdateMode::Rebuild {
        let refit = Arc::new(RefitTree::refit(d.topology.clone(), tris.clone()));
        let cost = refit.sah_cost();
        if mode == UpdateMode::Refit || cost <= threshold * d.baseline {
            d.part = Part::refitted(refit, PrimMap::Offset(first));
            d.triangles = tris;
            let reason = if mode == UpdateMode::Refit {
                "update = refit: topology kept, bounds refitted"
            } else {
                "auto: refitted cost within the threshold of the last fresh build"
            };
            return (d.part.clone(), "refit", reason, Some(cost));
        }
    }
    let reason = if mode == UpdateMode::Rebuild {
        "update = rebuild: deforming mesh changed"
    } else {
        "auto: refitted cost past the threshold of the last fresh build"
    };
    *d = build(tris);
    let cost = d.baseline;
    (d.part.clone(), "rebuild", reason, Some(cost))
}
