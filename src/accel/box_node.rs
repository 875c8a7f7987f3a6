//! The refitted tree's inner node as its walks read it: both children's boxes and where each
//! child is, in one 64-byte cache line. Read from the topology's 8-byte nodes (`tree.rs`) and a
//! box array beside them, a step touched two cache lines, and the box array kept a slot for
//! every leaf too (half its size unused).

use super::aabb::Aabb;
use super::tree::KdTree;
use glam::Vec3;
use std::ops::Range;

/// Marks a child that is a leaf, in `BoxNode::info`.
const LEAF: u32 = 1 << 2;

#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(super) struct BoxNode {
    pub boxes: [Aabb; 2],
    /// Per child (below, above): an inner child's index among the nodes, or a leaf's first
    /// slot in the topology's leaf references.
    child: [u32; 2],
    /// Per child: a leaf's reference count shifted left by three, with `LEAF`; both hold the
    /// node's split axis in their low two bits.
    info: [u32; 2],
}

/// Where a walk goes next: an inner node's index, or a leaf's slots in the leaf references.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Child {
    Inner(u32),
    Leaf(u32, u32),
}

impl Child {
    pub fn leaf_range(start: u32, count: u32) -> Range<usize> {
        start as usize..(start + count) as usize
    }
}

impl BoxNode {
    /// The split axis of the topology's node: which child a ray's octant meets first.
    #[inline(always)]
    pub fn axis(&self) -> usize {
        (self.info[0] & 3) as usize
    }

    /// Child `k`: 0 below, 1 above.
    #[inline(always)]
    pub fn child(&self, k: usize) -> Child {
        let info = self.info[k];
        if info & LEAF == 0 {
            Child::Inner(self.child[k])
        } else {
            Child::Leaf(self.child[k], info >> 3)
        }
    }
}

/// A topology fitted to its triangles' current pose.
pub(super) struct Fitted {
    /// The inner nodes, in the topology's order (the root first; none for a topology that is
    /// one leaf).
    pub nodes: Vec<BoxNode>,
    /// The triangle of each leaf reference, in the references' order: a leaf's triangles lie
    /// side by side, where the triangles' own order scatters them over the mesh.
    pub leaf_triangles: Vec<[Vec3; 3]>,
    pub bounds: Aabb,
}

/// Fits `topology` to `triangles`.
pub(super) fn fit(topology: &KdTree, triangles: &[[Vec3; 3]]) -> Fitted {
    let mut fitted = Fitted {
        nodes: Vec::with_capacity(topology.nodes.len() / 2 + 1),
        leaf_triangles: vec![[Vec3::ZERO; 3]; topology.prim_refs.len()],
        bounds: Aabb::EMPTY,
    };
    if !topology.nodes.is_empty() {
        (fitted.bounds, _) = fit_subtree(topology, triangles, 0, &mut fitted);
    }
    fitted
}

/// Fits the subtree at topology node `i`: its box and how its parent points to it.
fn fit_subtree(t: &KdTree, tris: &[[Vec3; 3]], i: usize, out: &mut Fitted) -> (Aabb, (u32, u32)) {
    let n = t.nodes[i];
    if n.is_leaf() {
        let range = n.leaf_range();
        let mut b = Aabb::EMPTY;
        for j in range.clone() {
            let tri = tris[t.prim_refs[j] as usize];
            out.leaf_triangles[j] = tri;
            b = b.union(&Aabb::of_points(&tri));
        }
        return (b, (range.start as u32, (range.len() as u32) << 3 | LEAF));
    }
    let at = out.nodes.len();
    out.nodes.push(BoxNode {
        boxes: [Aabb::EMPTY; 2],
        child: [0; 2],
        info: [0; 2],
    });
    let (below, (bc, bi)) = fit_subtree(t, tris, i + 1, out);
    let (above, (ac, ai)) = fit_subtree(t, tris, i + n.above_offset(), out);
    let axis = n.axis() as u32;
    out.nodes[at] = BoxNode {
        boxes: [below, above],
        child: [bc, ac],
        info: [bi | axis, ai | axis],
    };
    (below.union(&above), (at as u32, 0))
}

/// The children's boxes per topology node (unused at leaves), for walkers that read the
/// topology's nodes (the GPU's).
pub(super) fn boxes_by_topology(topology: &KdTree, nodes: &[BoxNode]) -> Vec<[Aabb; 2]> {
    let mut inner = nodes.iter();
    topology
        .nodes
        .iter()
        .map(|n| match n.is_leaf() {
            true => [Aabb::EMPTY; 2],
            false => inner.next().map_or([Aabb::EMPTY; 2], |b| b.boxes),
        })
        .collect()
}
