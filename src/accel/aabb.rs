//! The axis-aligned box: the one piece of geometry the builders, the traversals, the refit and
//! the instance top level all share. It lives apart so that none of them imports another.

use super::Ray;
use glam::{Mat4, Vec3};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    pub fn of_points(points: &[Vec3]) -> Aabb {
        points.iter().fold(Aabb::EMPTY, |b, &p| Aabb {
            min: b.min.min(p),
            max: b.max.max(p),
        })
    }

    /// The smallest box holding both.
    pub fn union(&self, o: &Aabb) -> Aabb {
        Aabb {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    pub fn is_empty(&self) -> bool {
        !(self.min.x <= self.max.x && self.min.y <= self.max.y && self.min.z <= self.max.z)
    }

    pub fn intersection(&self, o: &Aabb) -> Aabb {
        Aabb {
            min: self.min.max(o.min),
            max: self.max.min(o.max),
        }
    }

    pub fn surface_area(&self) -> f32 {
        if self.is_empty() {
            return 0.0;
        }
        let d = self.max - self.min;
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    }

    pub fn longest_axis(&self) -> usize {
        let d = self.max - self.min;
        if d.x >= d.y && d.x >= d.z {
            0
        } else if d.y >= d.z {
            1
        } else {
            2
        }
    }

    /// The box around the eight transformed corners (an empty box stays empty).
    pub fn transformed(&self, m: &Mat4) -> Aabb {
        if self.is_empty() {
            return *self;
        }
        let corners: [Vec3; 8] = std::array::from_fn(|i| {
            m.transform_point3(Vec3::new(
                if i & 1 == 0 { self.min.x } else { self.max.x },
                if i & 2 == 0 { self.min.y } else { self.max.y },
                if i & 4 == 0 { self.min.z } else { self.max.z },
            ))
        });
        Aabb::of_points(&corners)
    }

    /// Parametric interval `(t0, t1)` of a ray inside the box, clipped to `(0, t_max)`; `None`
    /// when it misses. Zero direction components are tested explicitly rather than through
    /// inf/NaN arithmetic.
    pub fn clip_ray(&self, ray: &Ray, t_max: f32) -> Option<(f32, f32)> {
        let (o, d) = (ray.origin.to_array(), ray.dir.to_array());
        self.clip(o, d, d.map(|d| 1.0 / d), t_max)
    }

    /// `clip_ray` with the ray's reciprocal direction already computed (a walk has it).
    #[inline]
    pub fn clip(
        &self,
        origin: [f32; 3],
        dir: [f32; 3],
        inv_dir: [f32; 3],
        t_max: f32,
    ) -> Option<(f32, f32)> {
        let (mut t0, mut t1) = (0.0f32, t_max);
        let (min, max) = (self.min.to_array(), self.max.to_array());
        for axis in 0..3 {
            let (o, d, inv) = (origin[axis], dir[axis], inv_dir[axis]);
            let (lo, hi) = (min[axis], max[axis]);
            if d == 0.0 {
                if o < lo || o > hi {
                    return None;
                }
                continue;
            }
            let (mut near, mut far) = ((lo - o) * inv, (hi - o) * inv);
            if near > far {
                std::mem::swap(&mut near, &mut far);
            }
            t0 = t0.max(near);
            t1 = t1.min(far);
            if t0 > t1 {
                return None;
            }
        }
        Some((t0, t1))
    }

    /// The two halves of the box cut at `pos` on `axis`.
    pub fn split(&self, axis: usize, pos: f32) -> (Aabb, Aabb) {
        let mut below = *self;
        let mut above = *self;
        below.max[axis] = pos;
        above.min[axis] = pos;
        (below, above)
    }
}
