//! The Whitted integrator of WHITTED.md section 4: emission, direct light from every punctual light
//! through shadow rays, a Fresnel-weighted mirror ray for smooth opaque surfaces, and reflection plus
//! refraction (exact Fresnel, total internal reflection) for smooth dielectrics, to `max_depth`.

use super::shading::{self, ShadingModel, SurfacePoint, brdf, dielectric_fresnel, schlick};
use crate::accel::{Hit, Intersect, Ray};
use crate::scene::light::{Light, LightKind};
use crate::scene::material::{Material, Texture};
use crate::scene::pose::Geometry;
use glam::{Vec2, Vec3};
use std::cell::Cell;

#[derive(Clone, Copy, Debug)]
pub struct TraceSettings {
    pub max_depth: u32,
    pub shading: ShadingModel,
    pub background: Vec3,
}

/// Counts of traced rays, kept per tile and summed (integer sums are order-independent).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayCounts {
    pub primary: u64,
    pub secondary: u64,
    pub shadow: u64,
}

impl RayCounts {
    pub fn total(&self) -> u64 {
        self.primary + self.secondary + self.shadow
    }

    pub fn add(&mut self, o: &RayCounts) {
        self.primary += o.primary;
        self.secondary += o.secondary;
        self.shadow += o.shadow;
    }
}

/// What the integrator reads of a posed frame.
pub struct SceneView<'a, A: Intersect> {
    pub accel: &'a A,
    pub geometry: &'a Geometry,
    pub materials: &'a [Material],
    pub textures: &'a [Option<Texture>],
    pub lights: &'a [Light],
}

pub struct Integrator<'a, A: Intersect> {
    pub scene: SceneView<'a, A>,
    pub settings: TraceSettings,
}

/// Offset a point off a surface along its geometric normal `n` (pointing to the side the new ray
/// leaves from), by a few float ulps of the point's own coordinates: Wächter and Binder, "A Fast and
/// Robust Method for Avoiding Self-Intersection" (Ray Tracing Gems, 2019, ch. 6). The offset scales
/// with the magnitude of the coordinates, so it works at 1e-3 and at 1e5 alike, unlike a fixed
/// epsilon; near the origin, where ulps vanish, a small fixed offset takes over.
pub fn offset_origin(p: Vec3, n: Vec3) -> Vec3 {
    const ORIGIN: f32 = 1.0 / 32.0;
    const FLOAT_SCALE: f32 = 1.0 / 65536.0;
    const INT_SCALE: f32 = 256.0;
    let mut out = p;
    for i in 0..3 {
        let of_i = (INT_SCALE * n[i]) as i32;
        let bits = p[i].to_bits() as i32;
        let moved = f32::from_bits(bits.wrapping_add(if p[i] < 0.0 { -of_i } else { of_i }) as u32);
        out[i] = if p[i].abs() < ORIGIN {
            p[i] + FLOAT_SCALE * n[i]
        } else {
            moved
        };
    }
    out
}

/// Shadow rays stop this fraction short of the light so a light sitting on a surface is not
/// shadowed by that surface.
const SHADOW_EPSILON: f32 = 1e-4;

/// Geometry of a hit, with normals flipped to the side the ray came from.
struct Shading {
    p: Vec3,
    /// Shading normal on the viewer's side.
    n: Vec3,
    /// Geometric normal on the viewer's side.
    ng: Vec3,
    /// The ray arrived on the front (counter-clockwise) face.
    front: bool,
    uv: [Vec2; 2],
    color: Vec3,
    material: u32,
}

impl<A: Intersect> Integrator<'_, A> {
    /// Radiance along a camera ray (depth 1).
    pub fn radiance(&self, ray: &Ray, t_max: f32, counts: &Cell<RayCounts>) -> Vec3 {
        bump(counts, |c| c.primary += 1);
        self.trace(ray, t_max, 1, counts)
    }

    fn trace(&self, ray: &Ray, t_max: f32, depth: u32, counts: &Cell<RayCounts>) -> Vec3 {
        let Some(hit) = self.scene.accel.closest_hit(ray, t_max) else {
            return self.settings.background;
        };
        let sh = self.shading_point(ray, &hit);
        let mat = &self.scene.materials[sh.material as usize];
        let base = self.base_color(mat, &sh);
        let v = -ray.dir;
        let mut radiance = mat.emissive;
        let glass = mat.transmission >= 0.5;
        let surface = SurfacePoint {
            base_color: base,
            metallic: mat.metallic,
            roughness: mat.roughness,
        };
        if !glass {
            radiance += self.direct(&sh, &surface, v, counts);
        }
        if depth >= self.settings.max_depth {
            return radiance;
        }
        let cos_i = sh.n.dot(v).clamp(0.0, 1.0);
        let reflect_dir = (ray.dir + 2.0 * cos_i * sh.n).normalize();
        if glass {
            let eta = if sh.front { 1.0 / mat.ior } else { mat.ior };
            let (f, cos_t) = dielectric_fresnel(cos_i, eta);
            radiance += f * self.spawn(&sh, reflect_dir, depth, counts);
            if let Some(cos_t) = cos_t {
                let t_dir = (eta * ray.dir + (eta * cos_i - cos_t) * sh.n).normalize();
                radiance += (1.0 - f) * base * self.spawn(&sh, t_dir, depth, counts);
            }
        } else if mat.roughness == 0.0 {
            let weight = (1.0 - mat.metallic) * schlick(Vec3::splat(0.04), cos_i)
                + mat.metallic * shading::schlick(base, cos_i);
            radiance += weight * self.spawn(&sh, reflect_dir, depth, counts);
        }
        radiance
    }

    /// Traces a secondary ray leaving the surface in `dir`.
    fn spawn(&self, sh: &Shading, dir: Vec3, depth: u32, counts: &Cell<RayCounts>) -> Vec3 {
        let side = if sh.ng.dot(dir) >= 0.0 { sh.ng } else { -sh.ng };
        let ray = Ray::new(offset_origin(sh.p, side), dir);
        bump(counts, |c| c.secondary += 1);
        self.trace(&ray, f32::INFINITY, depth + 1, counts)
    }

    fn direct(&self, sh: &Shading, s: &SurfacePoint, v: Vec3, counts: &Cell<RayCounts>) -> Vec3 {
        let mut sum = Vec3::ZERO;
        if sh.n.dot(v) <= 0.0 {
            return sum;
        }
        let origin = offset_origin(sh.p, sh.ng);
        for light in self.scene.lights {
            let (l, irradiance, shadow) = match light.kind {
                LightKind::Directional => {
                    let l = -light.direction;
                    (l, light.power, Ray::new(origin, l))
                }
                LightKind::Point | LightKind::Spot { .. } => {
                    let to = light.position - sh.p;
                    let d2 = to.length_squared();
                    let d = d2.sqrt();
                    let l = to / d;
                    let falloff = light.cone_attenuation(l) * light.range_attenuation(d) / d2;
                    (
                        l,
                        light.power * falloff,
                        Ray::new(origin, light.position - origin),
                    )
                }
            };
            let n_l = sh.n.dot(l);
            if n_l <= 0.0 || sh.ng.dot(l) <= 0.0 || irradiance == Vec3::ZERO {
                continue;
            }
            let t_max = match light.kind {
                LightKind::Directional => f32::INFINITY,
                _ => 1.0 - SHADOW_EPSILON,
            };
            bump(counts, |c| c.shadow += 1);
            if self.scene.accel.any_hit(&shadow, t_max) {
                continue;
            }
            sum += brdf(self.settings.shading, s, sh.n, l, v) * n_l * irradiance;
        }
        sum
    }

    fn shading_point(&self, ray: &Ray, hit: &Hit) -> Shading {
        let g = self.scene.geometry;
        let [i0, i1, i2] = g.triangles[hit.prim as usize].map(|i| i as usize);
        let (b1, b2) = (hit.b1, hit.b2);
        let b0 = 1.0 - b1 - b2;
        let (p0, p1, p2) = (g.positions[i0], g.positions[i1], g.positions[i2]);
        // The barycentric point is more accurate than origin + t * dir, which the offset relies on.
        let p = p0 * b0 + p1 * b1 + p2 * b2;
        let ng = (p1 - p0).cross(p2 - p0).normalize_or_zero();
        let interp = g.normals[i0] * b0 + g.normals[i1] * b1 + g.normals[i2] * b2;
        let ns = if interp.length_squared() > 1e-12 {
            interp.normalize()
        } else {
            ng
        };
        let front = ng.dot(-ray.dir) > 0.0;
        let s = if front { 1.0 } else { -1.0 };
        let uv = [0, 1].map(|k| {
            let t = &g.tex_coords[k];
            t[i0] * b0 + t[i1] * b1 + t[i2] * b2
        });
        let color = (g.colors[i0] * b0 + g.colors[i1] * b1 + g.colors[i2] * b2).truncate();
        Shading {
            p,
            n: ns * s,
            ng: ng * s,
            front,
            uv,
            color,
            material: g.triangle_materials[hit.prim as usize],
        }
    }

    fn base_color(&self, mat: &Material, sh: &Shading) -> Vec3 {
        let mut c = mat.base_color.truncate() * sh.color;
        if let Some(tr) = mat.base_color_texture
            && let Some(Some(tex)) = self.scene.textures.get(tr.texture)
        {
            c *= tex.sample(sh.uv[tr.tex_coord]).truncate();
        }
        c
    }
}

#[inline]
fn bump(counts: &Cell<RayCounts>, f: impl FnOnce(&mut RayCounts)) {
    let mut c = counts.get();
    f(&mut c);
    counts.set(c);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offset_moves_the_point_to_the_requested_side_at_any_scale() {
        for scale in [1e-4f32, 1.0, 1e5] {
            let p = Vec3::new(0.3, -0.7, 0.5) * scale;
            let n = Vec3::new(0.0, 1.0, 0.0);
            let o = offset_origin(p, n);
            assert!(o.y > p.y, "scale {scale}");
            assert!((o - p).length() < 1e-3 * scale.max(1.0));
            assert!(offset_origin(p, -n).y < p.y);
        }
    }
}
