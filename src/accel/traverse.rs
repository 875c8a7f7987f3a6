//! Iterative front-to-back kd-tree traversal with a fixed stack (one entry per tree level at most).
//! Closest-hit stops as soon as the best hit lies before the next node's entry distance; any-hit
//! returns at the first hit. Rays parallel to a split plane, starting on one, or with zero
//! direction components are handled explicitly rather than through inf/NaN arithmetic.

use super::tree::{KdTree, MAX_DEPTH};
use super::triangle::{RayPre, intersect};
use super::{Hit, Intersect, Ray};
use glam::Vec3;

const STACK: usize = MAX_DEPTH as usize + 4;

impl LeafWalk for KdTree {
    fn triangles(&self) -> &[[Vec3; 3]] {
        &self.triangles
    }

    #[inline]
    fn walk(&self, ray: &Ray, t_max: f32, mut on_leaf: impl FnMut(&[u32], f32) -> (f32, bool)) {
        if self.nodes.is_empty() || self.bounds.is_empty() {
            return;
        }
        let Some((mut t_min, mut t_far)) = self.bounds.clip_ray(ray, t_max) else {
            return;
        };
        let mut best = t_max;
        let mut stack = [(0u32, 0f32, 0f32); STACK];
        let mut sp = 0;
        let mut node = 0usize;
        loop {
            if best < t_min {
                break;
            }
            let n = self.nodes[node];
            if n.is_leaf() {
                let (b, stop) = on_leaf(&self.prim_refs[n.leaf_range()], best);
                best = b;
                if stop || sp == 0 {
                    break;
                }
                sp -= 1;
                let (next, a, b) = stack[sp];
                node = next as usize;
                t_min = a;
                t_far = b;
                continue;
            }
            let axis = n.axis();
            let split = n.split();
            let (o, d) = (ray.origin[axis], ray.dir[axis]);
            let below = node + 1;
            let above = node + n.above_offset();
            let below_first = o < split || (o == split && d <= 0.0);
            let (first, second) = if below_first {
                (below, above)
            } else {
                (above, below)
            };
            if d == 0.0 {
                if o == split {
                    // The ray lies in the split plane: triangles in it may sit on either side.
                    stack[sp] = (second as u32, t_min, t_far);
                    sp += 1;
                }
                node = first;
                continue;
            }
            let t_plane = (split - o) / d;
            if t_plane > t_far || t_plane <= 0.0 {
                node = first;
            } else if t_plane < t_min {
                node = second;
            } else {
                stack[sp] = (second as u32, t_plane, t_far);
                sp += 1;
                node = first;
                t_far = t_plane;
            }
        }
    }
}

impl Intersect for KdTree {
    fn closest_hit(&self, ray: &Ray, t_max: f32) -> Option<Hit> {
        closest_hit(self, ray, t_max)
    }

    fn any_hit(&self, ray: &Ray, t_max: f32) -> bool {
        any_hit(self, ray, t_max)
    }
}

/// A tree whose leaves list indices into its own triangles, walked front to back: the static
/// kd-tree and the refitted one differ only in how they walk, not in what a leaf does.
pub(super) trait LeafWalk {
    fn triangles(&self) -> &[[Vec3; 3]];
    /// Visits leaves front to back; `on_leaf` tests a leaf against the current best distance
    /// and returns the new best and whether to stop.
    fn walk(&self, ray: &Ray, t_max: f32, on_leaf: impl FnMut(&[u32], f32) -> (f32, bool));
}

/// Closest hit over a walk: every leaf's triangles against the best distance so far.
pub(super) fn closest_hit(tree: &impl LeafWalk, ray: &Ray, t_max: f32) -> Option<Hit> {
    let pre = RayPre::new(ray);
    let triangles = tree.triangles();
    let mut hit = None;
    tree.walk(ray, t_max, |prims, mut best| {
        for &p in prims {
            if let Some((t, b1, b2)) = intersect(&pre, &triangles[p as usize], best) {
                best = t;
                hit = Some(Hit { t, prim: p, b1, b2 });
            }
        }
        (best, false)
    });
    hit
}

/// Any hit over a walk: stops at the first leaf with a hit.
pub(super) fn any_hit(tree: &impl LeafWalk, ray: &Ray, t_max: f32) -> bool {
    let pre = RayPre::new(ray);
    let triangles = tree.triangles();
    let mut found = false;
    tree.walk(ray, t_max, |prims, best| {
        found = prims
            .iter()
            .any(|&p| intersect(&pre, &triangles[p as usize], best).is_some());
        (best, found)
    });
    found
}

#[cfg(test)]
mod tests {
    use super::super::test_rng::Lcg;
    use super::super::{BruteForce, BuildParams, SplitMethod};
    use super::*;

    fn soup(rng: &mut Lcg, n: usize) -> Vec<[Vec3; 3]> {
        (0..n)
            .map(|_| {
                let c = rng.v(10.0);
                [c, c + rng.v(1.0) - 0.5, c + rng.v(1.0) - 0.5]
            })
            .collect()
    }

    fn agree(tris: Vec<[Vec3; 3]>, rays: &[Ray], method: SplitMethod) {
        let brute = BruteForce {
            triangles: tris.clone(),
        };
        let tree = KdTree::build(tris, BuildParams::with_method(method));
        for r in rays {
            let a = tree.closest_hit(r, f32::INFINITY);
            let b = brute.closest_hit(r, f32::INFINITY);
            assert_eq!(a.map(|h| h.t), b.map(|h| h.t), "{method:?} ray {r:?}");
            assert_eq!(tree.any_hit(r, f32::INFINITY), b.is_some());
        }
    }

    #[test]
    fn every_split_method_finds_the_brute_force_closest_hit() {
        let mut rng = Lcg(7);
        let tris = soup(&mut rng, 2000);
        let rays: Vec<Ray> = (0..2000)
            .map(|_| Ray::new(rng.v(14.0) - 2.0, rng.v(2.0) - 1.0))
            .collect();
        for m in [SplitMethod::Sah, SplitMethod::Center, SplitMethod::Median] {
            agree(tris.clone(), &rays, m);
        }
    }

    #[test]
    fn axis_aligned_rays_and_planar_triangles_on_split_candidates() {
        // A grid of unit quads in the plane z = 0 and walls at integer x: every triangle lies on a
        // candidate plane, and rays run exactly along planes.
        let mut tris = Vec::new();
        for i in 0..8 {
            for j in 0..8 {
                let (x, y) = (i as f32, j as f32);
                tris.push([
                    Vec3::new(x, y, 0.0),
                    Vec3::new(x + 1.0, y, 0.0),
                    Vec3::new(x, y + 1.0, 0.0),
                ]);
                tris.push([
                    Vec3::new(x, 0.0, y),
                    Vec3::new(x, 1.0, y),
                    Vec3::new(x, 0.0, y + 1.0),
                ]);
            }
        }
        let mut rays = Vec::new();
        for i in 0..40 {
            let f = i as f32 * 0.2;
            rays.push(Ray::new(Vec3::new(f, 0.3, 5.0), Vec3::NEG_Z));
            rays.push(Ray::new(Vec3::new(-3.0, 0.5, f), Vec3::X));
            rays.push(Ray::new(Vec3::new(3.0, 0.5, f), Vec3::NEG_X));
            rays.push(Ray::new(Vec3::new(f, 0.5, 0.0), Vec3::new(0.0, 1.0, 1.0)));
        }
        for m in [SplitMethod::Sah, SplitMethod::Center, SplitMethod::Median] {
            agree(tris.clone(), &rays, m);
        }
    }

    #[test]
    fn coincident_triangles_and_an_empty_scene() {
        let t = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let tree = KdTree::build(vec![t; 3000], BuildParams::default());
        let r = Ray::new(Vec3::new(0.2, 0.2, 1.0), Vec3::NEG_Z);
        assert!(tree.closest_hit(&r, f32::INFINITY).is_some());
        let empty = KdTree::build(Vec::new(), BuildParams::default());
        assert!(empty.closest_hit(&r, f32::INFINITY).is_none());
        assert!(!empty.any_hit(&r, f32::INFINITY));
    }
}
