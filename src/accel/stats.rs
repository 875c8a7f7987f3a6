//! Statistics of a built kd-tree: size, depth, references and the SAH cost of the whole tree.

use super::aabb::Aabb;
use super::tree::KdTree;
use serde::Serialize;

#[derive(Clone, Debug, Serialize)]
pub struct TreeStats {
    pub triangles: usize,
    pub nodes: usize,
    pub leaves: usize,
    pub empty_leaves: usize,
    pub max_depth: usize,
    pub mean_leaf_depth: f64,
    pub references_per_triangle: f64,
    pub triangles_per_nonempty_leaf: f64,
    /// Expected cost of a random ray: sum over nodes of (area / root area) * node cost.
    pub sah_cost: f64,
    pub bytes: usize,
    pub build_seconds: f64,
}

impl KdTree {
    pub fn stats(&self) -> TreeStats {
        let root_area = self.bounds.surface_area().max(f32::MIN_POSITIVE) as f64;
        let (kt, ki) = (
            self.params.traversal_cost as f64,
            self.params.intersection_cost as f64,
        );
        let mut s = TreeStats {
            triangles: self.triangles.len(),
            nodes: self.nodes.len(),
            leaves: 0,
            empty_leaves: 0,
            max_depth: 0,
            mean_leaf_depth: 0.0,
            references_per_triangle: self.prim_refs.len() as f64
                / self.triangles.len().max(1) as f64,
            triangles_per_nonempty_leaf: 0.0,
            sah_cost: 0.0,
            bytes: std::mem::size_of_val(&self.nodes[..])
                + std::mem::size_of_val(&self.prim_refs[..])
                + std::mem::size_of_val(&self.triangles[..]),
            build_seconds: self.build_seconds,
        };
        if self.nodes.is_empty() || self.bounds.is_empty() {
            return s;
        }
        let mut depth_sum = 0usize;
        let mut refs_in_nonempty = 0usize;
        let mut stack: Vec<(usize, Aabb, usize)> = vec![(0, self.bounds, 0)];
        while let Some((i, b, depth)) = stack.pop() {
            let n = self.nodes[i];
            let p = b.surface_area() as f64 / root_area;
            s.max_depth = s.max_depth.max(depth);
            if n.is_leaf() {
                let count = n.leaf_range().len();
                s.leaves += 1;
                depth_sum += depth;
                if count == 0 {
                    s.empty_leaves += 1;
                } else {
                    refs_in_nonempty += count;
                }
                s.sah_cost += p * ki * count as f64;
            } else {
                s.sah_cost += p * kt;
                let (lo, hi) = b.split(n.axis(), n.split());
                stack.push((i + 1, lo, depth + 1));
                stack.push((i + n.above_offset(), hi, depth + 1));
            }
        }
        s.mean_leaf_depth = depth_sum as f64 / s.leaves.max(1) as f64;
        s.triangles_per_nonempty_leaf =
            refs_in_nonempty as f64 / (s.leaves - s.empty_leaves).max(1) as f64;
        s
    }
}
