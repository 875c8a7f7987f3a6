//! The fast builders' output as it is written: nodes in depth-first order (the below child right
//! after its parent) and the leaves' primitive references, with the subtrees other tasks built
//! kept aside until the end, where one pass lays the whole tree out.

use super::tree::Node;
use rayon::prelude::*;
use std::mem::MaybeUninit;

/// A tree, or a subtree built on a task of its own, as written so far.
pub(super) struct Flat {
    nodes: Vec<Node>,
    refs: Vec<u32>,
    /// Subtrees built on other tasks, each belonging before `nodes[at_node]` and `refs[at_ref]`
    /// (positions in this part's own arrays), in order. Appending each one to its parent as it
    /// finished copied every node once per level of tasks above it, into fresh pages each time
    /// (the 1M peer mesh: about a tenth of a one-thread build in copies and page faults).
    spliced: Vec<Splice>,
    /// Nodes and references held in `spliced`, at every depth.
    spliced_nodes: usize,
    spliced_refs: usize,
}

struct Splice {
    at_node: usize,
    at_ref: usize,
    part: Flat,
}

impl Flat {
    /// Room reserved, not grown: growing copies and first-touches the arrays once per doubling,
    /// while a generous reserve costs only the pages written.
    pub(super) fn with_capacity(nodes: usize, refs: usize) -> Flat {
        Flat {
            nodes: Vec::with_capacity(nodes),
            refs: Vec::with_capacity(refs),
            spliced: Vec::new(),
            spliced_nodes: 0,
            spliced_refs: 0,
        }
    }

    /// Nodes written so far, counting those of spliced subtrees.
    fn node_count(&self) -> usize {
        self.nodes.len() + self.spliced_nodes
    }

    fn ref_count(&self) -> usize {
        self.refs.len() + self.spliced_refs
    }

    /// A leaf over `prims`. Its first reference is counted from the start of this part, spliced
    /// subtrees included; `into_arrays` moves it to where the part lands.
    pub(super) fn leaf(&mut self, prims: impl ExactSizeIterator<Item = u32>) {
        self.nodes
            .push(Node::leaf(self.ref_count() as u32, prims.len() as u32));
        self.refs.extend(prims);
    }

    /// Writes an inner node, then its below and above subtrees. With `parallel` (the above
    /// child's reference count) the above one is built on another rayon task into a part of its
    /// own, spliced in after the below subtree (above-child offsets are relative, so only leaf
    /// references move when the parts are laid out).
    pub(super) fn inner(
        &mut self,
        axis: usize,
        pos: f32,
        parallel: Option<usize>,
        below: impl FnOnce(&mut Flat) + Send,
        above: impl FnOnce(&mut Flat) + Send,
    ) {
        let (here, here_counted) = (self.nodes.len(), self.node_count());
        self.nodes.push(Node::inner(axis, pos, 0));
        let link = |f: &mut Flat| {
            f.nodes[here] = Node::inner(axis, pos, (f.node_count() - here_counted) as u32)
        };
        if let Some(above_refs) = parallel {
            // The 1M peer mesh's trees hold about 1.2 nodes and 2.3 leaf references per
            // triangle.
            let ((), part) = rayon::join(
                || below(self),
                || {
                    let mut part = Flat::with_capacity(2 * above_refs, 3 * above_refs);
                    above(&mut part);
                    part
                },
            );
            link(self);
            self.spliced_nodes += part.node_count();
            self.spliced_refs += part.ref_count();
            self.spliced.push(Splice {
                at_node: self.nodes.len(),
                at_ref: self.refs.len(),
                part,
            });
        } else {
            below(self);
            link(self);
            above(self);
        }
    }

    /// The whole tree's nodes and references, each copied once (not at all when no subtree was
    /// built apart). Every part's place is known from the counts, so the parts are copied on all
    /// threads: copied on one, the 1M peer mesh's 9 MB of nodes and 9 MB of references took
    /// 10-46 ms of a 0.37-0.50 s two-thread build.
    pub(super) fn into_arrays(self) -> (Vec<Node>, Vec<u32>) {
        if self.spliced.is_empty() {
            return (self.nodes, self.refs);
        }
        let (node_count, ref_count) = (self.node_count(), self.ref_count());
        let mut nodes = Vec::with_capacity(node_count);
        let mut refs = Vec::with_capacity(ref_count);
        self.lay_out(
            &mut nodes.spare_capacity_mut()[..node_count],
            &mut refs.spare_capacity_mut()[..ref_count],
            0,
        );
        // SAFETY: `lay_out` wrote every node and reference: a part's own arrays and its
        // spliced parts together fill exactly its counts.
        unsafe {
            nodes.set_len(node_count);
            refs.set_len(ref_count);
        }
        (nodes, refs)
    }

    /// Writes this part into `nodes` and `refs` (exactly its counts) with its first reference
    /// at `base` of the whole array: its own runs here, its spliced parts on other rayon tasks.
    /// A leaf's first reference is counted from the start of its part (see `leaf`), so every
    /// own leaf moves by `base`.
    fn lay_out(self, nodes: &mut [MaybeUninit<Node>], refs: &mut [MaybeUninit<u32>], base: u32) {
        let (mut nodes, mut refs) = (nodes, refs);
        // This part's references laid out so far, spliced parts' included.
        let mut written = 0;
        let (mut node_from, mut ref_from) = (0, 0);
        let mut parts = Vec::with_capacity(self.spliced.len());
        for s in self.spliced {
            let own = (
                &self.nodes[node_from..s.at_node],
                &self.refs[ref_from..s.at_ref],
            );
            let (here_nodes, rest_nodes) = nodes.split_at_mut(own.0.len());
            let (here_refs, rest_refs) = refs.split_at_mut(own.1.len());
            copy_run(own, here_nodes, here_refs, base);
            written += own.1.len();
            let (part_nodes, rest_nodes) = rest_nodes.split_at_mut(s.part.node_count());
            let (part_refs, rest_refs) = rest_refs.split_at_mut(s.part.ref_count());
            let part_base = base + written as u32;
            written += s.part.ref_count();
            parts.push((s.part, part_nodes, part_refs, part_base));
            (nodes, refs) = (rest_nodes, rest_refs);
            (node_from, ref_from) = (s.at_node, s.at_ref);
        }
        let own = (&self.nodes[node_from..], &self.refs[ref_from..]);
        copy_run(own, nodes, refs, base);
        parts
            .into_par_iter()
            .for_each(|(part, nodes, refs, base)| part.lay_out(nodes, refs, base));
    }
}

/// Copies a run of a part's own nodes and references, moving its leaves' references by `base`.
fn copy_run(
    (from_nodes, from_refs): (&[Node], &[u32]),
    nodes: &mut [MaybeUninit<Node>],
    refs: &mut [MaybeUninit<u32>],
    base: u32,
) {
    // `into_arrays` relies on every slot being written.
    assert_eq!(nodes.len(), from_nodes.len());
    for (to, n) in nodes.iter_mut().zip(from_nodes) {
        to.write(n.with_refs_from(base));
    }
    refs.write_copy_of_slice(from_refs);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A synthetic subtree of `depth` levels under the node numbered `id` (children `2 id` and
    /// `2 id + 1`), each leaf holding a few references named after its number; the subtrees at
    /// the levels in `apart` are built as parts of their own and spliced, the rest in place.
    fn write(out: &mut Flat, depth: u32, id: u32, apart: &[u32]) {
        if depth == 0 {
            out.leaf(4 * id..4 * id + id % 4);
            return;
        }
        out.inner(
            depth as usize % 3,
            id as f32,
            apart.contains(&depth).then_some(8),
            |o| write(o, depth - 1, 2 * id, apart),
            |o| write(o, depth - 1, 2 * id + 1, apart),
        );
    }

    #[test]
    fn spliced_parts_lay_out_as_if_written_in_place() {
        let mut in_place = Flat::with_capacity(0, 0);
        write(&mut in_place, 7, 1, &[]);
        let (nodes, refs) = in_place.into_arrays();
        assert_eq!((nodes.len(), refs.len()), (255, 192));
        for apart in [&[7][..], &[7, 6, 3], &[5, 4, 3, 2, 1], &[1]] {
            let mut spliced = Flat::with_capacity(0, 0);
            write(&mut spliced, 7, 1, apart);
            assert!(!spliced.spliced.is_empty());
            assert_eq!(
                spliced.into_arrays(),
                (nodes.clone(), refs.clone()),
                "{apart:?}"
            );
        }
    }
}
