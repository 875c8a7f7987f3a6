//! The light a scene without lights gets: a point light at the rig's centre, bright enough to
//! show the scene and dim enough that no white surface clips.

use crate::scene::{Light, LightKind, distance_to_bounds};
use glam::{Mat4, Vec3};

/// The radiance of a white diffuse surface facing the head-light at the nearest point of the
/// scene's bounds: below 1 so that the nearest surfaces keep their shading instead of clipping
/// to white in an 8-bit output (surfaces further away are darker by the square of distance).
const HEAD_LIGHT_WHITE: f32 = 0.8;

/// A scene without lights gets a head-light: a point light at the rig's centre whose intensity
/// is `HEAD_LIGHT_WHITE * pi * d^2`, with `d` the distance to the nearest point of the scene's
/// bounds. From inside the bounds (a camera among buildings, a room) the nearest point of the
/// bounds is the camera itself; there `d` is the depth that a twentieth of what the camera sees
/// is nearer than (`nearest_seen`, from the depth probe), so that a stray object by the lens
/// does not darken the view while at most that twentieth can clip; the bounds' centre when the
/// camera sees nothing.
pub(super) fn head_light(
    camera: &Mat4,
    bounds: Option<(Vec3, Vec3)>,
    nearest_seen: impl FnOnce() -> Option<f32>,
) -> Light {
    let position = camera.transform_point3(Vec3::ZERO);
    let d = match bounds {
        None => 1.0,
        Some((lo, hi)) if position.cmpge(lo).all() && position.cmple(hi).all() => {
            nearest_seen().unwrap_or_else(|| distance_to_bounds(position, (lo, hi)))
        }
        Some(b) => distance_to_bounds(position, b),
    };
    let d2 = (d * d).max(1e-6);
    Light {
        kind: LightKind::Point,
        power: Vec3::splat(HEAD_LIGHT_WHITE * std::f32::consts::PI * d2),
        position,
        direction: camera.transform_vector3(Vec3::NEG_Z),
        range: None,
    }
}
