//! One ray against four triangles at once, a triangle a lane: the single-ray walk's leaf test
//! (`traverse.rs`), each lane bit for bit `triangle::intersect`.

use super::lanes::F4;
use super::triangle::{RayPre, depths, intersect};
use glam::Vec3;

/// `intersect` of one ray against four triangles at once, a triangle a lane: bit `i` of the mask
/// is set where `intersect(pre, tris[i], t_max)` hits, with its `(t, b1, b2)` in lane `i`.
///
/// The sheared vertices are `x = (v[kx] - o[kx]) + (-sx) (v[kz] - o[kz])`, `y` likewise with `ky`,
/// `z = sz (v[kz] - o[kz])`: the matrix product's sums without its products by the shear's zeros
/// and ones. They differ from it only in the sign of a zero result; such a zero changes no edge
/// function that is not exactly zero (it enters them only as a product added to a nonzero one),
/// a lane with an exactly zero edge function runs the scalar test itself, and it changes no
/// `t_scaled` but a zero one, which is no hit either way. So every lane is the scalar test's, bit
/// for bit (the test below holds it to that).
#[inline(always)]
pub(super) fn intersect4(pre: &RayPre, tris: [&[Vec3; 3]; 4], t_max: f32) -> (u32, [[f32; 4]; 3]) {
    let [kx, ky, kz] = pre.axes;
    let o = pre.origin.to_array();
    let [nsx, nsy, sz] = pre.shear_kz.map(F4::splat);
    // One vertex of the four triangles, sheared, lane by lane.
    let sheared = |j: usize| {
        // SAFETY: `shear_axes` gives axes in 0..3.
        let lane = |k: usize| {
            F4::new(tris.map(|t| unsafe { *t[j].as_ref().get_unchecked(k) }))
                .sub(F4::splat(unsafe { *o.get_unchecked(k) }))
        };
        let (rx, ry, rz) = (lane(kx), lane(ky), lane(kz));
        (rx.add(nsx.mul(rz)), ry.add(nsy.mul(rz)), sz.mul(rz))
    };
    let ((ax, ay, az), (bx, by, bz), (cx, cy, cz)) = (sheared(0), sheared(1), sheared(2));
    let u = cx.mul(by).sub(cy.mul(bx));
    let v = ax.mul(cy).sub(ay.mul(cx));
    let w = bx.mul(ay).sub(by.mul(ax));
    let zero = F4::splat(0.0);
    let exact_zero = u.eq(zero).or(v.eq(zero)).or(w.eq(zero)).bits();
    let negative = u.lt(zero).or(v.lt(zero)).or(w.lt(zero)).bits();
    let positive = u.gt(zero).or(v.gt(zero)).or(w.gt(zero)).bits();
    let mut out = [[0.0; 4]; 3];
    let mut hit = 0;
    // Most groups end here, the ray outside all four triangles.
    if (exact_zero | !(negative & positive)) & 0b1111 != 0 {
        let outside = exact_zero | (negative & positive);
        (hit, out) = depths(u, v, w, [az, bz, cz], F4::splat(t_max), outside);
        hit &= 0b1111;
    }
    for i in (0..4).filter(|i| exact_zero >> i & 1 == 1) {
        if let Some((t, b1, b2)) = intersect(pre, tris[i], t_max) {
            hit |= 1 << i;
            [out[0][i], out[1][i], out[2][i]] = [t, b1, b2];
        }
    }
    (hit, out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Ray;

    /// One ray against four triangles gives each triangle's scalar result bit for bit, on
    /// coordinates from a few values with both zeros (vertices on the origin's planes, where the
    /// sheared rows and edge functions come out zero) and on random ones.
    #[test]
    fn four_triangles_give_the_scalar_results_bit_for_bit() {
        let mut rng = crate::accel::test_rng::Lcg(17);
        let values = [0.0, -0.0, 0.5, -1.0, 1.0, 2.0];
        let mut hits = 0;
        for k in 0..20_000 {
            let coarse = k % 2 == 0;
            let mut coord = |scale: f32| {
                if coarse {
                    values[(rng.next() * values.len() as f32) as usize % values.len()]
                } else {
                    (rng.next() - 0.5) * scale
                }
            };
            let tris: [[Vec3; 3]; 4] = std::array::from_fn(|_| {
                std::array::from_fn(|_| Vec3::new(coord(4.0), coord(4.0), coord(4.0)))
            });
            let origin = Vec3::new(coord(4.0), coord(4.0), coord(4.0));
            let dir = Vec3::new(coord(2.0), coord(2.0), coord(2.0));
            if dir == Vec3::ZERO {
                continue;
            }
            let ray = Ray::new(origin, dir);
            let pre = RayPre::new(&ray);
            let t_max = if k % 3 == 0 { 1.5 } else { f32::INFINITY };
            let (hit, out) = intersect4(&pre, [&tris[0], &tris[1], &tris[2], &tris[3]], t_max);
            for (i, tri) in tris.iter().enumerate() {
                let scalar = intersect(&pre, tri, t_max);
                let lane = (hit >> i & 1 == 1).then(|| (out[0][i], out[1][i], out[2][i]));
                let bits = |h: Option<(f32, f32, f32)>| {
                    h.map(|(t, b1, b2)| [t.to_bits(), b1.to_bits(), b2.to_bits()])
                };
                assert_eq!(
                    bits(lane),
                    bits(scalar),
                    "case {k} lane {i}: {tri:?} {ray:?}"
                );
                hits += scalar.is_some() as usize;
            }
        }
        assert!(hits > 2_000, "too few hits to mean anything: {hits}");
    }
}
