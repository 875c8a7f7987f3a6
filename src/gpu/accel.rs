//! A frame's acceleration structure on the GPU, part for part the CPU's (`accel::TwoLevel`):
//! every part's tree in shared arrays (8-byte nodes, leaf references, triangles, and the child
//! boxes of refitted trees) and a table of parts that `parts.wgsl` walks in the CPU's order.
//!
//! A frame writes only what changed: for an instance that moved, its row of the table; for a
//! refitted mesh, its boxes and triangles; for a rebuilt one, its tree, in place when it fits
//! the room it had. The first frame, a part added or removed, or a tree outgrowing its room
//! lays all the arrays out again, giving a quarter more room to every part rebuilt since the
//! last layout (the one that outgrew its room among them).
//!
//! Triangles: world parts' triangles sit at their global index (the first `triangle_count`
//! entries), so their leaf references are global indices; instances' object-space triangles
//! follow. A hit's global index is its entry less the part's first entry plus the part's offset
//! (`PrimMap::Offset`), which for a world part is the entry itself.

use super::device::Gpu;
use super::split_array::SplitArray;
use crate::accel::{Aabb, KdTree, Part, PartTree, PrimMap, RefitTree, TwoLevel};
use crate::error::Result;
use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec3};
use std::ops::Range;
use std::sync::Arc;

/// `Part.kind` bits in `parts.wgsl`.
const PART_INSTANCE: u32 = 1;
const PART_BOXES: u32 = 2;

/// A row of the part table (`Part` in `parts.wgsl`, 144 bytes).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct GpuPart {
    world_to_object: [[f32; 4]; 4],
    world_min: [f32; 3],
    kind: u32,
    world_max: [f32; 3],
    node_base: u32,
    tree_min: [f32; 3],
    ref_base: u32,
    tree_max: [f32; 3],
    box_base: u32,
    tri_base: u32,
    prim_offset: u32,
    pad: [u32; 2],
}

/// What the GPU was sent so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Uploads {
    /// Times the arrays were laid out from scratch.
    pub layouts: usize,
    /// Trees written (each part's tree at a layout, and every rebuilt tree).
    pub trees: usize,
    /// Refitted trees' boxes and triangles written in place.
    pub refits: usize,
    /// Bytes written, tables of parts included.
    pub bytes: u64,
}

impl std::fmt::Display for Uploads {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "sent {:.2} MiB: trees laid out {} time(s), {} tree(s) written, {} refit(s) written",
            self.bytes as f64 / 1048576.0,
            self.layouts,
            self.trees,
            self.refits
        )
    }
}

/// Where one part's arrays sit (its room in each), and the tree written there.
struct Slot {
    tree: Option<PartTree>,
    nodes: Range<usize>,
    refs: Range<usize>,
    boxes: Range<usize>,
    /// An instance's object-space triangles; empty for a world part.
    tris: Range<usize>,
    instance: bool,
    /// Rebuilt since the last layout: the next layout gives it room to grow.
    rebuilt: bool,
}

/// A part's tree, borrowed.
#[derive(Clone, Copy)]
enum TreeView<'a> {
    Kd(&'a KdTree),
    Refit(&'a RefitTree),
}

impl<'a> TreeView<'a> {
    fn of(tree: &'a PartTree) -> TreeView<'a> {
        match tree {
            PartTree::Kd(t) => TreeView::Kd(t),
            PartTree::Refit(t) => TreeView::Refit(t),
        }
    }

    /// The kd-tree whose nodes and references the GPU walks (a refitted tree's topology).
    fn topology(self) -> &'a KdTree {
        match self {
            TreeView::Kd(t) => t,
            TreeView::Refit(t) => t.topology(),
        }
    }

    /// The triangles the leaves reference, as they are now.
    fn triangles(self) -> &'a [[Vec3; 3]] {
        match self {
            TreeView::Kd(t) => t.arrays().triangles,
            TreeView::Refit(t) => t.triangles(),
        }
    }

    fn bounds(self) -> Aabb {
        match self {
            TreeView::Kd(t) => t.bounds(),
            TreeView::Refit(t) => t.bounds(),
        }
    }

    /// A refitted tree's children's boxes per topology node; none for a kd-tree.
    fn boxes(self) -> Vec<[Aabb; 2]> {
        match self {
            TreeView::Kd(_) => Vec::new(),
            TreeView::Refit(t) => t.boxes(),
        }
    }

    /// How many entries `boxes` has.
    fn box_count(self) -> usize {
        match self {
            TreeView::Kd(_) => 0,
            TreeView::Refit(t) => t.topology().arrays().nodes.len(),
        }
    }
}

/// A part as the upload reads it.
#[derive(Clone, Copy)]
struct PartView<'a> {
    tree: TreeView<'a>,
    map: &'a PrimMap,
    world_to_object: Option<Mat4>,
    bounds: Aabb,
}

impl<'a> PartView<'a> {
    fn of(part: &'a Part) -> PartView<'a> {
        PartView {
            tree: TreeView::of(&part.tree),
            map: &part.map,
            world_to_object: part.world_to_object,
            bounds: part.bounds,
        }
    }

    /// Elements of each array the part needs: nodes, references, boxes, object-space triangles.
    fn sizes(&self) -> [usize; 4] {
        let topology = self.tree.topology().arrays();
        [
            topology.nodes.len(),
            topology.prim_refs.len(),
            self.tree.box_count(),
            match self.world_to_object {
                Some(_) => self.tree.triangles().len(),
                None => 0,
            },
        ]
    }
}

/// Whether two trees are the same one (nothing to write).
fn same_tree(a: &PartTree, b: &PartTree) -> bool {
    match (a, b) {
        (PartTree::Kd(a), PartTree::Kd(b)) => Arc::ptr_eq(a, b),
        (PartTree::Refit(a), PartTree::Refit(b)) => Arc::ptr_eq(a, b),
        _ => false,
    }
}

/// Whether `new` replaces `old` with another tree (a rebuild), rather than being the same tree
/// or the same topology refitted.
fn rebuilt(old: &PartTree, new: &PartTree) -> bool {
    match (old, new) {
        (PartTree::Refit(a), PartTree::Refit(b)) => !Arc::ptr_eq(a.topology(), b.topology()),
        _ => !same_tree(old, new),
    }
}

/// A triangle as the walk reads it (nine floats).
fn flat(t: &[Vec3; 3]) -> [f32; 9] {
    let [p, q, r] = t.map(|v| v.to_array());
    [p[0], p[1], p[2], q[0], q[1], q[2], r[0], r[1], r[2]]
}

/// An infinite bound (a refitted subtree with no finite triangle) as the largest float: WGSL
/// lets a compiler assume no value is infinite.
fn finite(v: Vec3) -> [f32; 3] {
    v.clamp(Vec3::splat(f32::MIN), Vec3::splat(f32::MAX))
        .to_array()
}

/// The trees of a frame, resident on the GPU.
pub struct GpuAccel {
    pub(super) nodes: SplitArray,
    pub(super) prim_refs: SplitArray,
    pub(super) triangles: SplitArray,
    pub(super) boxes: SplitArray,
    pub(super) parts: wgpu::Buffer,
    /// Rows of `parts` the walk reads (parts with nothing to hit have none).
    pub(super) part_count: u32,
    slots: Vec<Slot>,
    triangle_count: usize,
    /// Bytes per buffer (0: every array in two halves, for tests).
    limit: u64,
    uploads: Uploads,
}

impl GpuAccel {
    /// An empty structure whose arrays split at the adapter's binding limit.
    pub fn new(gpu: &Gpu) -> Result<GpuAccel> {
        Self::with_limit(gpu, super::buffers::binding_limit(gpu))
    }

    /// `new` with every array split in two halves whatever its size: the path a structure
    /// larger than the binding limit takes, for testing it on a small one.
    pub fn in_halves(gpu: &Gpu) -> Result<GpuAccel> {
        Self::with_limit(gpu, 0)
    }

    fn with_limit(gpu: &Gpu, limit: u64) -> Result<GpuAccel> {
        let empty = |what: &str, element: usize| SplitArray::new(gpu, what, element, 0, limit);
        Ok(GpuAccel {
            nodes: empty("the kd-trees' nodes", 8)?,
            prim_refs: empty("the kd-trees' leaf references", 4)?,
            triangles: empty("the triangles", 36)?,
            boxes: empty("the refitted trees' boxes", 48)?,
            parts: super::buffers::storage(
                gpu,
                "the parts",
                bytemuck::bytes_of(&GpuPart::zeroed()),
                wgpu::BufferUsages::empty(),
            )?,
            part_count: 0,
            slots: Vec::new(),
            triangle_count: 0,
            limit,
            uploads: Uploads::default(),
        })
    }

    /// One kd-tree over triangles `0..n`, as a single world part.
    pub fn upload_tree(&mut self, gpu: &Gpu, tree: &KdTree) -> Result<()> {
        let map = PrimMap::Offset(0);
        let part = PartView {
            tree: TreeView::Kd(tree),
            map: &map,
            world_to_object: None,
            bounds: tree.bounds(),
        };
        self.lay_out(gpu, &[part], tree.triangle_count(), &[None])
    }

    /// Brings the GPU's copy up to date with a frame's structure over `triangle_count`
    /// triangles, writing only what changed (see the module comment).
    pub fn update(&mut self, gpu: &Gpu, accel: &TwoLevel, triangle_count: usize) -> Result<()> {
        let parts = accel.parts();
        let views: Vec<PartView> = parts.iter().map(PartView::of).collect();
        let fits = |slot: &Slot, view: &PartView| {
            let same_kind = slot.tree.as_ref().is_some_and(|t| {
                matches!(
                    (t, view.tree),
                    (PartTree::Kd(_), TreeView::Kd(_)) | (PartTree::Refit(_), TreeView::Refit(_))
                )
            });
            let room = [&slot.nodes, &slot.refs, &slot.boxes, &slot.tris].map(|r| r.len());
            let instance = slot.instance == view.world_to_object.is_some();
            same_kind && instance && view.sizes().iter().zip(room).all(|(&n, r)| n <= r)
        };
        let in_place = self.triangle_count == triangle_count
            && self.slots.len() == parts.len()
            && self.slots.iter().zip(&views).all(|(s, v)| fits(s, v));
        if !in_place {
            let trees: Vec<Option<PartTree>> = parts.iter().map(|p| Some(p.tree.clone())).collect();
            return self.lay_out(gpu, &views, triangle_count, &trees);
        }
        for (i, (part, view)) in parts.iter().zip(&views).enumerate() {
            let written = self.slots[i].tree.as_ref().expect("laid out from parts");
            if same_tree(written, &part.tree) {
                continue;
            }
            if rebuilt(written, &part.tree) {
                self.write_part(gpu, i, view);
                self.slots[i].rebuilt = true;
            } else {
                self.write_boxes_and_triangles(gpu, i, view);
                self.uploads.refits += 1;
            }
            self.slots[i].tree = Some(part.tree.clone());
        }
        self.write_table(gpu, &views)
    }

    /// What was sent so far.
    pub fn uploads(&self) -> Uploads {
        self.uploads
    }

    /// Arrays sized for `views` (with room to grow for parts rebuilt since the last layout),
    /// every part written, and the table.
    fn lay_out(
        &mut self,
        gpu: &Gpu,
        views: &[PartView],
        triangle_count: usize,
        trees: &[Option<PartTree>],
    ) -> Result<()> {
        // World triangles first, at their global indices.
        let mut ends = [0, 0, 0, triangle_count];
        let mut slots = Vec::with_capacity(views.len());
        for (i, view) in views.iter().enumerate() {
            // Rebuilt since the last layout, or now (a tree that outgrew its room).
            let grows = self.slots.get(i).is_some_and(|s| {
                s.rebuilt
                    || s.tree
                        .as_ref()
                        .zip(trees[i].as_ref())
                        .is_some_and(|(a, b)| rebuilt(a, b))
            });
            let room = view.sizes().map(|n| if grows { n + n / 4 } else { n });
            let mut ranges = [0..0, 0..0, 0..0, 0..0];
            for k in 0..4 {
                ranges[k] = ends[k]..ends[k] + room[k];
                ends[k] += room[k];
            }
            let [nodes, refs, boxes, tris] = ranges;
            slots.push(Slot {
                tree: trees[i].clone(),
                nodes,
                refs,
                boxes,
                tris,
                instance: view.world_to_object.is_some(),
                rebuilt: false,
            });
        }
        let limit = self.limit;
        self.nodes = SplitArray::new(gpu, "the kd-trees' nodes", 8, ends[0], limit)?;
        self.prim_refs = SplitArray::new(gpu, "the kd-trees' leaf references", 4, ends[1], limit)?;
        self.boxes = SplitArray::new(gpu, "the refitted trees' boxes", 48, ends[2], limit)?;
        self.triangles = SplitArray::new(gpu, "the triangles", 36, ends[3], limit)?;
        self.slots = slots;
        self.triangle_count = triangle_count;
        self.uploads.layouts += 1;
        for (i, view) in views.iter().enumerate() {
            self.write_part(gpu, i, view);
        }
        self.write_table(gpu, views)
    }

    /// Writes a part's whole tree into its slot.
    fn write_part(&mut self, gpu: &Gpu, i: usize, view: &PartView) {
        let slot = &self.slots[i];
        let topology = view.tree.topology().arrays();
        let nodes: Vec<[u32; 2]> = topology.nodes.iter().map(|n| n.words()).collect();
        let mut bytes = self.nodes.write(gpu, slot.nodes.start, &nodes);
        // Leaf references name entries of the triangle array (see the module comment).
        let refs: Vec<u32> = match view.world_to_object {
            Some(_) => topology
                .prim_refs
                .iter()
                .map(|&r| slot.tris.start as u32 + r)
                .collect(),
            None => topology
                .prim_refs
                .iter()
                .map(|&r| view.map.global(r))
                .collect(),
        };
        bytes += self.prim_refs.write(gpu, slot.refs.start, &refs);
        self.uploads.bytes += bytes;
        self.uploads.trees += 1;
        self.write_boxes_and_triangles(gpu, i, view);
    }

    /// Writes a part's boxes (a refitted tree's) and its triangles.
    fn write_boxes_and_triangles(&mut self, gpu: &Gpu, i: usize, view: &PartView) {
        let slot = &self.slots[i];
        let boxes: Vec<[f32; 12]> = view
            .tree
            .boxes()
            .iter()
            .map(|[b, a]| {
                let [p, q, r, s] = [b.min, b.max, a.min, a.max].map(finite);
                [
                    p[0], p[1], p[2], q[0], q[1], q[2], r[0], r[1], r[2], s[0], s[1], s[2],
                ]
            })
            .collect();
        let mut bytes = self.boxes.write(gpu, slot.boxes.start, &boxes);
        let tris = view.tree.triangles();
        match view.world_to_object {
            Some(_) => {
                let flat: Vec<[f32; 9]> = tris.iter().map(flat).collect();
                bytes += self.triangles.write(gpu, slot.tris.start, &flat);
            }
            // A world part's triangles at their global indices, in runs of consecutive ones.
            None => {
                let mut run: Vec<[f32; 9]> = Vec::new();
                let mut run_start = 0;
                for (local, t) in tris.iter().enumerate() {
                    let global = view.map.global(local as u32) as usize;
                    if run.is_empty() || global != run_start + run.len() {
                        bytes += self.triangles.write(gpu, run_start, &run);
                        run.clear();
                        run_start = global;
                    }
                    run.push(flat(t));
                }
                bytes += self.triangles.write(gpu, run_start, &run);
            }
        }
        self.uploads.bytes += bytes;
    }

    /// The table of parts the walk goes through: every part with something to hit.
    fn write_table(&mut self, gpu: &Gpu, views: &[PartView]) -> Result<()> {
        let rows: Vec<GpuPart> = views
            .iter()
            .zip(&self.slots)
            .filter(|(v, _)| {
                !v.tree.bounds().is_empty() && !v.tree.topology().arrays().nodes.is_empty()
            })
            .map(|(v, slot)| {
                let tree = v.tree.bounds();
                let offset = match (v.world_to_object, v.map) {
                    (None, _) => 0,
                    (Some(_), PrimMap::Offset(o)) => *o,
                    // `Updater` places instances over one object's contiguous triangles.
                    (Some(_), PrimMap::Table(_)) => unreachable!("an instance maps by offset"),
                };
                let kind = match v.world_to_object {
                    Some(_) => PART_INSTANCE,
                    None => 0,
                } | match v.tree {
                    TreeView::Refit(_) => PART_BOXES,
                    TreeView::Kd(_) => 0,
                };
                GpuPart {
                    world_to_object: v.world_to_object.unwrap_or_default().to_cols_array_2d(),
                    world_min: finite(v.bounds.min),
                    kind,
                    world_max: finite(v.bounds.max),
                    node_base: slot.nodes.start as u32,
                    tree_min: finite(tree.min),
                    ref_base: slot.refs.start as u32,
                    tree_max: finite(tree.max),
                    box_base: slot.boxes.start as u32,
                    tri_base: match v.world_to_object {
                        Some(_) => slot.tris.start as u32,
                        None => 0,
                    },
                    prim_offset: offset,
                    pad: [0; 2],
                }
            })
            .collect();
        self.part_count = rows.len() as u32;
        // A binding holds at least one row; with nothing to hit, a zeroed one the walk never reads.
        let rows = if rows.is_empty() {
            vec![GpuPart::zeroed()]
        } else {
            rows
        };
        let bytes: &[u8] = bytemuck::cast_slice(&rows);
        self.parts = super::buffers::storage(gpu, "the parts", bytes, wgpu::BufferUsages::empty())?;
        self.uploads.bytes += bytes.len() as u64;
        Ok(())
    }
}
