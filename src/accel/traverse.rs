//! Iterative front-to-back kd-tree traversal with a fixed stack (one entry per tree level at most).
//! Closest-hit stops as soon as the best hit lies before the next node's entry distance; any-hit
//! returns at the first hit. Rays parallel to a split plane, starting on one, or with zero
//! direction components are handled explicitly rather than through inf/NaN arithmetic.

use super::tree::{KdTree, MAX_DEPTH};
use super::triangle::{RayPre, intersect};
use super::triangle4::intersect4;
use super::{Hit, Ray};
use glam::Vec3;
use std::mem::MaybeUninit;

pub(super) const STACK: usize = MAX_DEPTH as usize + 4;

/// What a walk did, for explaining speed (`bench accel`); the renderer counts nothing.
pub trait Tally {
    fn inner(&mut self) {}
    fn leaf(&mut self) {}
    fn test(&mut self) {}
}

/// The renderer's tally: every count compiles away.
pub struct NoTally;

impl Tally for NoTally {}

/// Inner nodes visited, leaves visited and ray-triangle tests run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WalkCounts {
    pub inner: u64,
    pub leaves: u64,
    pub tests: u64,
}

impl WalkCounts {
    pub fn add(&mut self, o: &WalkCounts) {
        self.inner += o.inner;
        self.leaves += o.leaves;
        self.tests += o.tests;
    }
}

impl Tally for WalkCounts {
    fn inner(&mut self) {
        self.inner += 1;
    }
    fn leaf(&mut self) {
        self.leaves += 1;
    }
    fn test(&mut self) {
        self.tests += 1;
    }
}

/// A ray prepared for walking: the components as arrays, so that the walk indexes them by axis
/// without glam's per-index `match`, and the reciprocal direction, so that each inner node costs
/// a multiplication where a division stalled the walk (the profile's hottest instruction was the
/// comparison waiting on that division).
pub(super) struct WalkRay {
    pub origin: [f32; 4],
    pub dir: [f32; 4],
    /// `1 / dir` per axis (infinite on a zero component, which the walks test before using it).
    pub inv_dir: [f32; 4],
}

impl WalkRay {
    /// The ray's parametric interval inside a box (`Aabb::clip_ray` without its divisions).
    #[inline]
    pub fn clip(&self, b: &super::Aabb, t_max: f32) -> Option<(f32, f32)> {
        let three = |v: [f32; 4]| [v[0], v[1], v[2]];
        b.clip(
            three(self.origin),
            three(self.dir),
            three(self.inv_dir),
            t_max,
        )
    }

    pub fn new(ray: &Ray) -> WalkRay {
        let dir = ray.dir.extend(0.0).to_array();
        WalkRay {
            origin: ray.origin.extend(0.0).to_array(),
            dir,
            inv_dir: dir.map(|d| 1.0 / d),
        }
    }
}

/// What a walk does at the leaves it reaches, front to back.
pub(super) trait Visit {
    /// Nothing past this distance matters any more (for closest hit, the best hit so far).
    fn limit(&self) -> f32;
    /// Tests a leaf's references; `true` ends the walk.
    fn leaf(&mut self, prims: &[u32]) -> bool;
    /// An inner node was visited.
    fn inner(&mut self);
}

/// Asks the cache for what `p` points to, ahead of its use. The walk asks for a node it may
/// visit next: the below child sits next to its parent; the above child is a subtree away and,
/// on a tree larger than the cache, a miss the walk would otherwise wait for when it goes there
/// (about half the time).
#[inline(always)]
pub fn prefetch<T>(p: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch is a hint: it reads nothing into the program and cannot fault.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(
            (p as *const T).cast(),
        );
    }
}

impl LeafWalk for KdTree {
    fn triangles(&self) -> &[[Vec3; 3]] {
        &self.triangles
    }

    #[inline]
    fn walk(&self, ray: &WalkRay, t_max: f32, visit: &mut impl Visit) {
        if self.nodes.is_empty() || self.bounds.is_empty() {
            return;
        }
        let Some((mut t_min, mut t_far)) = ray.clip(&self.bounds, t_max) else {
            return;
        };
        // Uninitialised: a ray that never pushes pays nothing for the stack.
        let mut stack = [const { MaybeUninit::<(u32, f32, f32)>::uninit() }; STACK];
        let mut sp = 0;
        let mut node = 0usize;
        loop {
            if visit.limit() < t_min {
                break;
            }
            let n = self.nodes[node];
            if n.is_leaf() {
                if sp > 0 {
                    // The node the walk resumes at comes in while the leaf is tested.
                    // SAFETY: every entry below `sp` was written by a push below.
                    prefetch(&self.nodes[unsafe { stack[sp - 1].assume_init_ref() }.0 as usize]);
                }
                if visit.leaf(&self.prim_refs[n.leaf_range()]) || sp == 0 {
                    break;
                }
                sp -= 1;
                // SAFETY: every entry below `sp` was written by a push below.
                let (next, a, b) = unsafe { stack[sp].assume_init() };
                node = next as usize;
                t_min = a;
                t_far = b;
                continue;
            }
            visit.inner();
            let axis = n.axis();
            let split = n.split();
            let (o, d, inv_d) = (ray.origin[axis], ray.dir[axis], ray.inv_dir[axis]);
            let below = node + 1;
            let above = node + n.above_offset();
            prefetch(&self.nodes[above]);
            let below_first = o < split || (o == split && d <= 0.0);
            let (first, second) = if below_first {
                (below, above)
            } else {
                (above, below)
            };
            if d == 0.0 {
                if o == split {
                    // The ray lies in the split plane: triangles in it may sit on either side.
                    stack[sp].write((second as u32, t_min, t_far));
                    sp += 1;
                }
                node = first;
                continue;
            }
            let t_plane = (split - o) * inv_d;
            if t_plane > t_far || t_plane <= 0.0 {
                node = first;
            } else if t_plane < t_min {
                node = second;
            } else {
                stack[sp].write((second as u32, t_plane, t_far));
                sp += 1;
                node = first;
                t_far = t_plane;
            }
        }
    }
}

/// A tree whose leaves list indices into its own triangles, walked front to back: the static
/// kd-tree and the refitted one differ only in how they walk, not in what a leaf does.
pub(super) trait LeafWalk {
    fn triangles(&self) -> &[[Vec3; 3]];
    fn walk(&self, ray: &WalkRay, t_max: f32, visit: &mut impl Visit);
}

/// The last triangles a ray tested, hashed by index (Mitsuba's kd-tree keeps the same per-ray
/// mailbox, 8 slots). With perfect splits a triangle is referenced by every leaf its clipped
/// pieces reach (4-5 leaves on large meshes), and a ray crossing several of them would test it
/// again in each. Skipping a retest is exact: a triangle that missed within the current limit
/// misses within any later, smaller limit, and one that hit set the best hit already. Only
/// leaves of one triangle consult it; larger ones test four triangles at once (`intersect4`)
/// and test again what they tested, which for the same reason changes no result.
struct Mailbox([u32; 8]);

impl Mailbox {
    fn new() -> Mailbox {
        Mailbox([u32::MAX; 8])
    }

    /// Whether `prim` was tested already; records it otherwise.
    #[inline]
    fn seen(&mut self, prim: u32) -> bool {
        let slot = &mut self.0[prim as usize & 7];
        let seen = *slot == prim;
        *slot = prim;
        seen
    }
}

/// The leaf tests of a walk. Closest hit (`ANY = false`): every triangle against the best
/// distance so far. Any hit (`ANY = true`): the walk ends at the first triangle hit before
/// `t_max`, which stays the limit. A leaf's triangles are tested four at a time, in their
/// order, keeping what testing them one by one keeps. Single rays (`bench accel --walk single`,
/// two alternating rounds on bunny, bunny_loop1, TransmissionTest, MetalRoughSpheresNoTextures
/// and the 1M peer mesh) ran 16-28% more camera and 32-51% more shadow rays a second than one
/// at a time, at about the same instruction count (the peer mesh's single walks: 8.55G -> 8.49G,
/// callgrind): four independent tests overlap where one test's steps wait on each other.
struct LeafTests<'a, T: Tally, const ANY: bool> {
    mailbox: Mailbox,
    pre: RayPre,
    triangles: &'a [[Vec3; 3]],
    best: f32,
    hit: Option<Hit>,
    tally: &'a mut T,
}

impl<'a, T: Tally, const ANY: bool> LeafTests<'a, T, ANY> {
    fn new(tree: &'a impl LeafWalk, ray: &Ray, t_max: f32, tally: &'a mut T) -> Self {
        LeafTests {
            mailbox: Mailbox::new(),
            pre: RayPre::new(ray),
            triangles: tree.triangles(),
            best: t_max,
            hit: None,
            tally,
        }
    }
}

impl<T: Tally, const ANY: bool> Visit for LeafTests<'_, T, ANY> {
    #[inline]
    fn limit(&self) -> f32 {
        self.best
    }

    #[inline]
    fn leaf(&mut self, prims: &[u32]) -> bool {
        self.tally.leaf();
        // Every triangle of the leaf is asked for before the first is tested, so their cache
        // misses overlap instead of following one another.
        for &p in prims {
            prefetch(&self.triangles[p as usize]);
        }
        if let [p] = *prims {
            if self.mailbox.seen(p) {
                return false;
            }
            self.tally.test();
            if let Some((t, b1, b2)) = intersect(&self.pre, &self.triangles[p as usize], self.best)
            {
                self.hit = Some(Hit { t, prim: p, b1, b2 });
                if ANY {
                    return true;
                }
                self.best = t;
            }
            return false;
        }
        // Four triangles a test, the last group padded with its last triangle (tested again,
        // it changes nothing).
        for group in prims.chunks(4) {
            let idx: [u32; 4] = std::array::from_fn(|i| group[i.min(group.len() - 1)]);
            for _ in group {
                self.tally.test();
            }
            let tris = idx.map(|p| &self.triangles[p as usize]);
            let (hit, [t, b1, b2]) = intersect4(&self.pre, tris, self.best);
            if hit == 0 {
                continue;
            }
            // What testing them one by one against the best so far keeps: the first hit of an
            // any-hit walk, else the nearest, the first of equally near ones.
            let mut k = hit.trailing_zeros() as usize;
            if !ANY {
                for i in (k + 1..4).filter(|i| hit >> i & 1 == 1) {
                    if t[i] < t[k] {
                        k = i;
                    }
                }
            }
            self.hit = Some(Hit {
                t: t[k],
                prim: idx[k],
                b1: b1[k],
                b2: b2[k],
            });
            if ANY {
                return true;
            }
            self.best = t[k];
        }
        false
    }

    #[inline]
    fn inner(&mut self) {
        self.tally.inner();
    }
}

/// One ray's walk: its closest hit (`ANY = false`) or the first hit found (`ANY = true`).
pub(super) fn walk_one<const ANY: bool>(
    tree: &impl LeafWalk,
    ray: &Ray,
    t_max: f32,
    tally: &mut impl Tally,
) -> Option<Hit> {
    let mut v = LeafTests::<_, ANY>::new(tree, ray, t_max, tally);
    tree.walk(&WalkRay::new(ray), t_max, &mut v);
    v.hit
}

pub(super) fn closest_hit(
    tree: &impl LeafWalk,
    ray: &Ray,
    t_max: f32,
    tally: &mut impl Tally,
) -> Option<Hit> {
    walk_one::<false>(tree, ray, t_max, tally)
}

pub(super) fn any_hit(tree: &impl LeafWalk, ray: &Ray, t_max: f32, tally: &mut impl Tally) -> bool {
    walk_one::<true>(tree, ray, t_max, tally).is_some()
}

#[cfg(test)]
mod tests {
    use super::super::test_rng::Lcg;
    use super::super::{BruteForce, BuildParams, Intersect, SplitMethod};
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
