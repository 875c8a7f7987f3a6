//! The per-frame acceleration update, doing no more than the frame needs. Each mesh node is an
//! object, classified once by `scene::motion`:
//! - static: one world-space tree for all static objects, built on the first frame and reused;
//! - rigid: an instance, its object-space tree built once and placed by the node's world matrix
//!   each frame;
//! - deforming: reused on a frame where its triangles did not change; otherwise, by
//!   `[accel] update`: `rebuild` (a fresh kd-tree every frame, the fastest to trace), `refit` (a
//!   bounded kd-tree, `bounded.rs`, built once with each triangle in one leaf and its boxes
//!   refitted every frame), or `auto`: a mesh that the frame samples many times per triangle
//!   (`REBUILD_SAMPLES_PER_TRIANGLE`) is rebuilt as a kd-tree, since the faster trace repays the
//!   build; any other is the bounded tree refitted, rebuilt once the refitted SAH cost exceeds
//!   `auto_threshold` times the cost it had when built. Both rules read counts and SAH costs, not
//!   measured times, so the same pipeline makes the same choices, and the same images, on every
//!   run and machine.
//!
//! Every frame logs one row per object (the static ones as one row): action, reason, time. The
//! update reads the posed frame's triangles and node matrices, nothing else of the scene.

use super::instances::{Part, PrimMap, TwoLevel};
use super::params::BuildParams;
use super::refit::RefitTree;
use super::tree::KdTree;
use crate::scene::Scene;
use crate::scene::animation::Animation;
use crate::scene::motion::{self, Motion, SceneObject};
use crate::scene::pose::{self, PosedScene};
use glam::Vec3;
use serde::Deserialize;
use std::fmt;
use std::sync::Arc;
use std::time::Instant;

/// How deforming meshes follow their animation (`[accel] update`).
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "kebab-case")]
pub enum UpdateMode {
    Rebuild,
    Refit,
    #[default]
    Auto,
}

/// Under `auto`, a deforming mesh sampled more than this many times per triangle each frame (camera
/// samples of both eyes) is rebuilt as a kd-tree instead of refitted. Where rebuilding starts to
/// pay, measured with the refitted tree in its walk layout (`box_node.rs`) and walked in four-ray
/// packets (update and tracing per frame, median of frames 1-11, three alternating runs, 2
/// threads): BrainStem (61,666 triangles, 320x240) at about 80 (24 spp, 60 samples per triangle:
/// refit 248-306 ms, rebuild 254-312 ms; 32 spp, 80: refit 318-349 ms, rebuild 326-340 ms);
/// CesiumMan (4,672, 480x360) between 74 (1 spp: refit 25-29 ms, rebuild 34-39 ms) and 1,180 (16
/// spp: rebuild 223-226 ms, refit 239-250 ms), about even at 296 (4 spp). Faster refit walks moved
/// it up: 30 with single-ray walks, 50 with packets over the topology's nodes. Counting only the
/// samples that reach the mesh would not reconcile the two meshes: their boxes cover about the same
/// share of the film (BrainStem 0.17-0.29, CesiumMan 0.16-0.20 over frames 0-11). What differs is a
/// rebuild's cost per triangle (65 ms for BrainStem, 8.5 ms for CesiumMan: 1.1 against 1.8 us) and
/// the refitted tree's trace penalty (1.2-1.27x against 1.07-1.13x).
pub const REBUILD_SAMPLES_PER_TRIANGLE: f64 = 80.0;

/// What the update did to an object this frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Action {
    Build,
    Reuse,
    Instance,
    Refit,
    Rebuild,
}

impl Action {
    pub fn as_str(self) -> &'static str {
        match self {
            Action::Build => "build",
            Action::Reuse => "reuse",
            Action::Instance => "instance",
            Action::Refit => "refit",
            Action::Rebuild => "rebuild",
        }
    }
}

impl fmt::Display for Action {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Why the update did it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reason {
    StaticFirstFrame,
    StaticUnchanged,
    RigidFirstFrame,
    RigidMoved,
    DeformingFirstFrame,
    DeformingUnchanged,
    RefitRequested,
    RebuildRequested,
    AutoWithinThreshold,
    AutoPastThreshold,
    AutoManySamples,
}

impl fmt::Display for Reason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Reason::StaticFirstFrame => "static geometry, built once for the whole range",
            Reason::StaticUnchanged => "static geometry",
            Reason::RigidFirstFrame => "rigid motion: object-space tree built once",
            Reason::RigidMoved => "rigid motion: transform updated",
            Reason::DeformingFirstFrame => "deforming mesh (skin or morph weights): first frame",
            Reason::DeformingUnchanged => "deforming mesh did not change this frame",
            Reason::RefitRequested => "update = refit: bounded tree kept, boxes refitted",
            Reason::RebuildRequested => "update = rebuild: deforming mesh changed",
            Reason::AutoWithinThreshold => {
                "auto: refitted cost within the threshold of the last build"
            }
            Reason::AutoPastThreshold => "auto: refitted cost past the threshold of the last build",
            Reason::AutoManySamples => {
                "auto: many samples per triangle, a fresh kd-tree repays its build"
            }
        })
    }
}

/// One row of the frame log.
#[derive(Clone, Debug)]
pub struct LogRow {
    pub object: String,
    pub action: Action,
    pub reason: Reason,
    pub seconds: f64,
    /// SAH cost of a tree built, rebuilt or refitted this frame.
    pub sah_cost: Option<f64>,
}

/// What the update keeps for one moving object between frames.
enum State {
    /// Object-space triangles (from the rest pose) and, once built, their tree.
    Rigid {
        object_space: Vec<[Vec3; 3]>,
        tree: Option<Arc<KdTree>>,
    },
    /// Nothing before the first frame.
    Deforming(Option<Deforming>),
}

/// A deforming object's bounded-tree topology last built (none under `rebuild`), its SAH cost
/// when built (the baseline `auto` measures drift against), the triangles it was last fitted
/// to, and the part in use.
struct Deforming {
    topology: Option<Arc<KdTree>>,
    baseline: f64,
    triangles: Vec<[Vec3; 3]>,
    part: Part,
}

pub struct Updater {
    params: BuildParams,
    mode: UpdateMode,
    auto_threshold: f64,
    /// Camera samples per frame, when the caller says (see `REBUILD_SAMPLES_PER_TRIANGLE`).
    samples_per_frame: Option<f64>,
    /// Triangle ranges of the static objects, and their shared part once built.
    statics: Vec<SceneObject>,
    static_part: Option<Part>,
    moving: Vec<(SceneObject, State)>,
}

impl Updater {
    pub fn new(
        scene: &Scene,
        animations: &[&Animation],
        params: BuildParams,
        mode: UpdateMode,
        auto_threshold: f32,
    ) -> Updater {
        let objects = motion::classify(scene, animations);
        let rest = objects
            .iter()
            .any(|o| o.motion == Motion::Rigid)
            .then(|| pose::pose(scene, &[]));
        let (statics, moving): (Vec<_>, Vec<_>) = objects
            .into_iter()
            .partition(|o| o.motion == Motion::Static);
        let moving = moving
            .into_iter()
            .map(|o| {
                let state = match (&rest, o.motion) {
                    (Some(rest), Motion::Rigid) => State::Rigid {
                        object_space: motion::object_space_triangles(rest, &o),
                        tree: None,
                    },
                    _ => State::Deforming(None),
                };
                (o, state)
            })
            .collect();
        Updater {
            params,
            mode,
            auto_threshold: auto_threshold as f64,
            samples_per_frame: None,
            statics,
            static_part: None,
            moving,
        }
    }

    /// Tells `auto` how many camera samples each frame takes; without it `auto` always refits.
    pub fn with_samples_per_frame(mut self, samples: u64) -> Updater {
        self.samples_per_frame = Some(samples as f64);
        self
    }

    /// Brings the structure up to date with a posed frame.
    pub fn update(&mut self, posed: &PosedScene) -> (TwoLevel, Vec<LogRow>) {
        let g = &posed.geometry;
        let mut rows = Vec::new();
        let mut parts = Vec::new();

        if !self.statics.is_empty() {
            let t = Instant::now();
            let (action, reason, sah_cost) = if self.static_part.is_none() {
                let ids: Vec<u32> = self
                    .statics
                    .iter()
                    .flat_map(|o| o.triangles.clone())
                    .collect();
                let tris = ids.iter().map(|&i| g.triangle(i as usize)).collect();
                let tree = Arc::new(KdTree::build(tris, self.params));
                let cost = tree.stats().sah_cost;
                self.static_part = Some(Part::world(tree, PrimMap::Table(Arc::new(ids))));
                (Action::Build, Reason::StaticFirstFrame, Some(cost))
            } else {
                (Action::Reuse, Reason::StaticUnchanged, None)
            };
            parts.push(self.static_part.clone().expect("built above"));
            rows.push(LogRow {
                object: "static".into(),
                action,
                reason,
                seconds: t.elapsed().as_secs_f64(),
                sah_cost,
            });
        }

        let policy = Policy {
            params: self.params,
            mode: self.mode,
            threshold: self.auto_threshold,
            samples_per_frame: self.samples_per_frame,
        };
        for (o, state) in &mut self.moving {
            let t = Instant::now();
            let first = o.triangles.start;
            let (part, action, reason, sah_cost) = match state {
                State::Rigid { object_space, tree } => {
                    let (reason, cost) = match tree {
                        Some(_) => (Reason::RigidMoved, None),
                        None => {
                            let built =
                                Arc::new(KdTree::build(object_space.clone(), policy.params));
                            let cost = built.stats().sah_cost;
                            *tree = Some(built);
                            (Reason::RigidFirstFrame, Some(cost))
                        }
                    };
                    let tree = tree.clone().expect("built above");
                    let world = posed.node_world[o.node];
                    let part = Part::instance(tree, PrimMap::Offset(first), world);
                    (part, Action::Instance, reason, cost)
                }
                State::Deforming(slot) => {
                    let tris = o
                        .triangles
                        .clone()
                        .map(|i| g.triangle(i as usize))
                        .collect();
                    policy.deform(slot, tris, first)
                }
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

/// The deforming-mesh policy: `[accel] update` and its threshold.
struct Policy {
    params: BuildParams,
    mode: UpdateMode,
    threshold: f64,
    samples_per_frame: Option<f64>,
}

impl Policy {
    /// One deforming object's update: build, reuse, refit or rebuild (see the module comment).
    /// Returns the part, the action and reason for the log, and the SAH cost of the tree used.
    fn deform(
        &self,
        slot: &mut Option<Deforming>,
        tris: Vec<[Vec3; 3]>,
        first: u32,
    ) -> (Part, Action, Reason, Option<f64>) {
        // A kd-tree rebuilt every frame, or a bounded tree refitted; fixed per object, since
        // neither the triangle count nor the samples change between frames.
        let many_samples = self
            .samples_per_frame
            .is_some_and(|s| s > REBUILD_SAMPLES_PER_TRIANGLE * tris.len() as f64);
        let kd_tree = match self.mode {
            UpdateMode::Rebuild => true,
            UpdateMode::Refit => false,
            UpdateMode::Auto => many_samples,
        };
        let build = |tris: Vec<[Vec3; 3]>| {
            if kd_tree {
                let tree = Arc::new(KdTree::build(tris.clone(), self.params));
                Deforming {
                    topology: None,
                    baseline: tree.stats().sah_cost,
                    triangles: tris,
                    part: Part::world(tree, PrimMap::Offset(first)),
                }
            } else {
                let fitted = Arc::new(RefitTree::build(tris.clone(), self.params));
                Deforming {
                    topology: Some(fitted.topology().clone()),
                    baseline: fitted.sah_cost(),
                    triangles: tris,
                    part: Part::refitted(fitted, PrimMap::Offset(first)),
                }
            }
        };
        let Some(d) = slot.as_mut() else {
            let d = slot.insert(build(tris));
            let cost = d.baseline;
            return (
                d.part.clone(),
                Action::Build,
                Reason::DeformingFirstFrame,
                Some(cost),
            );
        };
        if d.triangles == tris {
            return (
                d.part.clone(),
                Action::Reuse,
                Reason::DeformingUnchanged,
                None,
            );
        }
        if let Some(topology) = &d.topology {
            let refit = Arc::new(RefitTree::refit(topology.clone(), tris.clone()));
            let cost = refit.sah_cost();
            if self.mode == UpdateMode::Refit || cost <= self.threshold * d.baseline {
                d.part = Part::refitted(refit, PrimMap::Offset(first));
                d.triangles = tris;
                let reason = if self.mode == UpdateMode::Refit {
                    Reason::RefitRequested
                } else {
                    Reason::AutoWithinThreshold
                };
                return (d.part.clone(), Action::Refit, reason, Some(cost));
            }
        }
        let reason = match self.mode {
            UpdateMode::Rebuild => Reason::RebuildRequested,
            _ if kd_tree => Reason::AutoManySamples,
            _ => Reason::AutoPastThreshold,
        };
        *d = build(tris);
        let cost = d.baseline;
        (d.part.clone(), Action::Rebuild, reason, Some(cost))
    }
}
