//! KHR_lights_punctual lights: their definition in the file, and the world-space light a posed frame
//! shades with. Radiometry follows WHITTED.md: `intensity * color` is used directly as radiant
//! intensity (point, spot) or irradiance (directional), with no 683 lm/W or 4*pi factor.

use glam::{Mat4, Vec3};

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightKind {
    Point,
    /// Cone angles in radians, measured from the spot direction.
    Spot {
        inner_cone: f32,
        outer_cone: f32,
    },
    Directional,
}

#[derive(Clone, Debug)]
pub struct LightDef {
    pub name: Option<String>,
    pub kind: LightKind,
    pub color: Vec3,
    pub intensity: f32,
    /// Distance past which the light has no effect (point and spot only).
    pub range: Option<f32>,
}

/// A light placed in the world for one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Light {
    pub kind: LightKind,
    /// `intensity * color`.
    pub power: Vec3,
    pub position: Vec3,
    /// Direction the light points to (the node's -Z), unit length.
    pub direction: Vec3,
    pub range: Option<f32>,
}

impl Light {
    pub fn place(def: &LightDef, world: &Mat4) -> Light {
        Light {
            kind: def.kind,
            power: def.color * def.intensity,
            position: world.transform_point3(Vec3::ZERO),
            direction: world
                .transform_vector3(Vec3::NEG_Z)
                .normalize_or(Vec3::NEG_Z),
            range: def.range,
        }
    }

    /// Attenuation of a spot light's cone for a direction `to_light` (unit, from the shaded point to
    /// the light), as the KHR_lights_punctual specification's reference implementation computes it:
    /// a smooth ramp from the outer to the inner cone, squared.
    pub fn cone_attenuation(&self, to_light: Vec3) -> f32 {
        match self.kind {
            LightKind::Spot {
                inner_cone,
                outer_cone,
            } => {
                let cos_outer = outer_cone.cos();
                let scale = 1.0 / (inner_cone.cos() - cos_outer).max(0.001);
                let offset = -cos_outer * scale;
                let cd = self.direction.dot(-to_light);
                let a = (cd * scale + offset).clamp(0.0, 1.0);
                a * a
            }
            _ => 1.0,
        }
    }

    /// Range window of KHR_lights_punctual (its recommended `clamp(1 - (d/range)^4, 0, 1)`),
    /// multiplied with the inverse-square falloff.
    pub fn range_attenuation(&self, distance: f32) -> f32 {
        match self.range {
            Some(r) if r > 0.0 => (1.0 - (distance / r).powi(4)).clamp(0.0, 1.0),
            _ => 1.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spot() -> Light {
        Light {
            kind: LightKind::Spot {
                inner_cone: 0.2,
                outer_cone: 0.4,
            },
            power: Vec3::ONE,
            position: Vec3::ZERO,
            direction: Vec3::NEG_Z,
            range: None,
        }
    }

    #[test]
    fn spot_cone_is_full_inside_inner_and_dark_outside_outer() {
        let s = spot();
        // The point is down -Z from the light, so the direction to the light is +Z.
        assert_eq!(s.cone_attenuation(Vec3::Z), 1.0);
        let outside = Vec3::new(0.5f32.sin(), 0.0, 0.5f32.cos());
        assert_eq!(s.cone_attenuation(outside), 0.0);
        let between = Vec3::new(0.3f32.sin(), 0.0, 0.3f32.cos());
        let a = s.cone_attenuation(between);
        assert!(a > 0.0 && a < 1.0);
    }

    #[test]
    fn range_window_reaches_zero_at_the_range() {
        let mut s = spot();
        s.range = Some(2.0);
        assert_eq!(s.range_attenuation(2.0), 0.0);
        assert!((s.range_attenuation(1.0) - 15.0 / 16.0).abs() < 1e-6);
    }
}
