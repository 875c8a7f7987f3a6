//! Alpha coverage in the integrator's rays (WHITTED-materials.md section 4): MASK hits below
//! the cutoff do not exist for any ray, and shadow rays pass cut-outs and let `1 - a` through
//! each BLEND surface. Scenes without MASK or BLEND materials skip all of it.

use super::BATCH;
use super::integrator::{Integrator, RayCounts, bump};
use crate::accel::{Hit, Intersect, Ray};
use crate::scene::light::{Light, LightKind};
use crate::scene::material::AlphaMode;
use glam::Vec3;
use std::cell::Cell;

/// Cut-outs and BLEND surfaces one ray passes at most: a guard against a ray that the offset
/// fails to move past a surface, far above the layers of foliage or fences real scenes stack.
const MAX_CROSSINGS: usize = 256;

impl<A: Intersect> Integrator<'_, A> {
    /// MASK hits whose coverage is below the cutoff do not exist for any ray: each such lane
    /// goes on from the far side of the hit, same direction, for the rest of its range, until
    /// it finds a hit that exists or nothing (WHITTED-materials.md section 4). The hit's `t`
    /// stays measured from the first origin. Returns the lanes (bit i: lane i) that passed one.
    #[inline]
    pub(super) fn pass_cut_outs(
        &self,
        rays: &[Ray],
        t_max: &[f32],
        hits: &mut [Option<Hit>],
        counts: &Cell<RayCounts>,
    ) -> u32 {
        if !self.transparent {
            return 0;
        }
        let mut passed = 0u32;
        let mut current = [Ray::new(Vec3::ZERO, Vec3::Z); BATCH];
        current[..rays.len()].copy_from_slice(rays);
        let mut travelled = [0.0f32; BATCH];
        for crossing in 0..=MAX_CROSSINGS {
            let mut next = [Ray::new(Vec3::ZERO, Vec3::Z); BATCH];
            let mut limits = [0.0; BATCH];
            let mut lanes = [0usize; BATCH];
            let mut k = 0;
            for (i, hit) in hits.iter_mut().enumerate() {
                let Some(h) = *hit else { continue };
                let ray = current[i];
                let Some(sh) = self.scene.cut_out(&ray, &h) else {
                    continue;
                };
                if crossing == MAX_CROSSINGS {
                    *hit = None;
                    continue;
                }
                current[i] = Ray::new(sh.origin_toward(ray.dir), ray.dir);
                travelled[i] = h.t;
                passed |= 1 << i;
                (next[k], limits[k], lanes[k]) = (current[i], t_max[i] - h.t, i);
                k += 1;
            }
            if k == 0 {
                return passed;
            }
            bump(counts, |c| c.secondary += k as u64);
            let mut found = [None; BATCH];
            self.scene
                .accel
                .closest_hits(&next[..k], &limits[..k], &mut found[..k]);
            for (&i, f) in lanes[..k].iter().zip(found) {
                hits[i] = f.map(|h| Hit {
                    t: h.t + travelled[i],
                    ..h
                });
            }
        }
        passed
    }

    /// The fraction of a light's shadow rays that arrives: 0 behind an opaque, transmissive or
    /// uncut MASK surface; cut-outs are passed; each BLEND surface crossed lets `1 - a` through
    /// (untinted, WHITTED-materials.md section 4). Without MASK or BLEND materials it is the
    /// any-hit answer.
    #[inline]
    pub(super) fn visibility(
        &self,
        light: &Light,
        rays: &[Ray],
        t_max: &[f32],
        out: &mut [f32],
        counts: &Cell<RayCounts>,
    ) {
        let n = rays.len();
        if !self.transparent {
            let mut blocked = [false; BATCH];
            self.scene.accel.any_hits(rays, t_max, &mut blocked[..n]);
            for (o, b) in out.iter_mut().zip(blocked) {
                *o = if b { 0.0 } else { 1.0 };
            }
            return;
        }
        out.fill(1.0);
        let mut current = [Ray::new(Vec3::ZERO, Vec3::Z); BATCH];
        let mut limits = [0.0; BATCH];
        let mut lanes = [0usize; BATCH];
        current[..n].copy_from_slice(rays);
        limits[..n].copy_from_slice(t_max);
        for (i, l) in lanes[..n].iter_mut().enumerate() {
            *l = i;
        }
        let mut k = n;
        let mut first = true;
        for _ in 0..MAX_CROSSINGS {
            if k == 0 {
                return;
            }
            if !first {
                bump(counts, |c| c.shadow += k as u64);
            }
            first = false;
            let mut found = [None; BATCH];
            self.scene
                .accel
                .closest_hits(&current[..k], &limits[..k], &mut found[..k]);
            let mut still = 0;
            for j in 0..k {
                let (i, ray) = (lanes[j], current[j]);
                let Some(hit) = found[j] else { continue };
                let material = self.scene.geometry.triangle_materials[hit.prim as usize];
                let mat = &self.scene.materials[material as usize];
                if mat.alpha == AlphaMode::Opaque {
                    out[i] = 0.0;
                    continue;
                }
                let sh = self.scene.shading_point(&ray, &hit);
                let a = self.scene.base_color(mat, &sh).w;
                // MASK passes its cut-outs; BLEND (opaque blocked above) lets 1 - a through.
                let passes = if let AlphaMode::Mask { cutoff } = mat.alpha {
                    a < cutoff
                } else {
                    out[i] *= 1.0 - a;
                    out[i] > 0.0
                };
                if !passes {
                    out[i] = 0.0;
                    continue;
                }
                // On from the far side of the crossing: to the light's position (spawn_ray_to)
                // or, for a directional light, along the same direction without end.
                let origin = sh.origin_toward(ray.dir);
                let dir = match light.kind {
                    LightKind::Directional => ray.dir,
                    LightKind::Point | LightKind::Spot { .. } => light.position - origin,
                };
                (current[still], limits[still], lanes[still]) =
                    (Ray::new(origin, dir), limits[j], i);
                still += 1;
            }
            k = still;
        }
        for &i in &lanes[..k] {
            out[i] = 0.0;
        }
    }
}
