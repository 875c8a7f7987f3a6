//! The Whitted integrator of WHITTED.md section 4: emission, direct light from every punctual light
//! through shadow rays, a Fresnel-weighted mirror ray for smooth opaque surfaces, and reflection plus
//! refraction (exact Fresnel, total internal reflection) for smooth dielectrics, to `max_depth`.

use super::shading::{self, ShadingModel, SurfacePoint, brdf, dielectric_fresnel, schlick};
use crate::accel::{Hit, Intersect, LANES, Ray};
use crate::scene::light::{Light, LightKind};
use crate::scene::material::{Material, Texture};
use crate::scene::pose::Geometry;
use glam::{Vec2, Vec3};
use smallvec::SmallVec;
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

/// A hit's surface, as shading sees it.
struct Surface<'m> {
    sh: Shading,
    mat: &'m Material,
    point: SurfacePoint,
    /// Direction to the viewer.
    v: Vec3,
    glass: bool,
}

/// A light that reaches a hit unless its shadow ray is blocked.
struct LightQuery {
    /// Index into the scene's lights.
    light: usize,
    shadow: Ray,
    t_max: f32,
    /// Unit direction to the light, `n . l`, and the irradiance arriving.
    l: Vec3,
    n_l: f32,
    irradiance: Vec3,
}

/// A secondary ray a lane asks for, and the weight its radiance gets.
#[derive(Clone, Copy)]
struct Bounce {
    dir: Vec3,
    weight: Vec3,
}

impl<A: Intersect> Integrator<'_, A> {
    /// Radiance along a camera ray (depth 1).
    pub fn radiance(&self, ray: &Ray, t_max: f32, counts: &Cell<RayCounts>) -> Vec3 {
        let mut out = [Vec3::ZERO];
        self.radiance_packet(&[*ray], &[t_max], counts, &mut out);
        out[0]
    }

    /// Radiance along up to `LANES` camera rays (depth 1). The rays travel the tree as a packet,
    /// and so do, level by level, the shadow rays of their hits to each light and their mirror
    /// and refraction rays. Each ray's radiance is bit for bit what it would be alone: a lane adds
    /// the same terms in the same order.
    pub fn radiance_packet(
        &self,
        rays: &[Ray],
        t_max: &[f32],
        counts: &Cell<RayCounts>,
        out: &mut [Vec3],
    ) {
        bump(counts, |c| c.primary += rays.len() as u64);
        self.trace(rays, t_max, 1, counts, out);
    }

    fn trace(
        &self,
        rays: &[Ray],
        t_max: &[f32],
        depth: u32,
        counts: &Cell<RayCounts>,
        out: &mut [Vec3],
    ) {
        let n = rays.len();
        assert!(n <= LANES && t_max.len() == n && out.len() == n);
        let mut hits = [None; LANES];
        self.scene.accel.closest_hits(rays, t_max, &mut hits[..n]);
        let surfaces: [Option<Surface>; LANES] =
            std::array::from_fn(|i| hits[i].map(|h| self.surface(&rays[i], &h)));
        let direct = self.direct_light(&surfaces, counts);
        for (i, o) in out.iter_mut().enumerate() {
            *o = match &surfaces[i] {
                Some(s) if s.glass => s.mat.emissive,
                Some(s) => s.mat.emissive + direct[i],
                None => self.settings.background,
            };
        }
        if depth >= self.settings.max_depth {
            return;
        }
        // Each lane's mirror ray and (glass) refraction ray, traced as two packets; a lane adds
        // the reflection before the refraction, as WHITTED.md's order has it.
        let mut bounces = [[None::<Bounce>; 2]; LANES];
        for (i, s) in surfaces.iter().enumerate() {
            if let Some(s) = s {
                bounces[i] = self.bounces(&rays[i], s);
            }
        }
        for kind in 0..2 {
            let mut next = [Ray::new(Vec3::ZERO, Vec3::Z); LANES];
            let mut lanes = [0usize; LANES];
            let mut k = 0;
            for (i, b) in bounces.iter().enumerate() {
                if let (Some(b), Some(s)) = (b[kind], &surfaces[i]) {
                    let sh = &s.sh;
                    let side = if sh.ng.dot(b.dir) >= 0.0 {
                        sh.ng
                    } else {
                        -sh.ng
                    };
                    (next[k], lanes[k]) = (Ray::new(offset_origin(sh.p, side), b.dir), i);
                    k += 1;
                }
            }
            if k == 0 {
                continue;
            }
            bump(counts, |c| c.secondary += k as u64);
            let mut incoming = [Vec3::ZERO; LANES];
            let far = [f32::INFINITY; LANES];
            self.trace(&next[..k], &far[..k], depth + 1, counts, &mut incoming[..k]);
            for (&i, l) in lanes[..k].iter().zip(&incoming[..k]) {
                let w = bounces[i][kind].expect("a traced bounce").weight;
                out[i] += w * *l;
            }
        }
    }

    /// Direct light at each lane's surface: each light's shadow rays from all lanes travel as one
    /// packet (rays towards one light from neighbouring hits); every lane adds its lights in
    /// the scene's order.
    fn direct_light(
        &self,
        surfaces: &[Option<Surface>; LANES],
        counts: &Cell<RayCounts>,
    ) -> [Vec3; LANES] {
        let mut direct = [Vec3::ZERO; LANES];
        let mut queries: SmallVec<[(usize, LightQuery); 2 * LANES]> = SmallVec::new();
        for (lane, s) in surfaces.iter().enumerate() {
            if let Some(s) = s {
                queries.extend(self.light_queries(s).map(|q| (lane, q)));
            }
        }
        if queries.is_empty() {
            return direct;
        }
        bump(counts, |c| c.shadow += queries.len() as u64);
        let mut shadow = [Ray::new(Vec3::ZERO, Vec3::Z); LANES];
        let mut limits = [0.0; LANES];
        let mut members = [0usize; LANES];
        let mut blocked = [false; LANES];
        for light in 0..self.scene.lights.len() {
            let mut k = 0;
            for (index, (_, q)) in queries.iter().enumerate() {
                if q.light == light {
                    (shadow[k], limits[k], members[k]) = (q.shadow, q.t_max, index);
                    k += 1;
                }
            }
            if k == 0 {
                continue;
            }
            self.scene
                .accel
                .any_hits(&shadow[..k], &limits[..k], &mut blocked[..k]);
            for (&index, &b) in members[..k].iter().zip(&blocked[..k]) {
                let (lane, q) = &queries[index];
                if !b && let Some(s) = &surfaces[*lane] {
                    direct[*lane] += self.direct_term(s, q);
                }
            }
        }
        direct
    }

    /// The mirror ray (index 0) and the refraction ray (index 1) a surface asks for below
    /// `max_depth`, with their weights: Fresnel-weighted reflection and refraction for glass
    /// (none under total internal reflection), Schlick-weighted reflection for a smooth opaque
    /// surface, nothing for a rough one.
    fn bounces(&self, ray: &Ray, s: &Surface) -> [Option<Bounce>; 2] {
        let (sh, mat, base, v) = (&s.sh, s.mat, s.point.base_color, s.v);
        let cos_i = sh.n.dot(v).clamp(0.0, 1.0);
        let reflect_dir = (ray.dir + 2.0 * cos_i * sh.n).normalize();
        if s.glass {
            let eta = if sh.front { 1.0 / mat.ior } else { mat.ior };
            let (f, cos_t) = dielectric_fresnel(cos_i, eta);
            let refraction = cos_t.map(|cos_t| Bounce {
                dir: (eta * ray.dir + (eta * cos_i - cos_t) * sh.n).normalize(),
                weight: (1.0 - f) * base,
            });
            let reflection = Bounce {
                dir: reflect_dir,
                weight: Vec3::splat(f),
            };
            [Some(reflection), refraction]
        } else if mat.roughness == 0.0 {
            let weight = (1.0 - mat.metallic) * schlick(Vec3::splat(0.04), cos_i)
                + mat.metallic * shading::schlick(base, cos_i);
            [
                Some(Bounce {
                    dir: reflect_dir,
                    weight,
                }),
                None,
            ]
        } else {
            [None, None]
        }
    }

    fn surface(&self, ray: &Ray, hit: &Hit) -> Surface<'_> {
        let sh = self.shading_point(ray, hit);
        let mat = &self.scene.materials[sh.material as usize];
        let point = SurfacePoint {
            base_color: self.base_color(mat, &sh),
            metallic: mat.metallic,
            roughness: mat.roughness,
        };
        Surface {
            sh,
            mat,
            point,
            v: -ray.dir,
            glass: mat.transmission >= 0.5,
        }
    }

    /// What an unblocked light adds at a surface.
    fn direct_term(&self, s: &Surface, q: &LightQuery) -> Vec3 {
        brdf(self.settings.shading, &s.point, s.sh.n, q.l, s.v) * q.n_l * q.irradiance
    }

    /// The lights that can reach a surface (none for glass, which takes no direct light), in
    /// the scene's order, each with its shadow ray.
    fn light_queries<'s>(&'s self, s: &'s Surface) -> impl Iterator<Item = LightQuery> + 's {
        let (sh, v) = (&s.sh, s.v);
        let lit = !s.glass && sh.n.dot(v) > 0.0;
        let (lights, origin) = if lit {
            (self.scene.lights, offset_origin(sh.p, sh.ng))
        } else {
            (&[][..], sh.p)
        };
        lights.iter().enumerate().filter_map(move |(index, light)| {
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
                return None;
            }
            let t_max = match light.kind {
                LightKind::Directional => f32::INFINITY,
                _ => 1.0 - SHADOW_EPSILON,
            };
            Some(LightQuery {
                light: index,
                shadow,
                t_max,
                l,
                n_l,
                irradiance,
            })
        })
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
