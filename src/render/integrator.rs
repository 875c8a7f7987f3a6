//! The Whitted integrator of WHITTED.md section 4: emission, direct light from every punctual light
//! through shadow rays, a Fresnel-weighted mirror ray for smooth opaque surfaces, and reflection plus
//! refraction (exact Fresnel, total internal reflection) for smooth dielectrics, to `max_depth`;
//! with the material inputs of WHITTED-materials.md: textures on every slot, normal maps, and
//! alpha coverage (MASK hits that do not exist for any ray, BLEND surfaces over what lies behind).
//! The direct light of a packet's hits, its shadow rays and BRDF terms, is `direct.rs`.

use super::BATCH;
use super::shading::{self, ShadingModel, dielectric_fresnel, schlick};
use super::surface::{SceneView, Shading, Surface};
use crate::accel::{Hit, Intersect, Ray};
use crate::scene::material::{AlphaMode, Material};
use glam::Vec3;
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
    /// Camera rays of a view whose primary hit came from another view (`eye_reuse =
    /// "reproject"`), and shadow rays whose answer came with it: not traced, so not counted above.
    pub reused_primary: u64,
    pub reused_shadow: u64,
    /// Camera samples that took another view's radiance as well (`"reproject-radiance"`).
    pub reused_radiance: u64,
}

impl RayCounts {
    pub fn total(&self) -> u64 {
        self.primary + self.secondary + self.shadow
    }

    /// Each count divided by `parts`: one view's share of a pass that traced several.
    pub fn share(&self, parts: u64) -> RayCounts {
        RayCounts {
            primary: self.primary / parts,
            secondary: self.secondary / parts,
            shadow: self.shadow / parts,
            reused_primary: self.reused_primary / parts,
            reused_shadow: self.reused_shadow / parts,
            reused_radiance: self.reused_radiance / parts,
        }
    }

    pub fn add(&mut self, o: &RayCounts) {
        self.primary += o.primary;
        self.secondary += o.secondary;
        self.shadow += o.shadow;
        self.reused_primary += o.reused_primary;
        self.reused_shadow += o.reused_shadow;
        self.reused_radiance += o.reused_radiance;
    }
}

pub struct Integrator<'a, A: Intersect> {
    pub scene: SceneView<'a, A>,
    pub settings: TraceSettings,
    /// Whether any material is MASK or BLEND: only then do hits need their coverage tested and
    /// shadow rays their crossings walked, so opaque scenes pay nothing for alpha.
    pub(super) transparent: bool,
}

impl<'a, A: Intersect> Integrator<'a, A> {
    pub fn new(scene: SceneView<'a, A>, settings: TraceSettings) -> Self {
        let transparent = scene.materials.iter().any(Material::is_transparent);
        Integrator {
            scene,
            settings,
            transparent,
        }
    }
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

impl Shading {
    /// Where a ray leaving the hit along `dir` starts: offset to the side of the surface it
    /// leaves toward.
    pub(super) fn origin_toward(&self, dir: Vec3) -> Vec3 {
        let side = if self.ng.dot(dir) >= 0.0 {
            self.ng
        } else {
            -self.ng
        };
        offset_origin(self.p, side)
    }
}

/// Shadow results are kept for the first 32 lights (one bit each); later lights are always traced.
pub const RECORDED_LIGHTS: usize = 32;

/// What a view's camera ray found, for another view to reuse (`eye_reuse = "reproject"`).
#[derive(Clone, Copy, Debug)]
pub struct PrimaryRecord {
    pub hit: Option<Hit>,
    /// The hit point (barycentric, as shading computed it).
    pub point: Vec3,
    /// Lights (bit i: light i) whose shadow ray from the hit was traced and reached the light,
    /// and those whose shadow ray was blocked; both bits where it arrived in part (through
    /// BLEND surfaces).
    pub lit: u32,
    pub shadowed: u32,
    /// The width of the surface's highlight lobe (GGX alpha = roughness^2) where its radiance
    /// is emission and direct light alone (no mirror or glass ray), else negative: another
    /// view may take the radiance where its view direction differs by a small part of that.
    pub lobe: f32,
    /// The camera ray passed a MASK cut-out on its way: what it found is behind a hole
    /// another view may see through differently, so it is not offered for reuse.
    pub through_cut_out: bool,
}

impl PrimaryRecord {
    pub const NONE: PrimaryRecord = PrimaryRecord {
        hit: None,
        point: Vec3::ZERO,
        lit: 0,
        shadowed: 0,
        lobe: -1.0,
        through_cut_out: false,
    };
}

/// A camera ray's primary hit taken from another view, with the shadow answers that come with
/// it: lights in `lit` reach the hit, lights in `shadowed` do not, the others are traced.
#[derive(Clone, Copy, Debug)]
pub struct KnownHit {
    pub hit: Hit,
    pub lit: u32,
    pub shadowed: u32,
}

/// What a packet's camera rays bring besides themselves.
pub enum Primary<'a> {
    /// Trace every lane.
    Trace,
    /// Trace every lane and write what it found.
    Record(&'a mut [PrimaryRecord]),
    /// Lanes with a known hit skip their camera ray and their known shadow rays.
    Known(&'a [Option<KnownHit>]),
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
        self.radiance_packet(&[*ray], &[t_max], Primary::Trace, counts, &mut out);
        out[0]
    }

    /// Radiance along up to `BATCH` camera rays (depth 1). The rays travel the tree as a packet,
    /// and so do, level by level, the shadow rays of their hits to each light and their mirror
    /// and refraction rays. Each ray's radiance is bit for bit what it would be alone: a lane adds
    /// the same terms in the same order. `primary` says which camera hits are already known
    /// (and then only the unknown lanes are traced) or asks for a record of what was found.
    pub fn radiance_packet(
        &self,
        rays: &[Ray],
        t_max: &[f32],
        mut primary: Primary,
        counts: &Cell<RayCounts>,
        out: &mut [Vec3],
    ) {
        let n = rays.len();
        assert!(n <= BATCH && t_max.len() == n && out.len() == n);
        let mut hits = [None; BATCH];
        let mut known = [(0u32, 0u32); BATCH];
        if let Primary::Known(k) = primary {
            // Trace the lanes without a known hit as one (smaller) packet.
            let mut lanes = [0usize; BATCH];
            let mut sub_rays = [Ray::new(Vec3::ZERO, Vec3::Z); BATCH];
            let mut sub_t = [0.0; BATCH];
            let mut m = 0;
            for (i, k) in k[..n].iter().enumerate() {
                match k {
                    Some(k) => (hits[i], known[i]) = (Some(k.hit), (k.lit, k.shadowed)),
                    None => {
                        (lanes[m], sub_rays[m], sub_t[m]) = (i, rays[i], t_max[i]);
                        m += 1;
                    }
                }
            }
            let mut sub_hits = [None; BATCH];
            if m > 0 {
                self.scene
                    .accel
                    .closest_hits(&sub_rays[..m], &sub_t[..m], &mut sub_hits[..m]);
            }
            for (&i, h) in lanes[..m].iter().zip(sub_hits) {
                hits[i] = h;
            }
            bump(counts, |c| {
                c.primary += m as u64;
                c.reused_primary += (n - m) as u64;
            });
        } else {
            bump(counts, |c| c.primary += n as u64);
            self.scene.accel.closest_hits(rays, t_max, &mut hits[..n]);
        }
        // A known hit may be a cut-out too: the other view saw it through the same hole.
        let passed = self.pass_cut_outs(rays, t_max, &mut hits[..n], counts);
        let record = match &mut primary {
            Primary::Record(r) => Some(&mut r[..n]),
            _ => None,
        };
        self.shade(rays, &hits[..n], &known, 1, record, counts, out);
        if let Primary::Record(r) = &mut primary {
            for (i, r) in r[..n].iter_mut().enumerate() {
                r.through_cut_out = passed & (1 << i) != 0;
            }
        }
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
        assert!(n <= BATCH && t_max.len() == n && out.len() == n);
        let mut hits = [None; BATCH];
        self.scene.accel.closest_hits(rays, t_max, &mut hits[..n]);
        self.pass_cut_outs(rays, t_max, &mut hits[..n], counts);
        self.shade(rays, &hits[..n], &[(0, 0); BATCH], depth, None, counts, out);
    }

    /// Radiance of each lane from its hit (`None`: the background), recursing below
    /// `max_depth`. `known[i]` holds lane i's shadow answers already known (lit, shadowed).
    #[allow(clippy::too_many_arguments)]
    fn shade(
        &self,
        rays: &[Ray],
        hits: &[Option<Hit>],
        known: &[(u32, u32); BATCH],
        depth: u32,
        record: Option<&mut [PrimaryRecord]>,
        counts: &Cell<RayCounts>,
        out: &mut [Vec3],
    ) {
        // Filled in place: built by `std::array::from_fn`, the array was assembled aside and
        // copied in some builds (7% of the default pipeline's time in `memmove`).
        let mut surfaces: [Option<Surface>; BATCH] = [const { None }; BATCH];
        for (i, s) in surfaces.iter_mut().enumerate() {
            if let Some(Some(h)) = hits.get(i) {
                *s = Some(self.scene.surface(&rays[i], h));
            }
        }
        let (direct, shadows) = self.direct_light(&surfaces, known, counts);
        if let Some(record) = record {
            for (i, r) in record.iter_mut().enumerate() {
                *r = PrimaryRecord {
                    hit: hits[i],
                    point: surfaces[i].as_ref().map_or(Vec3::ZERO, |s| s.sh.p),
                    lit: shadows[i].0,
                    shadowed: shadows[i].1,
                    lobe: match &surfaces[i] {
                        Some(s)
                            // A BLEND surface's radiance holds what lies behind it, and a MASK
                            // surface's pixel may hold holes: neither stands for another view.
                            if !s.glass
                                && s.point.roughness != 0.0
                                && !s.mat.is_transparent() =>
                        {
                            s.point.roughness * s.point.roughness
                        }
                        _ => -1.0,
                    },
                    through_cut_out: false,
                };
            }
        }
        for (i, o) in out.iter_mut().enumerate() {
            *o = match &surfaces[i] {
                Some(s) if s.glass => s.emissive,
                Some(s) if s.mat.alpha == AlphaMode::Blend => s.alpha * (s.emissive + direct[i]),
                Some(s) => s.emissive + direct[i],
                None => self.settings.background,
            };
        }
        if depth >= self.settings.max_depth {
            return;
        }
        // Each lane's mirror ray, (glass) refraction ray and (BLEND) continuation ray, traced as
        // three packets; a lane adds the reflection before the refraction, as WHITTED.md's order
        // has it, and what lies behind a BLEND surface last.
        let mut bounces = [[None::<Bounce>; 3]; BATCH];
        for (i, s) in surfaces.iter().enumerate() {
            if let Some(s) = s {
                bounces[i] = self.bounces(&rays[i], s);
            }
        }
        for kind in 0..3 {
            let mut next = [Ray::new(Vec3::ZERO, Vec3::Z); BATCH];
            let mut lanes = [0usize; BATCH];
            let mut k = 0;
            for (i, b) in bounces.iter().enumerate() {
                if let (Some(b), Some(s)) = (b[kind], &surfaces[i]) {
                    (next[k], lanes[k]) = (Ray::new(s.sh.origin_toward(b.dir), b.dir), i);
                    k += 1;
                }
            }
            if k == 0 {
                continue;
            }
            bump(counts, |c| c.secondary += k as u64);
            let mut incoming = [Vec3::ZERO; BATCH];
            let far = [f32::INFINITY; BATCH];
            self.trace(&next[..k], &far[..k], depth + 1, counts, &mut incoming[..k]);
            for (&i, l) in lanes[..k].iter().zip(&incoming[..k]) {
                let w = bounces[i][kind].expect("a traced bounce").weight;
                out[i] += w * *l;
            }
        }
    }

    /// The mirror ray (index 0) and the refraction ray (index 1) a surface asks for below
    /// `max_depth`, with their weights: Fresnel-weighted reflection and refraction for glass
    /// (none under total internal reflection), Schlick-weighted reflection for a smooth opaque
    /// surface, nothing for a rough one.
    fn bounces(&self, ray: &Ray, s: &Surface) -> [Option<Bounce>; 3] {
        let [reflection, refraction] = self.specular_bounces(ray, s);
        let mut out = [reflection, refraction, None];
        if s.mapped {
            // A mirror ray below the geometric surface, or a refracted ray above it, is not
            // traced: its weight is dropped (WHITTED-materials.md section 3).
            let ng = s.sh.ng;
            out[0] = out[0].filter(|b| b.dir.dot(ng) > 0.0);
            out[1] = out[1].filter(|b| b.dir.dot(ng) < 0.0);
        }
        if s.mat.alpha == AlphaMode::Blend {
            for b in out.iter_mut().flatten() {
                b.weight *= s.alpha;
            }
            out[2] = Some(Bounce {
                dir: ray.dir,
                weight: Vec3::splat(1.0 - s.alpha),
            });
        }
        out
    }

    /// The mirror and refraction rays of `bounces`.
    fn specular_bounces(&self, ray: &Ray, s: &Surface) -> [Option<Bounce>; 2] {
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
        } else if s.point.roughness == 0.0 {
            let metallic = s.point.metallic;
            let weight = (1.0 - metallic) * schlick(Vec3::splat(0.04), cos_i)
                + metallic * shading::schlick(base, cos_i);
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
}

#[inline]
pub(super) fn bump(counts: &Cell<RayCounts>, f: impl FnOnce(&mut RayCounts)) {
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
