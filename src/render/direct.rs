//! Direct light at a packet's hits (WHITTED.md section 4): each punctual light's shadow rays
//! from every lane travel the tree as one packet, shadow answers another view already knows are
//! taken instead of rays, and each lane adds its lights' BRDF terms, four lanes at a time, in the
//! scene's order. Recursion and the surface's own values belong to `integrator` and `surface`.

use super::BATCH;
use super::integrator::{Integrator, RECORDED_LIGHTS, RayCounts, bump, offset_origin};
use super::shading::BrdfLanes;
use super::surface::Surface;
use crate::accel::{Intersect, Ray};
use crate::scene::light::LightKind;
use glam::Vec3;
use smallvec::SmallVec;
use std::cell::Cell;

/// Shadow rays stop this fraction short of the light so a light sitting on a surface is not
/// shadowed by that surface.
const SHADOW_EPSILON: f32 = 1e-4;

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

/// A packet's light queries, each with its lane.
type Queries = SmallVec<[(usize, LightQuery); 2 * BATCH]>;

impl<A: Intersect> Integrator<'_, A> {
    /// Direct light at each lane's surface: each light's shadow rays from all lanes travel as one
    /// packet (rays towards one light from neighbouring hits); every lane adds its lights in
    /// the scene's order. A shadow answer in `known` (lit, shadowed bits per lane) is used
    /// instead of its ray. Returns each lane's direct light and its shadow answers as bits.
    pub(super) fn direct_light(
        &self,
        surfaces: &[Option<Surface>; BATCH],
        known: &[(u32, u32); BATCH],
        counts: &Cell<RayCounts>,
    ) -> ([Vec3; BATCH], [(u32, u32); BATCH]) {
        let mut direct = [Vec3::ZERO; BATCH];
        let mut answers = [(0u32, 0u32); BATCH];
        let mut queries = Queries::new();
        for (lane, s) in surfaces.iter().enumerate() {
            if let Some(s) = s {
                self.push_light_queries(lane, s, &mut queries);
            }
        }
        if queries.is_empty() {
            return (direct, answers);
        }
        let mut shadow = [Ray::new(Vec3::ZERO, Vec3::Z); BATCH];
        let mut limits = [0.0; BATCH];
        let mut traced = [0usize; BATCH];
        let mut visible = [0.0f32; BATCH];
        let (mut n_traced, mut n_known) = (0u64, 0u64);
        for light in 0..self.scene.lights.len() {
            let bit = if light < RECORDED_LIGHTS {
                1u32 << light
            } else {
                0
            };
            // This light's queries in lane order (at most one per lane), each answered by a
            // known bit or by a ray.
            let mut members = [0usize; BATCH];
            let mut visible_of = [0.0f32; BATCH];
            let (mut n, mut k) = (0, 0);
            for (index, (lane, q)) in queries.iter().enumerate() {
                if q.light != light {
                    continue;
                }
                let (lit, shadowed) = known[*lane];
                // One bit alone is an answer; both (a partial one) or none are traced.
                if (lit ^ shadowed) & bit != 0 {
                    visible_of[n] = if shadowed & bit != 0 { 0.0 } else { 1.0 };
                } else {
                    (shadow[k], limits[k], traced[k]) = (q.shadow, q.t_max, n);
                    k += 1;
                }
                members[n] = index;
                n += 1;
            }
            if n == 0 {
                continue;
            }
            if k > 0 {
                let light = &self.scene.lights[light];
                self.visibility(light, &shadow[..k], &limits[..k], &mut visible[..k], counts);
                for (&m, &b) in traced[..k].iter().zip(&visible[..k]) {
                    visible_of[m] = b;
                }
            }
            n_traced += k as u64;
            n_known += (n - k) as u64;
            // The lanes this light reaches, four at a time: their BRDFs in lanes, then each
            // lane's term.
            let mut brdf = BrdfLanes::default();
            let mut reached = [(0usize, 0usize, 0.0f32); 4];
            let mut m = 0;
            for (&index, &vis) in members[..n].iter().zip(&visible_of[..n]) {
                let (lane, q) = &queries[index];
                // A light seen through BLEND surfaces is recorded as both lit and shadowed: a
                // window of samples with such an answer disagrees, so another view traces its
                // own shadow rays there.
                if vis < 1.0 {
                    answers[*lane].1 |= bit;
                }
                if vis > 0.0 {
                    answers[*lane].0 |= bit;
                }
                if let (Some(s), true) = (&surfaces[*lane], vis > 0.0) {
                    brdf.set(m, &s.point, s.sh.n, q.l, s.v);
                    reached[m] = (*lane, index, vis);
                    m += 1;
                }
                if m == 4 {
                    self.add_terms(&brdf, &reached, &queries, &mut direct);
                    m = 0;
                }
            }
            self.add_terms(&brdf, &reached[..m], &queries, &mut direct);
        }
        bump(counts, |c| {
            c.shadow += n_traced;
            c.reused_shadow += n_known;
        });
        (direct, answers)
    }

    /// Adds each reached lane's direct term for one light: its BRDF (lane `i` of `brdf` for the
    /// `i`-th of `reached`: lane, query index, visibility), times `n . l` and the irradiance.
    fn add_terms(
        &self,
        brdf: &BrdfLanes,
        reached: &[(usize, usize, f32)],
        queries: &[(usize, LightQuery)],
        direct: &mut [Vec3; BATCH],
    ) {
        if reached.is_empty() {
            return;
        }
        let values = brdf.brdf(self.settings.shading);
        for (&(lane, index, vis), value) in reached.iter().zip(values) {
            let q = &queries[index].1;
            let term = value * q.n_l * q.irradiance;
            direct[lane] += if vis == 1.0 { term } else { vis * term };
        }
    }

    /// Pushes the lights that can reach a surface (none for glass, which takes no direct light),
    /// in the scene's order, each with its shadow ray. A loop, not an iterator: the iterator's
    /// closure was not always inlined (1% more instructions a default frame when it was not).
    #[inline(always)]
    fn push_light_queries(&self, lane: usize, s: &Surface, queries: &mut Queries) {
        let (sh, v) = (&s.sh, s.v);
        let lit = !s.glass && sh.n.dot(v) > 0.0;
        if !lit {
            return;
        }
        let origin = offset_origin(sh.p, sh.ng);
        for (index, light) in self.scene.lights.iter().enumerate() {
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
            let query = LightQuery {
                light: index,
                shadow,
                t_max,
                l,
                n_l,
                irradiance,
            };
            queries.push((lane, query));
        }
    }
}
