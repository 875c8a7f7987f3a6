//! Local shading models and Fresnel terms. Cook-Torrance is the glTF 2.0 metallic-roughness BRDF
//! (specification Appendix B) exactly as WHITTED.md writes it; Phong is a documented mapping of the
//! same material onto a normalized Blinn-Phong lobe, for users who want the classic look.

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
/// and on the same side (the caller checks n.l > 0 and n.v > 0).
#[inline]
pub fn brdf(model: ShadingModel, s: &SurfacePoint, n: Vec3, l: Vec3, v: Vec3) -> Vec3 {
    match model {
        ShadingModel::CookTorrance => gltf_brdf(s, n, l, v),
        ShadingModel::Phong => phong_brdf(s, n, l, v),
    }
}

/// glTF 2.0 Appendix B with alpha = roughness^2, the height-correlated Smith visibility and
/// Schlick Fresnel; at roughness 0 the specular lobe is a delta that point lights cannot reach.
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
