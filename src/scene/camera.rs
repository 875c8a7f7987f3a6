//! Cameras as the glTF file defines them (perspective only), and the documented default used when a
//! scene has none: a camera that frames the scene's bounds.

use glam::{Mat4, Quat, Vec3};

#[derive(Clone, Debug)]
pub struct CameraDef {
    pub name: Option<String>,
    /// Vertical field of view in radians.
    pub yfov: f32,
    /// Width / height; `None` means "use the output's aspect".
    pub aspect_ratio: Option<f32>,
    pub znear: f32,
    /// `None` is an infinite far plane.
    pub zfar: Option<f32>,
}

/// Vertical field of view of the default camera: 45 degrees, a normal lens.
const DEFAULT_YFOV: f32 = std::f32::consts::FRAC_PI_4;

/// The default camera for a scene without one: it looks at the centre of the bounds from the +Z
/// side, raised 20 degrees, far enough that the bounding sphere fits the vertical field of view.
/// Returns the camera and its world matrix.
pub fn framing_camera(min: Vec3, max: Vec3) -> (CameraDef, Mat4) {
    let center = (min + max) * 0.5;
    let radius = ((max - min).length() * 0.5).max(1e-3);
    let distance = radius / (DEFAULT_YFOV * 0.5).sin() * 1.05;
    let elevation = 20f32.to_radians();
    let dir = Vec3::new(0.0, elevation.sin(), elevation.cos());
    let eye = center + dir * distance;
    let rotation = look_rotation(-dir);
    let camera = CameraDef {
        name: Some("default framing camera".into()),
        yfov: DEFAULT_YFOV,
        aspect_ratio: None,
        znear: (distance - radius).max(distance * 1e-3) * 0.5,
        zfar: None,
    };
    (camera, Mat4::from_rotation_translation(rotation, eye))
}

/// Rotation that turns the camera's -Z toward `forward` with +Y as close to world up as possible.
pub fn look_rotation(forward: Vec3) -> Quat {
    let f = forward.normalize();
    let up = if f.y.abs() > 0.999 { Vec3::Z } else { Vec3::Y };
    let x = f.cross(up).normalize();
    let y = x.cross(f);
    Quat::from_mat3(&glam::Mat3::from_cols(x, y, -f))
}

/// The distance from `point` to the nearest point of the box `bounds`, or to its centre when
/// `point` is inside it.
pub fn distance_to_bounds(point: Vec3, (lo, hi): (Vec3, Vec3)) -> f32 {
    match point.distance(point.clamp(lo, hi)) {
        d if d > 0.0 => d,
        _ => point.distance((lo + hi) * 0.5),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn framing_camera_looks_at_the_centre_of_the_bounds() {
        let (cam, m) = framing_camera(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(3.0, 2.0, 1.0));
        let eye = m.transform_point3(Vec3::ZERO);
        let forward = m.transform_vector3(Vec3::NEG_Z);
        let to_center = (Vec3::new(1.0, 1.0, 0.0) - eye).normalize();
        assert!(forward.dot(to_center) > 0.9999);
        assert!(cam.znear > 0.0);
    }
}
