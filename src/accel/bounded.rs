//! The topology of a bounded kd-tree (B-KD tree, Woop, Marmitt and Slusallek 2006) for meshes that
//! deform every frame: each triangle in exactly one leaf, children split by triangle centroid, so
//! sibling subtrees overlap only by the triangles near their split and a refit (`refit.rs`) keeps
//! them nearly as tight as at the build. A kd-tree built with clipped references, refitted, bounds
//! every reference by its whole triangle on both sides of every plane it straddled: that tree
//! traced 15-65x slower once refitted.
//!
//! The split search bins centroids (32 bins per axis, the count BVH builders use: Wald 2007) and
//! costs each boundary by the SAH of the two child boxes the refit walk really tests: the boxes
//! of each side's triangles, on all three axes (`refit.rs` keeps each child's whole box). Costed
//! with the older B-KD boxes (the parent's cut on the split axis only), BrainStem's tree had a
//! 14% higher SAH cost (1059.6 against 927.9) and traced 6% slower at 16 spp. 64 bins: SAH cost
//! 924.7, the same trace time, a quarter slower to build. Children partition their parent's
//! slice in place: no allocation per node.
//!
//! The tree this builds is a topology for `RefitTree` only: its split positions do not separate
//! its leaves, so the kd-tree walk must never see it (`RefitTree::build` keeps it private).

use super::aabb::Aabb;
use super::flat::Flat;
use super::params::BuildParams;
use super::split::PARALLEL_THRESHOLD;
use super::tree::{KdTree, depth_cap};
use glam::Vec3;
use std::time::Instant;

const BINS: usize = 32;

#[derive(Clone, Copy)]
struct Item {
    lo: [f32; 3],
    hi: [f32; 3],
    centroid: [f32; 3],
    prim: u32,
}

/// Builds the object-partition topology of `triangles`.
pub(super) fn build_topology(triangles: Vec<[Vec3; 3]>, params: BuildParams) -> KdTree {
    let start = Instant::now();
    let mut items: Vec<Item> = triangles
        .iter()
        .enumerate()
        .filter_map(|(i, t)| {
            let b = Aabb::of_points(t);
            (b.min.is_finite() && b.max.is_finite()).then(|| Item {
                lo: b.min.to_array(),
                hi: b.max.to_array(),
                centroid: ((b.min + b.max) * 0.5).to_array(),
                prim: i as u32,
            })
        })
        .collect();
    let bounds = items.iter().fold(Aabb::EMPTY, |acc, it| {
        acc.union(&Aabb {
            min: Vec3::from_array(it.lo),
            max: Vec3::from_array(it.hi),
        })
    });
    let max_depth = depth_cap(items.len());
    let ctx = Ctx { params, max_depth };
    let mut out = Flat::with_capacity(2 * items.len(), items.len());
    let (centroids, _) = extents(&items);
    ctx.node(&mut items, bounds, centroids, 0, &mut out);
    let (nodes, refs) = out.into_arrays();
    KdTree::assemble(nodes, refs, triangles, bounds, params, start)
}

struct Ctx {
    params: BuildParams,
    max_depth: u32,
}

/// Per bin of centroids: how many, and the box of their triangles.
#[derive(Clone, Copy)]
struct Bin {
    count: usize,
    bounds: Aabb,
}

const EMPTY_BIN: Bin = Bin {
    count: 0,
    bounds: Aabb::EMPTY,
};

/// A chosen split: axis, boundary index in that axis's centroid bins, and the bins' mapping.
struct Choice {
    axis: usize,
    boundary: usize,
    origin: f32,
    scale: f32,
    position: f32,
}

/// Per axis, the lowest and highest triangle centroid of a node's items: the range its
/// centroid bins span.
type CentroidRange = [(f32, f32); 3];

/// The centroid range and the box of `items`, in one pass: each child's come from its parent's
/// partition, not from a pass of its own.
fn extents(items: &[Item]) -> (CentroidRange, Aabb) {
    let mut range = [(f32::INFINITY, f32::NEG_INFINITY); 3];
    let mut bounds = Aabb::EMPTY;
    for it in items {
        for (r, &c) in range.iter_mut().zip(&it.centroid) {
            *r = (r.0.min(c), r.1.max(c));
        }
        bounds = bounds.union(&it.bounds());
    }
    (range, bounds)
}

impl Item {
    fn bounds(&self) -> Aabb {
        Aabb {
            min: Vec3::from_array(self.lo),
            max: Vec3::from_array(self.hi),
        }
    }
}

impl Ctx {
    fn node(
        &self,
        items: &mut [Item],
        node_box: Aabb,
        centroids: CentroidRange,
        depth: u32,
        out: &mut Flat,
    ) {
        let choice = if items.len() <= 1 || depth >= self.max_depth {
            None
        } else {
            self.find_split(items, &node_box, &centroids)
        };
        let Some(c) = choice else {
            out.leaf(items.iter().map(|it| it.prim));
            return;
        };
        let bin = |it: &Item| centroid_bin(it.centroid[c.axis], c.origin, c.scale);
        let mid = partition(items, |it| bin(it) < c.boundary);
        let (below, above) = items.split_at_mut(mid);
        // The children's boxes: their triangles' bounds, as the refit will fit them.
        let (below_centroids, below_box) = extents(below);
        let (above_centroids, above_box) = extents(above);
        out.inner(
            c.axis,
            c.position,
            (below.len() + above.len() > PARALLEL_THRESHOLD).then_some(above.len()),
            |out| self.node(below, below_box, below_centroids, depth + 1, out),
            |out| self.node(above, above_box, above_centroids, depth + 1, out),
        );
    }

    /// The cheapest centroid-bin boundary over the three axes, or `None` when a leaf is cheaper.
    /// The three axes are binned in one pass over the items: three independent histograms
    /// interleave, where one axis at a time waited on each bin's last update (neighbouring
    /// triangles fall in the same bin).
    fn find_split(
        &self,
        items: &[Item],
        node_box: &Aabb,
        centroids: &CentroidRange,
    ) -> Option<Choice> {
        let area = node_box.surface_area();
        if area <= 0.0 {
            return None;
        }
        let n = items.len();
        let leaf_cost = self.params.intersection_cost * n as f32;
        let scale = centroids.map(|(cmin, cmax)| {
            if cmax > cmin {
                BINS as f32 / (cmax - cmin)
            } else {
                0.0
            }
        });
        let mut bins = [[EMPTY_BIN; BINS]; 3];
        for it in items {
            for axis in 0..3 {
                let b = &mut bins[axis]
                    [centroid_bin(it.centroid[axis], centroids[axis].0, scale[axis])];
                b.count += 1;
                b.bounds = b.bounds.union(&it.bounds());
            }
        }
        let mut best: Option<(f32, Choice)> = None;
        for (axis, bins) in bins.iter().enumerate() {
            let (cmin, scale) = (centroids[axis].0, scale[axis]);
            if scale == 0.0 {
                continue;
            }
            // Sweep from the top for the above sides' boxes, then from the bottom.
            let mut above_area = [0f32; BINS];
            let mut acc = Aabb::EMPTY;
            for k in (1..BINS).rev() {
                acc = acc.union(&bins[k].bounds);
                above_area[k] = acc.surface_area();
            }
            let (mut nb, mut below_box) = (0usize, Aabb::EMPTY);
            for k in 1..BINS {
                // After an empty bin the boundary is the one before it again (the same counts
                // and reaches, the same cost, and ties keep the first): small nodes, most of
                // whose 32 bins are empty, cost as many boundaries as they have items.
                if bins[k - 1].count == 0 {
                    continue;
                }
                nb += bins[k - 1].count;
                below_box = below_box.union(&bins[k - 1].bounds);
                if nb == n {
                    continue;
                }
                let (below, above) = (below_box.surface_area(), above_area[k]);
                let cost = self.params.traversal_cost
                    + self.params.intersection_cost * (below * nb as f32 + above * (n - nb) as f32)
                        / area;
                if best.as_ref().is_none_or(|(c, _)| cost < *c) {
                    best = Some((
                        cost,
                        Choice {
                            axis,
                            boundary: k,
                            origin: cmin,
                            scale,
                            position: cmin + k as f32 / scale,
                        },
                    ));
                }
            }
        }
        best.filter(|(cost, _)| *cost < leaf_cost).map(|(_, c)| c)
    }
}

#[inline]
fn centroid_bin(x: f32, origin: f32, scale: f32) -> usize {
    (((x - origin) * scale) as usize).min(BINS - 1)
}

/// Moves the items for which `below` holds to the front (in a fixed order, so the result does not
/// depend on threads) and returns how many there are.
fn partition(items: &mut [Item], below: impl Fn(&Item) -> bool) -> usize {
    let mut mid = 0;
    for i in 0..items.len() {
        if below(&items[i]) {
            items.swap(i, mid);
            mid += 1;
        }
    }
    mid
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::test_rng::Lcg;

    fn soup(n: usize) -> Vec<[Vec3; 3]> {
        let mut rng = Lcg(41);
        (0..n)
            .map(|_| {
                let c = rng.v(30.0);
                [c, c + rng.v(1.0) - 0.5, c + rng.v(1.0) - 0.5]
            })
            .collect()
    }

    #[test]
    fn every_triangle_is_in_exactly_one_leaf() {
        let tree = build_topology(soup(5000), BuildParams::default());
        let mut seen = vec![0u32; 5000];
        for &p in &tree.prim_refs {
            seen[p as usize] += 1;
        }
        assert!(seen.iter().all(|&c| c == 1));
        assert!(tree.nodes.len() > 1000, "{} nodes", tree.nodes.len());
    }

    #[test]
    fn the_topology_does_not_depend_on_the_thread_count() {
        let tris = soup(20_000);
        let build = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| build_topology(tris.clone(), BuildParams::default()).shape())
        };
        assert!(build(1) == build(2));
    }
}
