//! Watertight ray-triangle intersection (Woop, Benthin and Wald, "Watertight Ray/Triangle
//! Intersection", JCGT 2013). The ray is sheared so that it runs along +Z; the edge functions of
//! the projected triangle then decide the hit with no epsilon, so a ray through a shared edge or
//! vertex hits at least one of the triangles meeting there, and never slips between them. Edge
//! functions that come out exactly zero are recomputed in f64, as the paper prescribes.

use super::Ray;
use glam::Vec3;

/// Per-ray constants of the shear transform.
pub struct RayPre {
    pub origin: Vec3,
    kx: usize,
    ky: usize,
    kz: usize,
    sx: f32,
    sy: f32,
    sz: f32,
}

impl RayPre {
    pub fn new(ray: &Ray) -> RayPre {
        let d = ray.dir;
        let a = d.abs();
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        // Keep the winding of the projected triangle independent of the ray's direction sign.
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        RayPre {
            origin: ray.origin,
            kx,
            ky,
            kz,
            sx: d[kx] / d[kz],
            sy: d[ky] / d[kz],
            sz: 1.0 / d[kz],
        }
    }
}

/// Distance and barycentrics `(t, b1, b2)` of a hit with `0 < t < t_max`, both faces counted.
#[inline]
pub fn intersect(pre: &RayPre, tri: &[Vec3; 3], t_max: f32) -> Option<(f32, f32, f32)> {
    let a = tri[0] - pre.origin;
    let b = tri[1] - pre.origin;
    let c = tri[2] - pre.origin;
    let (kx, ky, kz) = (pre.kx, pre.ky, pre.kz);
    let ax = a[kx] - pre.sx * a[kz];
    let ay = a[ky] - pre.sy * a[kz];
    let bx = b[kx] - pre.sx * b[kz];
    let by = b[ky] - pre.sy * b[kz];
    let cx = c[kx] - pre.sx * c[kz];
    let cy = c[ky] - pre.sy * c[kz];
    let mut u = cx * by - cy * bx;
    let mut v = ax * cy - ay * cx;
    let mut w = bx * ay - by * ax;
    if u == 0.0 || v == 0.0 || w == 0.0 {
        u = (cx as f64 * by as f64 - cy as f64 * bx as f64) as f32;
        v = (ax as f64 * cy as f64 - ay as f64 * cx as f64) as f32;
        w = (bx as f64 * ay as f64 - by as f64 * ax as f64) as f32;
    }
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + v + w;
    if det == 0.0 {
        return None;
    }
    let az = pre.sz * a[kz];
    let bz = pre.sz * b[kz];
    let cz = pre.sz * c[kz];
    let t_scaled = u * az + v * bz + w * cz;
    let inv_det = 1.0 / det;
    let t = t_scaled * inv_det;
    if !(t > 0.0 && t < t_max) {
        return None;
    }
    Some((t, v * inv_det, w * inv_det))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> [Vec3; 3] {
        [
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ]
    }

    #[test]
    fn hit_distance_and_barycentrics_reconstruct_the_point() {
        let ray = Ray::new(Vec3::new(0.2, 0.1, 2.0), Vec3::new(0.0, 0.0, -1.0));
        let (t, b1, b2) = intersect(&RayPre::new(&ray), &tri(), f32::INFINITY).unwrap();
        assert!((t - 2.0).abs() < 1e-6);
        let [a, b, c] = tri();
        let p = a * (1.0 - b1 - b2) + b * b1 + c * b2;
        assert!((p - Vec3::new(0.2, 0.1, 0.0)).length() < 1e-6);
    }

    #[test]
    fn both_faces_hit_and_t_max_excludes() {
        let from_below = Ray::new(Vec3::new(0.0, 0.0, -1.0), Vec3::Z);
        assert!(intersect(&RayPre::new(&from_below), &tri(), f32::INFINITY).is_some());
        assert!(intersect(&RayPre::new(&from_below), &tri(), 0.99).is_none());
        let away = Ray::new(Vec3::new(0.0, 0.0, 1.0), Vec3::Z);
        assert!(intersect(&RayPre::new(&away), &tri(), f32::INFINITY).is_none());
    }

    #[test]
    fn ray_through_a_shared_edge_hits_exactly_one_of_two_triangles_or_both() {
        // Two triangles sharing the edge x = 0; rays exactly on the edge must not pass between.
        let left = [
            Vec3::new(0.0, -1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(-1.0, 0.0, 0.0),
        ];
        let right = [
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, -1.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
        ];
        for i in 0..200 {
            let y = -0.99 + i as f32 * 0.0099;
            let ray = Ray::new(Vec3::new(0.0, y, 1.0), Vec3::new(0.0, 0.0, -1.0));
            let pre = RayPre::new(&ray);
            let hits = [left, right]
                .iter()
                .filter(|t| intersect(&pre, t, f32::INFINITY).is_some())
                .count();
            assert!(hits >= 1, "ray at y={y} slipped through the shared edge");
        }
    }
}
