//! Watertight ray-triangle intersection (Woop, Benthin and Wald, "Watertight Ray/Triangle
//! Intersection", JCGT 2013). The ray is sheared so that it runs along +Z; the edge functions of
//! the projected triangle then decide the hit with no epsilon, so a ray through a shared edge or
//! vertex hits at least one of the triangles meeting there, and never slips between them. Edge
//! functions that come out exactly zero are recomputed in f64, as the paper prescribes.

use super::lanes::{F4, LaneMask, Lanes};
use super::{Hit, Ray};
use glam::{Mat3A, Vec3, Vec3A};

/// Per-ray constants of the shear transform, stored as a 3x3 matrix so that a vertex's sheared
/// coordinates are one SIMD matrix-vector product: `x = v[kx] - sx v[kz]` is row x of the matrix
/// (1 at `kx`, `-sx` at `kz`) times `v`. Each lane sums its three products in the order a dot
/// product would, and the exact zeros of the other terms change no bit of the result; `intersect`
/// picks no component by a runtime index (the four-triangle test, `triangle4.rs`, does, once
/// per vertex for four triangles).
pub struct RayPre {
    pub(super) origin: Vec3A,
    shear: Mat3A,
    /// The shear's axes `[kx, ky, kz]` and its column `kz`, `(-sx, -sy, sz)`, for
    /// `triangle4::intersect4`.
    pub(super) axes: [usize; 3],
    pub(super) shear_kz: [f32; 3],
}

impl RayPre {
    #[inline]
    pub fn new(ray: &Ray) -> RayPre {
        let d = ray.dir;
        let (kx, ky, kz) = shear_axes(d);
        let [dx, dy, dz] = [kx, ky, kz].map(|k| match k {
            0 => d.x,
            1 => d.y,
            _ => d.z,
        });
        let (sx, sy, sz) = (dx / dz, dy / dz, 1.0 / dz);
        // The shear's rows are `e_kx - sx e_kz`, `e_ky - sy e_kz` and `sz e_kz`; its columns are
        // therefore the unit vectors at `kx` and `ky` and `(-sx, -sy, sz)` at `kz`.
        let cols = [Vec3A::X, Vec3A::Y, Vec3A::new(-sx, -sy, sz)];
        let order = [kx, ky, kz];
        let mut shear = [Vec3A::ZERO; 3];
        for (col, &k) in cols.iter().zip(&order) {
            shear[k] = *col;
        }
        RayPre {
            origin: ray.origin.into(),
            shear: Mat3A::from_cols(shear[0], shear[1], shear[2]),
            axes: order,
            shear_kz: [-sx, -sy, sz],
        }
    }
}

/// Distance and barycentrics `(t, b1, b2)` of a hit with `0 < t < t_max`, both faces counted.
#[inline]
pub fn intersect(pre: &RayPre, tri: &[Vec3; 3], t_max: f32) -> Option<(f32, f32, f32)> {
    let a = pre.shear * (Vec3A::from(tri[0]) - pre.origin);
    let b = pre.shear * (Vec3A::from(tri[1]) - pre.origin);
    let c = pre.shear * (Vec3A::from(tri[2]) - pre.origin);
    let (ax, ay) = (a.x, a.y);
    let (bx, by) = (b.x, b.y);
    let (cx, cy) = (c.x, c.y);
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
    let (az, bz, cz) = (a.z, b.z, c.z);
    let t_scaled = u * az + v * bz + w * cz;
    // Most candidates that pass the edge tests lie behind the origin (a shadow ray's own
    // triangle) or beyond the best hit: reject those before the division. `t_scaled` with the
    // sign of `det` is positive exactly when `t` is. The far test keeps a margin of 8 ulps over
    // the rounding of the division below and is skipped when `t_max * |det|` is subnormal (its
    // relative error unbounded there), so it only rejects what the exact test rejects too.
    let sign = det.to_bits() & 0x8000_0000;
    let t_signed = f32::from_bits(t_scaled.to_bits() ^ sign);
    let far = t_max * det.abs();
    // NaN fails `> 0` as it fails the exact test below.
    let ahead = t_signed > 0.0;
    if !ahead || (far >= f32::MIN_POSITIVE && t_signed > far * (1.0 + 8.0 * f32::EPSILON)) {
        return None;
    }
    let inv_det = 1.0 / det;
    let t = t_scaled * inv_det;
    if !(t > 0.0 && t < t_max) {
        return None;
    }
    Some((t, v * inv_det, w * inv_det))
}

/// The watertight test past its edge functions, lane by lane: from the edge functions `u`, `v`,
/// `w` and the sheared vertices' depths, the lanes outside `outside` that hit within `t_max`
/// (the scalar test's pre-test before the division, then its exact test), and every lane's
/// `(t, b1, b2)`. The same operations in the same order as `intersect`.
#[inline(always)]
pub(super) fn depths<L: Lanes<N>, const N: usize>(
    u: L,
    v: L,
    w: L,
    [az, bz, cz]: [L; 3],
    t_max: L,
    outside: u32,
) -> (u32, [[f32; N]; 3]) {
    let zero = L::splat(0.0);
    let det = u.add(v).add(w);
    let t_scaled = u.mul(az).add(v.mul(bz)).add(w.mul(cz));
    let t_signed = t_scaled.flip_sign_of(det);
    let far = t_max.mul(det.abs());
    let ahead = t_signed.gt(zero).bits();
    let beyond = far.ge(L::splat(f32::MIN_POSITIVE)).bits()
        & t_signed
            .gt(far.mul(L::splat(1.0 + 8.0 * f32::EPSILON)))
            .bits();
    let inv_det = L::splat(1.0).div(det);
    let t = t_scaled.mul(inv_det);
    let in_range = t.gt(zero).bits() & t.lt(t_max).bits();
    let hit = !outside & !det.eq(zero).bits() & ahead & !beyond & in_range;
    (
        hit,
        [
            t.to_array(),
            v.mul(inv_det).to_array(),
            w.mul(inv_det).to_array(),
        ],
    )
}

/// `N` rays' `RayPre`, lane by lane, so that one triangle is tested against `N` rays at once
/// (four in `F4`'s lanes, eight in `F8`'s).
pub(super) struct RayPack<L, const N: usize> {
    origin: [L; 3],
    /// `cols[c][r]`: row `r` of the shear's column `c`, per lane.
    cols: [[L; 3]; 3],
    rays: [Ray; N],
}

/// Four rays' `RayPre`, in SSE lanes.
pub(super) type RayPre4 = RayPack<F4, 4>;

impl<L: Lanes<N>, const N: usize> RayPack<L, N> {
    /// The shear of each ray exactly as `RayPre::new` builds it (the same axis choice and the
    /// same three divisions per ray, `N` rays to a division instruction).
    #[inline(always)]
    pub(super) fn new(rays: [Ray; N]) -> Self {
        let mut axes = [[0usize; 3]; N];
        let mut pick = [[0.0f32; N]; 3];
        for (i, r) in rays.iter().enumerate() {
            let (kx, ky, kz) = shear_axes(r.dir);
            axes[i] = [kx, ky, kz];
            let d = r.dir.to_array();
            (pick[0][i], pick[1][i], pick[2][i]) = (d[kx], d[ky], d[kz]);
        }
        // No `array::map` over lane constructors here: the eight-lane walk needs every lane
        // operation inlined (see `KdTree::batch_in`).
        let (dx, dy, dz) = (L::new(pick[0]), L::new(pick[1]), L::new(pick[2]));
        let sx = dx.div(dz).to_array();
        let sy = dy.div(dz).to_array();
        let sz = L::splat(1.0).div(dz).to_array();
        // Column `kx` is the unit x vector, column `ky` unit y, column `kz` (-sx, -sy, sz).
        let mut cols = [[[0.0f32; N]; 3]; 3];
        for (i, [kx, ky, kz]) in axes.into_iter().enumerate() {
            cols[kx][0][i] = 1.0;
            cols[ky][1][i] = 1.0;
            (cols[kz][0][i], cols[kz][1][i], cols[kz][2][i]) = (-sx[i], -sy[i], sz[i]);
        }
        let mut origin = [[0.0f32; N]; 3];
        for (i, r) in rays.iter().enumerate() {
            (origin[0][i], origin[1][i], origin[2][i]) = (r.origin.x, r.origin.y, r.origin.z);
        }
        let lanes = |c: [[f32; N]; 3]| [L::new(c[0]), L::new(c[1]), L::new(c[2])];
        RayPack {
            origin: lanes(origin),
            cols: [lanes(cols[0]), lanes(cols[1]), lanes(cols[2])],
            rays,
        }
    }

    /// Lane `i`'s `v - origin`, the vector the shear multiplies.
    #[inline(always)]
    fn relative(&self, v: Vec3) -> [L; 3] {
        // Written out: `array::map` here is not always inlined, and the walk that calls it out
        // of line runs a third slower.
        [
            L::splat(v.x).sub(self.origin[0]),
            L::splat(v.y).sub(self.origin[1]),
            L::splat(v.z).sub(self.origin[2]),
        ]
    }

    /// Row `r` of lane `i`'s sheared vertex, from its `relative` vector: row `r` of
    /// `shear * rel` as glam computes it, `(x_axis * rel.x + y_axis * rel.y) + z_axis * rel.z`.
    #[inline(always)]
    fn row(&self, rel: &[L; 3], r: usize) -> L {
        self.cols[0][r]
            .mul(rel[0])
            .add(self.cols[1][r].mul(rel[1]))
            .add(self.cols[2][r].mul(rel[2]))
    }
}

/// The shear's axes for a direction: `kz` its largest component, `kx` and `ky` the next two in
/// cyclic order, swapped when `d[kz] < 0` so the projected winding does not depend on the sign.
#[inline]
fn shear_axes(d: Vec3) -> (usize, usize, usize) {
    let a = d.abs();
    let kz = if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    };
    let (kx, ky) = ((kz + 1) % 3, (kz + 2) % 3);
    if d[kz] < 0.0 {
        (ky, kx, kz)
    } else {
        (kx, ky, kz)
    }
}

/// `intersect` for the `N` rays of `pre` on the lanes set in `lanes`: bit `i` of the mask is set
/// where `intersect(lane i, tri, t_max[i])` hits, with its `(t, b1, b2)` in lane `i`. Each lane
/// runs the scalar test's IEEE operations in the same order, so results are bit for bit the
/// scalar ones; a lane with an edge function exactly zero (the f64 recompute) runs the scalar
/// test itself.
#[inline(always)]
pub(super) fn intersect_packet<L: Lanes<N>, const N: usize>(
    pre: &RayPack<L, N>,
    tri: &[Vec3; 3],
    t_max: L,
    lanes: u32,
) -> (u32, [[f32; N]; 3]) {
    let rel = [
        pre.relative(tri[0]),
        pre.relative(tri[1]),
        pre.relative(tri[2]),
    ];
    let (ax, ay) = (pre.row(&rel[0], 0), pre.row(&rel[0], 1));
    let (bx, by) = (pre.row(&rel[1], 0), pre.row(&rel[1], 1));
    let (cx, cy) = (pre.row(&rel[2], 0), pre.row(&rel[2], 1));
    let u = cx.mul(by).sub(cy.mul(bx));
    let v = ax.mul(cy).sub(ay.mul(cx));
    let w = bx.mul(ay).sub(by.mul(ax));
    let zero = L::splat(0.0);
    let exact_zero = u.eq(zero).or(v.eq(zero)).or(w.eq(zero)).bits() & lanes;
    let negative = u.lt(zero).or(v.lt(zero)).or(w.lt(zero)).bits();
    let positive = u.gt(zero).or(v.gt(zero)).or(w.gt(zero)).bits();
    // Most tests end here, every lane outside the triangle: the depths and the division are
    // computed only where a lane may still hit.
    if lanes & (exact_zero | !(negative & positive)) == 0 {
        return (0, [[0.0; N]; 3]);
    }
    let (az, bz, cz) = (
        pre.row(&rel[0], 2),
        pre.row(&rel[1], 2),
        pre.row(&rel[2], 2),
    );
    let (mut hit, mut out) = depths(
        u,
        v,
        w,
        [az, bz, cz],
        t_max,
        exact_zero | (negative & positive),
    );
    hit &= lanes;
    if exact_zero != 0 {
        let limits = t_max.to_array();
        for i in (0..N).filter(|i| exact_zero >> i & 1 == 1) {
            if let Some((t, b1, b2)) = intersect(&RayPre::new(&pre.rays[i]), tri, limits[i]) {
                hit |= 1 << i;
                [out[0][i], out[1][i], out[2][i]] = [t, b1, b2];
            }
        }
    }
    (hit, out)
}

/// For each ray of `rays` whose bit is set in `active`, the nearest hit within its `t_max`
/// among `candidates` (triangle index and vertices), visited in order: bit for bit what the
/// scalar loop finds that tests each candidate in turn with `intersect` up to the nearest hit
/// so far. Four rays share each triangle test.
pub fn nearest4(
    rays: [Ray; 4],
    active: u32,
    t_max: [f32; 4],
    candidates: impl Iterator<Item = (u32, [Vec3; 3])>,
) -> [Option<Hit>; 4] {
    let pre = RayPre4::new(rays);
    let mut limit = t_max;
    let mut best = [None; 4];
    for (prim, tri) in candidates {
        let (hits, [t, b1, b2]) = intersect_packet(&pre, &tri, F4::new(limit), active);
        for i in (0..4).filter(|i| hits >> i & 1 == 1) {
            limit[i] = t[i];
            best[i] = Some(Hit {
                t: t[i],
                prim,
                b1: b1[i],
                b2: b2[i],
            });
        }
    }
    best
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
    fn the_shear_is_the_papers_row_by_row() {
        let mut rng = crate::accel::test_rng::Lcg(9);
        for _ in 0..1000 {
            let d = rng.v(2.0) - Vec3::ONE;
            let pre = RayPre::new(&Ray::new(Vec3::ZERO, d));
            // Woop et al.'s listing: kz the largest component, kx and ky the next two, swapped
            // when d[kz] < 0; x = v[kx] - sx v[kz], y = v[ky] - sy v[kz], z = sz v[kz].
            let a = d.abs();
            let kz = if a.x >= a.y && a.x >= a.z {
                0
            } else if a.y >= a.z {
                1
            } else {
                2
            };
            let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
            if d[kz] < 0.0 {
                std::mem::swap(&mut kx, &mut ky);
            }
            let (sx, sy, sz) = (d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]);
            let rows = pre.shear.transpose();
            let expect = |k_one: Option<usize>, s: f32| {
                let mut r = Vec3A::ZERO;
                if let Some(k) = k_one {
                    r[k] = 1.0;
                }
                r[kz] = s;
                r
            };
            for (row, want) in [
                (rows.x_axis, expect(Some(kx), -sx)),
                (rows.y_axis, expect(Some(ky), -sy)),
                (rows.z_axis, expect(None, sz)),
            ] {
                assert_eq!(
                    row.to_array().map(f32::to_bits),
                    want.to_array().map(f32::to_bits)
                );
            }
        }
    }

    #[test]
    fn four_lanes_give_the_scalar_results_bit_for_bit() {
        let mut rng = crate::accel::test_rng::Lcg(3);
        let mut cases = 0;
        for k in 0..6000 {
            // Every fourth triangle is axis-aligned with integer corners and the rays run through
            // its edges and corners, where edge functions come out exactly zero.
            let grid = k % 4 == 0;
            let tri = if grid {
                [
                    Vec3::ZERO,
                    Vec3::new(2.0, 0.0, 0.0),
                    Vec3::new(0.0, 2.0, 0.0),
                ]
            } else {
                let c = rng.v(4.0);
                [c, c + rng.v(2.0) - 1.0, c + rng.v(2.0) - 1.0]
            };
            let rays: [Ray; 4] = std::array::from_fn(|i| {
                if grid {
                    let p = Vec3::new((k / 4 % 3) as f32, i as f32 * 0.5, 0.0);
                    Ray::new(
                        p + Vec3::Z * 3.0,
                        Vec3::NEG_Z + rng.v(1e-3) * (i % 2) as f32,
                    )
                } else {
                    Ray::new(rng.v(6.0) - 1.0, rng.v(2.0) - 1.0)
                }
            });
            let limits: [f32; 4] = std::array::from_fn(|i| match (k + i) % 4 {
                0 => f32::INFINITY,
                1 => 2.0,
                2 => rng.next() * 6.0,
                _ => 1e-30,
            });
            let pres = rays.map(|r| RayPre::new(&r));
            let pre4 = RayPre4::new(rays);
            let lanes = if k % 5 == 0 { 0b1011 } else { 0b1111 };
            let (hit, out) = intersect_packet(&pre4, &tri, F4::new(limits), lanes);
            for i in 0..4 {
                let scalar = (lanes >> i & 1 == 1)
                    .then(|| intersect(&pres[i], &tri, limits[i]))
                    .flatten();
                let lane = (hit >> i & 1 == 1).then(|| (out[0][i], out[1][i], out[2][i]));
                let bits = |h: Option<(f32, f32, f32)>| {
                    h.map(|(t, b1, b2)| [t.to_bits(), b1.to_bits(), b2.to_bits()])
                };
                assert_eq!(bits(lane), bits(scalar), "case {k} lane {i}");
                cases += scalar.is_some() as usize;
            }
        }
        assert!(cases > 1000, "too few hits to mean anything: {cases}");
    }

    #[test]
    fn the_nearest_of_candidates_for_four_rays_is_the_scalar_loops() {
        let mut rng = crate::accel::test_rng::Lcg(11);
        let mut found = 0;
        for k in 0..400 {
            // A stack of overlapping triangles ahead of the rays: nearer ones come later in
            // some cases and earlier in others.
            let tris: Vec<[Vec3; 3]> = (0..12)
                .map(|_| {
                    let c = rng.v(2.0) - Vec3::new(1.0, 1.0, 1.0 + 4.0 * rng.next());
                    [c, c + rng.v(3.0) - 1.5, c + rng.v(3.0) - 1.5]
                })
                .collect();
            let rays: [Ray; 4] =
                std::array::from_fn(|_| Ray::new(rng.v(0.5), Vec3::NEG_Z + rng.v(0.4) - 0.2));
            let t_max: [f32; 4] = std::array::from_fn(|i| if i == 3 { 2.5 } else { f32::INFINITY });
            let active = if k % 3 == 0 { 0b0111 } else { 0b1111 };
            let candidates = tris.iter().enumerate().map(|(p, t)| (p as u32, *t));
            let four = nearest4(rays, active, t_max, candidates);
            for i in 0..4 {
                let mut scalar = None;
                if active >> i & 1 == 1 {
                    let pre = RayPre::new(&rays[i]);
                    let mut limit = t_max[i];
                    for (p, tri) in tris.iter().enumerate() {
                        if let Some((t, b1, b2)) = intersect(&pre, tri, limit) {
                            limit = t;
                            scalar = Some((p as u32, [t, b1, b2].map(f32::to_bits)));
                        }
                    }
                }
                let lane = four[i].map(|h| (h.prim, [h.t, h.b1, h.b2].map(f32::to_bits)));
                assert_eq!(lane, scalar, "case {k} ray {i}");
                found += scalar.is_some() as usize;
            }
        }
        assert!(found > 500, "too few hits to mean anything: {found}");
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
