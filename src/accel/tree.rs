//! The kd-tree as traversal sees it: compact 8-byte nodes in depth-first order, a primitive
//! reference array the leaves index, the triangles, and the scene bounds. The builders produce
//! a `BuildNode` tree; `flatten` lays it out once.

use super::aabb::Aabb;
use super::params::BuildParams;
use super::split::BuildNode;
use glam::Vec3;

/// A kd-tree node in 8 bytes: two nodes per 16 bytes, four per cache line, which is what
/// traversal spends its time loading (pbrt-v3's KdAccelNode makes the same choice).
/// Inner: `a` = split position (f32 bits), `b` = (offset of the above child from this node) << 2 | axis.
/// The below child always follows its parent directly.
/// Leaf: `a` = first index into the primitive-reference array, `b` = count << 2 | 3.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C)]
pub struct Node {
    a: u32,
    b: u32,
}

const _: () = assert!(std::mem::size_of::<Node>() == 8);

impl Node {
    pub(super) fn leaf(first: u32, count: u32) -> Node {
        Node {
            a: first,
            b: (count << 2) | 3,
        }
    }

    pub(super) fn inner(axis: usize, split: f32, above_offset: u32) -> Node {
        Node {
            a: split.to_bits(),
            b: (above_offset << 2) | axis as u32,
        }
    }

    /// The same node with its leaf references moved `base` entries on (inner nodes unchanged),
    /// for appending a separately built subtree.
    pub(super) fn with_refs_from(self, base: u32) -> Node {
        if self.is_leaf() {
            Node {
                a: self.a + base,
                ..self
            }
        } else {
            self
        }
    }

    #[inline]
    pub fn is_leaf(&self) -> bool {
        self.b & 3 == 3
    }

    #[inline]
    pub fn axis(&self) -> usize {
        (self.b & 3) as usize
    }

    #[inline]
    pub fn split(&self) -> f32 {
        f32::from_bits(self.a)
    }

    #[inline]
    pub fn above_offset(&self) -> usize {
        (self.b >> 2) as usize
    }

    /// The node's two words as laid out in memory (see the type's documentation), for walkers
    /// that read the tree elsewhere (the GPU's).
    pub fn words(&self) -> [u32; 2] {
        [self.a, self.b]
    }

    #[inline]
    pub fn leaf_range(&self) -> std::ops::Range<usize> {
        let first = self.a as usize;
        first..first + (self.b >> 2) as usize
    }
}

pub struct KdTree {
    pub(super) nodes: Vec<Node>,
    pub(super) prim_refs: Vec<u32>,
    pub(super) triangles: Vec<[Vec3; 3]>,
    pub(super) bounds: Aabb,
    pub params: BuildParams,
    pub build_seconds: f64,
}

/// A kd-tree's arrays: nodes in depth-first order, the leaves' references into `triangles`,
/// and the box the root covers.
pub struct TreeArrays<'a> {
    pub nodes: &'a [Node],
    pub prim_refs: &'a [u32],
    pub triangles: &'a [[Vec3; 3]],
    pub bounds: Aabb,
}

/// Hard cap so the traversal stack (one entry per level) has a fixed size.
pub const MAX_DEPTH: u32 = 60;

impl KdTree {
    /// The tree from a builder's arrays; `build_seconds` counts from `start`.
    pub(super) fn assemble(
        nodes: Vec<Node>,
        prim_refs: Vec<u32>,
        triangles: Vec<[Vec3; 3]>,
        bounds: Aabb,
        params: BuildParams,
        start: std::time::Instant,
    ) -> KdTree {
        KdTree {
            nodes,
            prim_refs,
            triangles,
            bounds,
            params,
            build_seconds: start.elapsed().as_secs_f64(),
        }
    }

    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The tree's arrays as they are, for a walker elsewhere (the GPU's) to upload.
    pub fn arrays(&self) -> TreeArrays<'_> {
        TreeArrays {
            nodes: &self.nodes,
            prim_refs: &self.prim_refs,
            triangles: &self.triangles,
            bounds: self.bounds,
        }
    }

    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// The tree's inner nodes and leaves in layout order, for comparing trees in tests: inner
    /// nodes as (axis, split, above offset), leaves as their sorted primitive lists.
    pub fn shape(&self) -> Vec<(usize, f32, usize, Vec<u32>)> {
        self.nodes
            .iter()
            .map(|n| {
                if n.is_leaf() {
                    let mut prims = self.prim_refs[n.leaf_range()].to_vec();
                    prims.sort_unstable();
                    (3, 0.0, 0, prims)
                } else {
                    (n.axis(), n.split(), n.above_offset(), Vec::new())
                }
            })
            .collect()
    }
}

/// The depth cap for a tree over `triangles` triangles: pbrt-v3's `8 + 1.3 log2 N`, only a safety
/// net since the SAH termination criterion ends the recursion, and never past `MAX_DEPTH`.
pub(super) fn depth_cap(triangles: usize) -> u32 {
    let n = triangles.max(1) as f32;
    ((8.0 + 1.3 * n.log2()).round() as u32).min(MAX_DEPTH)
}

/// Depth-first layout: the below child follows its parent, the above child's offset is stored.
pub(super) fn flatten(root: BuildNode) -> (Vec<Node>, Vec<u32>) {
    let mut nodes = Vec::new();
    let mut refs = Vec::new();
    // (node, index of the parent whose above-offset waits for this node)
    let mut stack: Vec<(BuildNode, Option<usize>)> = vec![(root, None)];
    while let Some((node, parent)) = stack.pop() {
        let here = nodes.len();
        if let Some(p) = parent {
            let Node { a, .. } = nodes[p];
            let axis = nodes[p].axis();
            nodes[p] = Node::inner(axis, f32::from_bits(a), (here - p) as u32);
        }
        match node {
            BuildNode::Leaf(prims) => {
                nodes.push(Node::leaf(refs.len() as u32, prims.len() as u32));
                refs.extend(prims);
            }
            BuildNode::Inner {
                split,
                below,
                above,
            } => {
                nodes.push(Node::inner(split.axis, split.pos, 0));
                stack.push((*above, Some(here)));
                stack.push((*below, None));
            }
        }
    }
    (nodes, refs)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn node_packs_leaf_and_inner_fields() {
        let l = Node::leaf(7, 3);
        assert!(l.is_leaf());
        assert_eq!(l.leaf_range(), 7..10);
        let i = Node::inner(2, 1.5, 42);
        assert!(!i.is_leaf());
        assert_eq!((i.axis(), i.split(), i.above_offset()), (2, 1.5, 42));
    }
}
