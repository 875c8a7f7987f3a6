//! Min-max binning for the kd-tree build of `binned.rs`: the references a node holds, the grid of
//! equal bins over the node's box, and per-axis counts of the bins the references' lower and upper
//! bounds fall in (Shevtsov et al. 2007; Mitsuba 0.6's `gkdtree.h` calls it min-max binning).

use super::aabb::Aabb;
use std::cell::RefCell;

/// The part of one triangle inside the current node, by its bounds (arrays, not `Vec3`, so the
/// per-axis loops index without glam's checked `match`).
#[derive(Clone, Copy, Debug)]
pub(super) struct Ref {
    pub lo: [f32; 3],
    pub hi: [f32; 3],
    pub prim: u32,
}

/// The bins of one node: `count` equal slices of the node box on each axis.
pub(super) struct Grid {
    pub count: usize,
    pub origin: [f32; 3],
    pub extent: [f32; 3],
    inv_width: [f32; 3],
}

impl Grid {
    pub fn new(node_box: &Aabb, count: usize) -> Grid {
        let extent = (node_box.max - node_box.min).to_array();
        Grid {
            count,
            origin: node_box.min.to_array(),
            extent,
            inv_width: extent.map(|e| if e > 0.0 { count as f32 / e } else { 0.0 }),
        }
    }

    /// The bin of coordinate `x` on `axis` (`as usize` saturates and maps NaN to 0; the min keeps
    /// the node's upper face in the last bin). Counting and refinement both bin through here.
    #[inline]
    pub fn bin(&self, x: f32, axis: usize) -> usize {
        (((x - self.origin[axis]) * self.inv_width[axis]).min((self.count - 1) as f32)) as usize
    }
}

/// Per-axis counts of references by the bin of their lower bound and of their upper bound.
pub(super) struct Bins {
    pub count: usize,
    /// `[axis][lower, upper][bin]`, flattened.
    pub counts: Vec<u32>,
}

thread_local! {
    /// The bin counts' storage, reused from node to node on each thread.
    pub(super) static BIN_STORE: RefCell<Vec<u32>> = const { RefCell::new(Vec::new()) };
}

impl Bins {
    pub fn with_storage(count: usize, mut counts: Vec<u32>) -> Bins {
        counts.clear();
        counts.resize(6 * count, 0);
        Bins { count, counts }
    }

    pub fn lo(&self, axis: usize) -> &[u32] {
        &self.counts[2 * axis * self.count..][..self.count]
    }

    pub fn hi(&self, axis: usize) -> &[u32] {
        &self.counts[(2 * axis + 1) * self.count..][..self.count]
    }

    pub fn add(&mut self, refs: &[Ref], grid: &Grid) {
        let c = self.count;
        let counts = &mut self.counts[..6 * c];
        for r in refs {
            for a in 0..3 {
                counts[2 * a * c + grid.bin(r.lo[a], a)] += 1;
                counts[(2 * a + 1) * c + grid.bin(r.hi[a], a)] += 1;
            }
        }
    }

    pub fn merge(mut self, o: Bins) -> Bins {
        for (x, y) in self.counts.iter_mut().zip(&o.counts) {
            *x += y;
        }
        self
    }
}
