//! The depth probe: what a frame holds in depth, measured before (or beside) its render. One
//! camera ray per probe pixel from the rig's centre, closest hit only, on a grid of at most
//! `PROBE_COLUMNS` columns spread evenly over the film. The stereo comfort rules
//! (`comfort.rs`) read the depths: the nearest and farthest visible point, the depth at the
//! centre of the frame, and the nearest point of each column for the frame edges.
//!
//! Depth is the camera-space distance along the rig's viewing axis (`-z` in the rig's frame):
//! the eyes of an off-axis or parallel rig look down that axis, so it is each eye's own depth
//! too, and parallax depends on nothing else (WHITTED.md section 2).

use super::camera::{EyeCamera, Rig, RigParams};
use super::view::View;
use crate::accel::{Intersect, Ray};
use glam::Mat4;
use rayon::prelude::*;

/// At most this many probe columns (and rows at the same spacing): a 1920-pixel film is
/// probed every 4 pixels, 130k closest-hit rays, under 1% of its camera rays at 4 samples per
/// pixel and two eyes, and a film up to 480 pixels wide in every pixel.
pub const PROBE_COLUMNS: usize = 480;

/// The camera a probe looks through: the rig's centre, its lens and film size.
#[derive(Clone, Copy, Debug)]
pub struct ProbeCamera {
    pub world: Mat4,
    pub yfov: f32,
    pub znear: f32,
    pub zfar: Option<f32>,
    pub width: u32,
    pub height: u32,
}

/// The depths a probe found (metres along the viewing axis).
#[derive(Clone, Debug, PartialEq)]
pub struct DepthProbe {
    /// The nearest and farthest hit; `None` when every probe ray missed.
    pub near: Option<f32>,
    pub far: Option<f32>,
    /// The median depth of the hits in the middle third of the film, both ways.
    pub centre: Option<f32>,
    /// The depth a twentieth of the hits are nearer than: where most of what the camera sees
    /// begins, a stray near object aside (the head-light of a camera inside the scene).
    pub near_most: Option<f32>,
    /// Per probe column, left to right: its film x (pixels, at the column's centre) and the
    /// nearest depth hit in it (`f32::INFINITY` where every ray of the column missed).
    pub columns: Vec<(f32, f32)>,
}

impl DepthProbe {
    /// Probes `accel` through `camera` on the grid of `probe_grid`.
    pub fn measure(accel: &impl Intersect, camera: &ProbeCamera) -> DepthProbe {
        let (w, h) = (camera.width as usize, camera.height as usize);
        let (cols, rows) = probe_grid(w, h);
        let eye = EyeCamera::new(
            camera.world,
            &RigParams {
                rig: Rig::Mono,
                interaxial: 0.0,
                convergence: 1.0,
                width: camera.width,
                height: camera.height,
                yfov: camera.yfov,
                znear: camera.znear,
                zfar: camera.zfar,
            },
            View::CENTER,
        );
        let x_of = |i: usize| (i as f32 + 0.5) * w as f32 / cols as f32;
        let y_of = |j: usize| (j as f32 + 0.5) * h as f32 / rows as f32;
        // Rows in parallel, each in order, so the result does not depend on the thread count.
        let depths: Vec<Vec<f32>> = (0..rows)
            .into_par_iter()
            .map(|j| {
                let (rays, limits): (Vec<Ray>, Vec<f32>) =
                    (0..cols).map(|i| eye.ray(x_of(i), y_of(j))).unzip();
                let mut hits = vec![None; cols];
                accel.closest_hits(&rays, &limits, &mut hits);
                rays.iter()
                    .zip(&hits)
                    .map(|(r, hit)| {
                        hit.map_or(f32::INFINITY, |hit| eye.depth(r.origin + r.dir * hit.t))
                    })
                    .collect()
            })
            .collect();
        let hits = || depths.iter().flatten().copied().filter(|d| d.is_finite());
        let near = hits().reduce(f32::min);
        let mut all: Vec<f32> = hits().collect();
        all.sort_unstable_by(f32::total_cmp);
        let near_most = all.get(all.len() / 20).copied();
        let far = hits().reduce(f32::max);
        let mut middle: Vec<f32> = depths[rows / 3..rows - rows / 3]
            .iter()
            .flat_map(|row| &row[cols / 3..cols - cols / 3])
            .copied()
            .filter(|d| d.is_finite())
            .collect();
        middle.sort_unstable_by(f32::total_cmp);
        let centre = middle.get(middle.len() / 2).copied();
        let columns = (0..cols)
            .map(|i| {
                let nearest = depths
                    .iter()
                    .map(|row| row[i])
                    .fold(f32::INFINITY, f32::min);
                (x_of(i), nearest)
            })
            .collect();
        DepthProbe {
            near,
            far,
            centre,
            near_most,
            columns,
        }
    }
}

/// The probe grid for a `width` x `height` film: at most `PROBE_COLUMNS` columns, and rows at
/// about the same spacing (at least one of each).
pub fn probe_grid(width: usize, height: usize) -> (usize, usize) {
    let cols = width.clamp(1, PROBE_COLUMNS);
    let rows = (height * cols)
        .div_ceil(width.max(1))
        .clamp(1, height.max(1));
    (cols, rows)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::BruteForce;
    use glam::Vec3;

    /// A wall facing the camera at depth `z` behind a square at depth `near` covering the
    /// film's left quarter.
    fn scene(z: f32, near: f32) -> BruteForce {
        let quad = |x0: f32, x1: f32, y0: f32, y1: f32, d: f32| {
            [
                [
                    Vec3::new(x0, y0, -d),
                    Vec3::new(x1, y0, -d),
                    Vec3::new(x1, y1, -d),
                ],
                [
                    Vec3::new(x0, y0, -d),
                    Vec3::new(x1, y1, -d),
                    Vec3::new(x0, y1, -d),
                ],
            ]
        };
        let mut triangles = quad(-50.0, 50.0, -50.0, 50.0, z).to_vec();
        triangles.extend(quad(-50.0, -0.5, -50.0, 50.0, near));
        BruteForce { triangles }
    }

    fn camera() -> ProbeCamera {
        ProbeCamera {
            world: Mat4::IDENTITY,
            yfov: 0.8,
            znear: 0.1,
            zfar: None,
            width: 200,
            height: 100,
        }
    }

    #[test]
    fn the_probe_finds_the_depths_of_a_wall_and_of_a_square_before_it() {
        let p = DepthProbe::measure(&scene(4.0, 2.0), &camera());
        assert!((p.near.unwrap() - 2.0).abs() < 1e-5, "{p:?}");
        assert!((p.far.unwrap() - 4.0).abs() < 1e-5);
        assert!((p.centre.unwrap() - 4.0).abs() < 1e-5);
        assert_eq!(p.columns.len(), 200);
        assert!((p.columns[0].1 - 2.0).abs() < 1e-5);
        assert!((p.columns[199].1 - 4.0).abs() < 1e-5);
        assert_eq!(p.columns[0].0, 0.5);
    }

    #[test]
    fn a_film_wider_than_the_probe_is_probed_evenly_and_a_miss_is_infinite() {
        assert_eq!(probe_grid(1920, 1080), (480, 270));
        assert_eq!(probe_grid(1, 1), (1, 1));
        let empty = BruteForce {
            triangles: Vec::<[Vec3; 3]>::new(),
        };
        let p = DepthProbe::measure(&empty, &camera());
        assert_eq!((p.near, p.far, p.centre), (None, None, None));
        assert!(p.columns.iter().all(|c| c.1 == f32::INFINITY));
    }
}
