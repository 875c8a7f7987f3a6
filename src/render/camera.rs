//! The stereo rig: from one glTF camera (its node's world transform and vertical field of view) to
//! one pinhole camera per eye. WHITTED.md section 2 fixes the convention: eyes sit at
//! `x_e = -+interaxial/2` on the camera's local X axis; for `off-axis` both look down the same
//! axis and their frusta are shifted so that the plane at `convergence` has zero parallax;
//! `parallel` drops the shift (zero parallax at infinity); `toe-in` turns each eye toward the
//! convergence point on the axis (keystone and vertical parallax away from the centre, kept
//! because users ask to reproduce it); `mono` is the centre eye alone.

use super::view::View;
use crate::accel::{F4, Ray};
use glam::{Mat3, Mat4, Vec2, Vec3};
use serde::Deserialize;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Rig {
    #[default]
    OffAxis,
    Parallel,
    ToeIn,
    Mono,
}

/// Everything the rig needs besides the eye.
#[derive(Clone, Copy, Debug)]
pub struct RigParams {
    pub rig: Rig,
    pub interaxial: f32,
    pub convergence: f32,
    pub width: u32,
    pub height: u32,
    pub yfov: f32,
    pub znear: f32,
    pub zfar: Option<f32>,
}

/// One eye's pinhole camera.
#[derive(Clone, Debug)]
pub struct EyeCamera {
    /// Rigid world transform of the rig's centre (the glTF camera node), and its inverse.
    world: Mat4,
    to_rig: Mat4,
    /// Eye position on the rig's local X axis, metres.
    x_e: f32,
    /// The eye in the world (`world` applied to `x_e`), once rather than per ray.
    position: Vec3,
    /// Horizontal tangent shift of the frustum (off-axis only): `x_e / convergence`.
    shift: f32,
    /// Rotation of the eye about its local Y axis (toe-in only).
    toe: Mat3,
    tan_x: f32,
    tan_y: f32,
    width: f32,
    height: f32,
    znear: f32,
    zfar: Option<f32>,
}

impl EyeCamera {
    /// The camera of a view: the eye sits `interaxial * offset_fraction` metres along the rig's
    /// X axis (at the centre for a mono rig, whatever the interaxial).
    pub fn new(world: Mat4, p: &RigParams, view: View) -> EyeCamera {
        let x_e = if p.rig == Rig::Mono {
            0.0
        } else {
            p.interaxial * view.offset_fraction()
        };
        let tan_y = (p.yfov * 0.5).tan();
        let (shift, toe) = match p.rig {
            Rig::OffAxis => (x_e / p.convergence, Mat3::IDENTITY),
            Rig::ToeIn => (0.0, Mat3::from_rotation_y(x_e.atan2(p.convergence))),
            Rig::Parallel | Rig::Mono => (0.0, Mat3::IDENTITY),
        };
        EyeCamera {
            world,
            to_rig: world.inverse(),
            x_e,
            position: world.transform_point3(Vec3::new(x_e, 0.0, 0.0)),
            shift,
            toe,
            tan_x: tan_y * p.width as f32 / p.height as f32,
            tan_y,
            width: p.width as f32,
            height: p.height as f32,
            znear: p.znear,
            zfar: p.zfar,
        }
    }

    /// World position of the eye.
    pub fn position(&self) -> Vec3 {
        self.position
    }

    /// Primary ray through film point (px, py) in pixels (x right, y down), starting on the near
    /// plane, and the far limit in units of the (unit) direction.
    pub fn ray(&self, px: f32, py: f32) -> (Ray, f32) {
        let eye_dir = Vec3::new(
            (2.0 * px / self.width - 1.0) * self.tan_x - self.shift,
            (1.0 - 2.0 * py / self.height) * self.tan_y,
            -1.0,
        );
        // eye_dir has depth 1 in the eye's own frame, so multiples of it measure depth.
        let cam_dir = self.toe * eye_dir;
        let origin = self.position;
        let dir = self.world.transform_vector3(cam_dir);
        let len = dir.length();
        let start = origin + dir * self.znear;
        let t_max = self
            .zfar
            .map_or(f32::INFINITY, |f| (f - self.znear).max(0.0) * len);
        (Ray::new(start, dir / len), t_max)
    }

    /// `ray` for four film points at once: lane by lane the same IEEE operations in the same
    /// order (glam's: a matrix times a vector sums its columns first to last), so each ray and
    /// limit is bit for bit `ray`'s, with four rays' divisions and square roots in one
    /// instruction each (one ray at a time, camera rays were 6% of a diffuse frame).
    pub fn rays4(&self, px: [f32; 4], py: [f32; 4]) -> ([Ray; 4], [f32; 4]) {
        let s = F4::splat;
        let two = s(2.0);
        let eye_dir = [
            two.mul(F4::new(px))
                .div(s(self.width))
                .sub(s(1.0))
                .mul(s(self.tan_x))
                .sub(s(self.shift)),
            s(1.0)
                .sub(two.mul(F4::new(py)).div(s(self.height)))
                .mul(s(self.tan_y)),
            s(-1.0),
        ];
        let times = |columns: [Vec3; 3], v: [F4; 3]| -> [F4; 3] {
            std::array::from_fn(|row| {
                let c = |i: usize| s(columns[i][row]);
                c(0).mul(v[0]).add(c(1).mul(v[1])).add(c(2).mul(v[2]))
            })
        };
        let cam_dir = times([self.toe.x_axis, self.toe.y_axis, self.toe.z_axis], eye_dir);
        let w = &self.world;
        let dir = times(
            [
                w.x_axis.truncate(),
                w.y_axis.truncate(),
                w.z_axis.truncate(),
            ],
            cam_dir,
        );
        let len = dir[0]
            .mul(dir[0])
            .add(dir[1].mul(dir[1]))
            .add(dir[2].mul(dir[2]))
            .sqrt();
        let start = std::array::from_fn::<_, 3, _>(|c| {
            s(self.position[c])
                .add(dir[c].mul(s(self.znear)))
                .to_array()
        });
        let unit = dir.map(|d| d.div(len).to_array());
        let t_max = self
            .zfar
            .map_or(s(f32::INFINITY), |f| s((f - self.znear).max(0.0)).mul(len));
        let lane = |i: usize, v: &[[f32; 4]; 3]| Vec3::new(v[0][i], v[1][i], v[2][i]);
        (
            std::array::from_fn(|i| Ray::new(lane(i, &start), lane(i, &unit))),
            t_max.to_array(),
        )
    }

    /// The projection of `project` as one matrix, for points and directions alike: a world
    /// point (w = 1) or direction (w = 0, its point at infinity) maps to (X, Y, Z, W) with film position (X / W, Y / W), ahead of the
    /// eye where W > 0 (W is the depth in the eye's frame). Equal to them up to rounding.
    pub fn film_matrix(&self) -> Mat4 {
        let (w, h) = (self.width, self.height);
        // e -> (film_x * -e.z, film_y * -e.z, 0, -e.z) for e in the eye's (toed) frame.
        let to_film = Mat4::from_cols_array(&[
            0.5 * w / self.tan_x,
            0.0,
            0.0,
            0.0,
            0.0,
            -0.5 * h / self.tan_y,
            0.0,
            0.0,
            -(self.shift / self.tan_x + 1.0) * 0.5 * w,
            -0.5 * h,
            0.0,
            -1.0,
            0.0,
            0.0,
            0.0,
            0.0,
        ]);
        to_film
            * Mat4::from_mat3(self.toe.transpose())
            * Mat4::from_translation(Vec3::new(-self.x_e, 0.0, 0.0))
            * self.to_rig
    }

    /// Depth of a world point along the rig's viewing axis (metres; negative behind the rig):
    /// for off-axis and parallel rigs every eye's depth.
    pub fn depth(&self, world_point: Vec3) -> f32 {
        -self.to_rig.transform_point3(world_point).z
    }

    /// Depth of the near plane, metres: camera rays start there.
    pub fn znear(&self) -> f32 {
        self.znear
    }

    /// The point on the rig's viewing axis at `depth` metres.
    pub fn axis_point(&self, depth: f32) -> Vec3 {
        self.world.transform_point3(Vec3::new(0.0, 0.0, -depth))
    }

    /// How far a point moves along its film row from this eye's film to `other`'s, in pixels, as
    /// `(a, b)`: `a + b / depth` for a point `depth` metres deep (`a` at infinity). Exact for
    /// eyes that share their orientation (off-axis, parallel and mono rigs), whose film rows
    /// hold the same points; from `project`: film x is `k ((X - x_e) / depth + shift) + w / 2`.
    pub fn parallax_line(&self, other: &EyeCamera) -> (f32, f32) {
        let k = 0.5 * self.width / self.tan_x;
        (k * (other.shift - self.shift), k * (self.x_e - other.x_e))
    }

    /// Film position (pixels) of a world point, or `None` behind the eye: the inverse of `ray`.
    pub fn project(&self, world_point: Vec3) -> Option<Vec2> {
        let local = self.to_rig.transform_point3(world_point) - Vec3::new(self.x_e, 0.0, 0.0);
        let e = self.toe.transpose() * local;
        if e.z >= 0.0 {
            return None;
        }
        let x = e.x / -e.z;
        let y = e.y / -e.z;
        Some(Vec2::new(
            ((x + self.shift) / self.tan_x + 1.0) * 0.5 * self.width,
            (1.0 - y / self.tan_y) * 0.5 * self.height,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    fn params(rig: Rig) -> RigParams {
        RigParams {
            rig,
            interaxial: 0.065,
            convergence: 3.0,
            width: 640,
            height: 360,
            yfov: 0.8,
            znear: 0.1,
            zfar: None,
        }
    }

    fn world() -> Mat4 {
        Mat4::from_rotation_translation(
            Quat::from_euler(glam::EulerRot::YXZ, 0.4, -0.2, 0.05),
            Vec3::new(1.0, 2.0, 5.0),
        )
    }

    fn rig_point(local: Vec3) -> Vec3 {
        world().transform_point3(local)
    }

    #[test]
    fn off_axis_points_on_the_convergence_plane_land_on_the_same_pixel_in_both_eyes() {
        let p = params(Rig::OffAxis);
        let l = EyeCamera::new(world(), &p, View::LEFT);
        let r = EyeCamera::new(world(), &p, View::RIGHT);
        for (x, y) in [(0.0, 0.0), (0.7, 0.3), (-1.2, -0.5), (1.5, 0.8)] {
            let q = rig_point(Vec3::new(x, y, -3.0));
            let (a, b) = (l.project(q).unwrap(), r.project(q).unwrap());
            assert!((a - b).length() < 1e-3, "{a} vs {b}");
        }
    }

    #[test]
    fn off_axis_parallax_matches_the_whitted_formula_and_has_no_vertical_part() {
        let p = params(Rig::OffAxis);
        let l = EyeCamera::new(world(), &p, View::LEFT);
        let r = EyeCamera::new(world(), &p, View::RIGHT);
        let tan_x = (p.yfov * 0.5).tan() * 640.0 / 360.0;
        for z in [1.0f32, 2.0, 6.0, 50.0] {
            let q = rig_point(Vec3::new(0.3, -0.2, -z));
            let d = r.project(q).unwrap() - l.project(q).unwrap();
            let expected = 320.0 * p.interaxial * (1.0 / p.convergence - 1.0 / z) / tan_x;
            assert!(
                (d.x - expected).abs() < 2e-3,
                "z={z}: {} vs {expected}",
                d.x
            );
            assert!(d.y.abs() < 1e-3);
        }
    }

    #[test]
    fn the_parallax_line_gives_the_film_shift_between_eyes_by_depth() {
        for rig in [Rig::OffAxis, Rig::Parallel, Rig::Mono] {
            let p = params(rig);
            let l = EyeCamera::new(world(), &p, View::LEFT);
            let r = EyeCamera::new(world(), &p, View::RIGHT);
            let (a, b) = l.parallax_line(&r);
            for (x, y, z) in [(0.3, -0.2, 1.0), (-1.0, 0.5, 2.5), (2.0, 1.0, 40.0)] {
                let q = rig_point(Vec3::new(x, y, -z));
                let d = r.project(q).unwrap() - l.project(q).unwrap();
                assert!((d.x - (a + b / z)).abs() < 2e-3, "{rig:?} z={z}: {d}");
            }
        }
    }

    #[test]
    fn toe_in_converges_on_the_axis_only() {
        let p = params(Rig::ToeIn);
        let l = EyeCamera::new(world(), &p, View::LEFT);
        let r = EyeCamera::new(world(), &p, View::RIGHT);
        let on_axis = rig_point(Vec3::new(0.0, 0.0, -3.0));
        assert!((l.project(on_axis).unwrap() - r.project(on_axis).unwrap()).length() < 1e-3);
        let corner = rig_point(Vec3::new(1.5, 0.8, -3.0));
        let d = r.project(corner).unwrap() - l.project(corner).unwrap();
        assert!(
            d.y.abs() > 1e-2,
            "toe-in should show vertical parallax off-axis"
        );
    }

    #[test]
    fn ray_and_project_are_inverse() {
        for rig in [Rig::OffAxis, Rig::Parallel, Rig::ToeIn, Rig::Mono] {
            let p = params(rig);
            let c = EyeCamera::new(world(), &p, View::LEFT);
            let (ray, _) = c.ray(123.25, 77.5);
            let px = c.project(ray.at(4.0)).unwrap();
            assert!(
                (px - Vec2::new(123.25, 77.5)).length() < 1e-2,
                "{rig:?} {px}"
            );
        }
    }

    #[test]
    fn the_film_matrix_projects_as_project_does() {
        for rig in [Rig::OffAxis, Rig::Parallel, Rig::ToeIn] {
            let c = EyeCamera::new(world(), &params(rig), View::RIGHT);
            let m = c.film_matrix();
            for (px, py) in [(10.5, 20.25), (600.0, 300.0), (320.0, 180.0)] {
                let (ray, _) = c.ray(px, py);
                let p = m * ray.at(3.0).extend(1.0);
                let q = glam::Vec2::new(p.x / p.w, p.y / p.w);
                assert!(
                    (q - c.project(ray.at(3.0)).unwrap()).length() < 1e-2,
                    "{rig:?} {q}"
                );
                let d = m * ray.dir.extend(0.0);
                let q = glam::Vec2::new(d.x / d.w, d.y / d.w);
                assert!((q - glam::Vec2::new(px, py)).length() < 1e-2, "{rig:?} {q}");
            }
        }
    }

    #[test]
    fn a_mono_rig_puts_every_view_at_the_centre() {
        let p = params(Rig::Mono);
        let centre = EyeCamera::new(world(), &p, View::CENTER).position();
        for v in [View::LEFT, View::RIGHT, View::along_baseline(1, 3)] {
            assert_eq!(EyeCamera::new(world(), &p, v).position(), centre);
        }
        let stereo = params(Rig::OffAxis);
        let l = EyeCamera::new(world(), &stereo, View::LEFT).position();
        let r = EyeCamera::new(world(), &stereo, View::RIGHT).position();
        assert!(((r - l).length() - stereo.interaxial).abs() < 1e-6);
    }

    #[test]
    fn four_rays_at_once_are_bit_for_bit_one_at_a_time() {
        let bits = |r: &Ray, t: f32| {
            let v = [r.origin.to_array(), r.dir.to_array()].concat();
            (
                v.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
                t.to_bits(),
            )
        };
        let mut seed = 0x9e37_79b9u32;
        let mut next = move |scale: f32| {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            (seed >> 8) as f32 / (1u32 << 24) as f32 * scale
        };
        for rig in [Rig::OffAxis, Rig::Parallel, Rig::ToeIn, Rig::Mono] {
            for zfar in [None, Some(40.0), Some(0.05)] {
                let p = RigParams {
                    zfar,
                    ..params(rig)
                };
                for view in [View::LEFT, View::RIGHT] {
                    let c = EyeCamera::new(world(), &p, view);
                    for _ in 0..500 {
                        let px: [f32; 4] = std::array::from_fn(|_| next(640.0));
                        let py: [f32; 4] = std::array::from_fn(|_| next(360.0));
                        let (rays, limits) = c.rays4(px, py);
                        for i in 0..4 {
                            let (one, limit) = c.ray(px[i], py[i]);
                            assert_eq!(bits(&rays[i], limits[i]), bits(&one, limit));
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn primary_rays_start_on_the_near_plane() {
        let p = params(Rig::OffAxis);
        let c = EyeCamera::new(Mat4::IDENTITY, &p, View::RIGHT);
        let (ray, _) = c.ray(0.0, 0.0);
        assert!((ray.origin.z + p.znear).abs() < 1e-6);
    }
}
