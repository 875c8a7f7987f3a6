//! Local shading models and Fresnel terms. Cook-Torrance is the glTF 2.0 metallic-roughness BRDF
//! (specification Appendix B) exactly as WHITTED.md writes it; Phong is a documented mapping of the
//! same material onto a normalized Blinn-Phong lobe, for users who want the classic look.

use crate::accel::F4;
use glam::Vec3;
use serde::{Deserialize, Serialize};
use std::f32::consts::PI;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum ShadingModel {
    #[default]
    CookTorrance,
    Phong,
}

/// Schlick's approximation with a (possibly coloured) normal-incidence reflectance `f0`.
#[inline]
pub fn schlick(f0: Vec3, cos: f32) -> Vec3 {
    let w = (1.0 - cos.clamp(0.0, 1.0)).powi(5);
    f0 + (Vec3::ONE - f0) * w
}

/// Exact unpolarised Fresnel reflectance of a smooth dielectric interface for relative index
/// `eta = eta_i / eta_t` and `cos_i` > 0. Returns `(F, cos_t)`; `cos_t` is `None` under total
/// internal reflection (F = 1).
#[inline]
pub fn dielectric_fresnel(cos_i: f32, eta: f32) -> (f32, Option<f32>) {
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
    if sin2_t >= 1.0 {
        return (1.0, None);
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    (0.5 * (rs * rs + rp * rp), Some(cos_t))
}

/// Surface parameters at a shading point.
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint {
    pub base_color: Vec3,
    pub metallic: f32,
    pub roughness: f32,
}

/// BRDF value (no cosine) for light direction `l`, view direction `v`, shading normal `n`, all unit
/// and on the same side (the caller checks n.l > 0 and n.v > 0). The renderer calls
/// `BrdfLanes::brdf`; this one-point form is the formula as written, and that one's oracle.
#[cfg(test)]
pub fn brdf(model: ShadingModel, s: &SurfacePoint, n: Vec3, l: Vec3, v: Vec3) -> Vec3 {
    match model {
        ShadingModel::CookTorrance => gltf_brdf(s, n, l, v),
        ShadingModel::Phong => phong_brdf(s, n, l, v),
    }
}

/// glTF 2.0 Appendix B with alpha = roughness^2, the height-correlated Smith visibility and
/// Schlick Fresnel; at roughness 0 the specular lobe is a delta that point lights cannot reach.
#[cfg(test)]
fn gltf_brdf(s: &SurfacePoint, n: Vec3, l: Vec3, v: Vec3) -> Vec3 {
    let h = (l + v).normalize();
    let (n_l, n_v, n_h, v_h) = (n.dot(l), n.dot(v), n.dot(h), v.dot(h));
    let spec = if s.roughness > 0.0 && n_h > 0.0 {
        let a = s.roughness * s.roughness;
        let a2 = a * a;
        let d_term = n_h * n_h * (a2 - 1.0) + 1.0;
        let d = a2 / (PI * d_term * d_term);
        let vis = 0.5
            / (n_l * (n_v * n_v * (1.0 - a2) + a2).sqrt()
                + n_v * (n_l * n_l * (1.0 - a2) + a2).sqrt());
        let v = d * vis;
        if v.is_finite() { v } else { 0.0 }
    } else {
        0.0
    };
    let fw = (1.0 - v_h.abs()).powi(5);
    let f_dielectric = 0.04 + 0.96 * fw;
    let f_metal = s.base_color + (Vec3::ONE - s.base_color) * fw;
    let dielectric = (1.0 - f_dielectric) * s.base_color / PI + Vec3::splat(f_dielectric * spec);
    let metal = f_metal * spec;
    (1.0 - s.metallic) * dielectric + s.metallic * metal
}

/// Up to four shading points' `brdf` inputs, coordinate by coordinate (a lane not set holds
/// zeros, and its value means nothing).
#[derive(Clone, Copy, Default)]
pub struct BrdfLanes {
    n: [[f32; 4]; 3],
    l: [[f32; 4]; 3],
    v: [[f32; 4]; 3],
    base_color: [[f32; 4]; 3],
    metallic: [f32; 4],
    roughness: [f32; 4],
}

impl BrdfLanes {
    /// Lane `i`'s shading point, normal, light and view directions.
    #[inline]
    pub fn set(&mut self, i: usize, s: &SurfacePoint, n: Vec3, l: Vec3, v: Vec3) {
        for c in 0..3 {
            (self.n[c][i], self.l[c][i], self.v[c][i]) = (n[c], l[c], v[c]);
            self.base_color[c][i] = s.base_color[c];
        }
        (self.metallic[i], self.roughness[i]) = (s.metallic, s.roughness);
    }

    /// `brdf` of each lane, bit for bit the one-point value: Cook-Torrance in four-lane
    /// operations of `gltf_brdf`'s order (one lane at a time, its divisions and square roots
    /// were 10% of a diffuse frame), Phong one lane at a time.
    pub fn brdf(&self, model: ShadingModel) -> [Vec3; 4] {
        match model {
            ShadingModel::CookTorrance => self.gltf_brdf(),
            ShadingModel::Phong => std::array::from_fn(|i| {
                let at = |v: &[[f32; 4]; 3]| Vec3::new(v[0][i], v[1][i], v[2][i]);
                let point = SurfacePoint {
                    base_color: at(&self.base_color),
                    metallic: self.metallic[i],
                    roughness: self.roughness[i],
                };
                phong_brdf(&point, at(&self.n), at(&self.l), at(&self.v))
            }),
        }
    }

    /// `gltf_brdf` lane by lane: the same operations in the same order, with its two branches
    /// as selects (glam's `normalize` is `v * (1 / length)`; `powi(5)` is `x * (x^2)^2`, as
    /// LLVM expands a constant power and as compiler-rt's loop multiplies).
    fn gltf_brdf(&self) -> [Vec3; 4] {
        let splat = F4::splat;
        let one = splat(1.0);
        let lanes = |v: &[[f32; 4]; 3]| v.map(F4::new);
        let (n, l, v) = (lanes(&self.n), lanes(&self.l), lanes(&self.v));
        let sum: Vec3x4 = std::array::from_fn(|c| l[c].add(v[c]));
        let recip = one.div(dot4(sum, sum).sqrt());
        let h = sum.map(|x| x.mul(recip));
        let (n_l, n_v, n_h, v_h) = (dot4(n, l), dot4(n, v), dot4(n, h), dot4(v, h));
        let roughness = F4::new(self.roughness);
        let a = roughness.mul(roughness);
        let a2 = a.mul(a);
        let d_term = n_h.mul(n_h).mul(a2.sub(one)).add(one);
        let d = a2.div(splat(PI).mul(d_term).mul(d_term));
        let one_minus_a2 = one.sub(a2);
        let vis = splat(0.5).div(
            n_l.mul(n_v.mul(n_v).mul(one_minus_a2).add(a2).sqrt())
                .add(n_v.mul(n_l.mul(n_l).mul(one_minus_a2).add(a2).sqrt())),
        );
        let lobe = d.mul(vis);
        let zero = splat(0.0);
        let has_lobe = roughness.gt(zero).and(n_h.gt(zero));
        let finite = lobe.abs().lt(splat(f32::INFINITY));
        let spec = F4::select(has_lobe.and(finite), lobe, zero);
        let x = one.sub(v_h.abs());
        let x2 = x.mul(x);
        let fw = x.mul(x2.mul(x2));
        let f_dielectric = splat(0.04).add(splat(0.96).mul(fw));
        let metallic = F4::new(self.metallic);
        let (keep_dielectric, specular) = (one.sub(metallic), f_dielectric.mul(spec));
        let rgb = std::array::from_fn::<_, 3, _>(|c| {
            let base = F4::new(self.base_color[c]);
            let f_metal = base.add(one.sub(base).mul(fw));
            let dielectric = one.sub(f_dielectric).mul(base).div(splat(PI)).add(specular);
            let metal = f_metal.mul(spec);
            keep_dielectric
                .mul(dielectric)
                .add(metallic.mul(metal))
                .to_array()
        });
        std::array::from_fn(|i| Vec3::new(rgb[0][i], rgb[1][i], rgb[2][i]))
    }
}

/// Three coordinates of four vectors.
type Vec3x4 = [F4; 3];

/// glam's `dot`: `(x x') + (y y') + (z z')`.
fn dot4(a: Vec3x4, b: Vec3x4) -> F4 {
    a[0].mul(b[0]).add(a[1].mul(b[1])).add(a[2].mul(b[2]))
}

/// Phong mapping of a metallic-roughness material: diffuse `(1 - m) C / pi`; specular colour
/// `mix(0.04, C, m)` on an energy-normalized Blinn-Phong lobe `(e + 8) / (8 pi) (n.h)^e` whose
/// exponent `e = 2 / alpha^2 - 2` (alpha = roughness^2) matches the Beckmann distribution of the
/// same roughness (Walter et al. 2007). Roughness 0 is a mirror: no point-light highlight.
fn phong_brdf(s: &SurfacePoint, n: Vec3, l: Vec3, v: Vec3) -> Vec3 {
    let diffuse = (1.0 - s.metallic) * s.base_color / PI;
    if s.roughness <= 0.0 {
        return diffuse;
    }
    let a = (s.roughness * s.roughness).max(1e-3);
    let e = (2.0 / (a * a) - 2.0).max(0.0);
    let h = (l + v).normalize();
    let n_h = n.dot(h).max(0.0);
    let ks = Vec3::splat(0.04).lerp(s.base_color, s.metallic);
    diffuse + ks * ((e + 8.0) / (8.0 * PI) * n_h.powf(e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_at_normal_incidence_is_the_classic_value() {
        let (f, cos_t) = dielectric_fresnel(1.0, 1.0 / 1.5);
        assert!((f - 0.04).abs() < 1e-6);
        assert_eq!(cos_t, Some(1.0));
    }

    #[test]
    fn total_internal_reflection_past_the_critical_angle() {
        // From glass (1.5) to air: critical angle asin(1/1.5) = 41.8 degrees.
        let inside = 45f32.to_radians().cos();
        assert_eq!(dielectric_fresnel(inside, 1.5), (1.0, None));
        let below = 40f32.to_radians().cos();
        assert!(dielectric_fresnel(below, 1.5).0 < 1.0);
    }

    #[test]
    fn four_points_at_once_are_bit_for_bit_one_at_a_time() {
        let mut seed = 0x2545_f491u32;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            (seed >> 8) as f32 / (1u32 << 24) as f32
        };
        let unit = |next: &mut dyn FnMut() -> f32| {
            Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5).normalize()
        };
        for case in 0..4000 {
            let n: [Vec3; 4] = std::array::from_fn(|_| unit(&mut next));
            // Directions on either side of n, some grazing, some the same as n.
            let l: [Vec3; 4] =
                std::array::from_fn(|i| if case % 7 == i { n[i] } else { unit(&mut next) });
            let v: [Vec3; 4] = std::array::from_fn(|_| unit(&mut next));
            let points: [SurfacePoint; 4] = std::array::from_fn(|i| SurfacePoint {
                base_color: Vec3::new(next(), next(), next()),
                metallic: if i == 1 { 1.0 } else { next() },
                // Roughness 0 (no lobe) and tiny (a lobe past f32's range) among the lanes.
                roughness: [0.0, 1e-12, next(), 1.0][(case + i) % 4],
            });
            let mut lanes = BrdfLanes::default();
            for i in 0..4 {
                lanes.set(i, &points[i], n[i], l[i], v[i]);
            }
            for model in [ShadingModel::CookTorrance, ShadingModel::Phong] {
                let four = lanes.brdf(model);
                for i in 0..4 {
                    let one = brdf(model, &points[i], n[i], l[i], v[i]);
                    assert_eq!(
                        four[i].to_array().map(f32::to_bits),
                        one.to_array().map(f32::to_bits),
                        "{model:?} lane {i}: {} against {one}",
                        four[i]
                    );
                }
            }
        }
    }

    #[test]
    fn white_lambertian_dielectric_reflects_less_than_it_receives() {
        let s = SurfacePoint {
            base_color: Vec3::ONE,
            metallic: 0.0,
            roughness: 1.0,
        };
        let n = Vec3::Z;
        let v = Vec3::new(0.3, 0.0, 1.0).normalize();
        // Monte Carlo-free check: integrate over a coarse hemisphere grid.
        let mut albedo = Vec3::ZERO;
        let steps = 200;
        for i in 0..steps {
            for j in 0..steps {
                let theta = (i as f32 + 0.5) / steps as f32 * PI * 0.5;
                let phi = (j as f32 + 0.5) / steps as f32 * 2.0 * PI;
                let l = Vec3::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    theta.cos(),
                );
                let d_omega = theta.sin() * (PI * 0.5 / steps as f32) * (2.0 * PI / steps as f32);
                albedo += brdf(ShadingModel::CookTorrance, &s, n, l, v) * l.z * d_omega;
            }
        }
        assert!(albedo.x < 1.0 && albedo.x > 0.8, "albedo {albedo}");
    }
}
