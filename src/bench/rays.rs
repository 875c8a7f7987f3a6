//! The rays `bench accel` traces: camera rays through a square film, shadow rays from their hits
//! toward a light, and the binary ray files that replay identical rays in another tracer.

use crate::accel::{Intersect, KdTree, Ray};
use crate::error::{Error, Result};
use crate::render::offset_origin;
use glam::{Mat4, Vec3};
use rayon::prelude::*;
use std::io::Write;
use std::path::Path;

/// A ray with its far limit, as replayed from a file or made from a camera.
pub type TimedRay = (Ray, f32);

/// Reads a ray file: little-endian u64 count, then per ray origin xyz, direction xyz, t_max (f32).
pub fn read_rays(path: &Path) -> Result<Vec<TimedRay>> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let count = bytes
        .get(..8)
        .map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes")))
        .ok_or_else(|| Error::input(path, "ray file shorter than its 8-byte count"))?;
    let body = &bytes[8..];
    if count.checked_mul(28) != Some(body.len() as u64) {
        return Err(Error::input(
            path,
            format!(
                "ray file says {count} rays (28 bytes each) but holds {} bytes after the count",
                body.len()
            ),
        ));
    }
    let f =
        |c: &[u8], i: usize| f32::from_le_bytes(c[4 * i..4 * i + 4].try_into().expect("4 bytes"));
    body.chunks_exact(28)
        .enumerate()
        .map(|(i, c)| {
            let r = Ray::new(
                Vec3::new(f(c, 0), f(c, 1), f(c, 2)),
                Vec3::new(f(c, 3), f(c, 4), f(c, 5)),
            );
            if !(r.origin.is_finite() && r.dir.is_finite() && r.dir != Vec3::ZERO) {
                return Err(Error::input(
                    path,
                    format!("ray {i} has a non-finite origin or a zero direction"),
                ));
            }
            Ok((r, f(c, 6)))
        })
        .collect()
}

/// Writes rays in the format `read_rays` reads.
pub fn write_rays(path: &Path, rays: &[TimedRay]) -> Result<()> {
    crate::output::write_atomic(path, |w| {
        w.write_all(&(rays.len() as u64).to_le_bytes())?;
        for (r, t) in rays {
            for v in [
                r.origin.x, r.origin.y, r.origin.z, r.dir.x, r.dir.y, r.dir.z, *t,
            ] {
                w.write_all(&v.to_le_bytes())?;
            }
        }
        Ok(())
    })
}

/// Square pinhole film of `film` x `film` rays through pixel centres.
pub fn camera_rays(world: Mat4, yfov: f32, film: u32) -> Vec<TimedRay> {
    (0..film * film)
        .map(|i| eye_ray(world, yfov, film, (i % film, i / film), 0.0, 1.0))
        .collect()
}

/// The camera rays of a `film` (columns, rows) given row by row, regrouped tile by tile
/// (`tile` columns and rows, row by row inside a tile), and the shadow rays in the order of
/// their camera rays, where `shadow[k]` belongs to the `k`-th camera ray that `hits` (as the peer
/// workload makes them). `None` when the counts do not fit: the reason.
pub fn regroup_tiles(
    primary: &[TimedRay],
    shadow: &[TimedRay],
    hits: &[bool],
    (fw, fh): (u32, u32),
    (tw, th): (u32, u32),
) -> std::result::Result<(Vec<TimedRay>, Vec<TimedRay>), String> {
    if primary.len() != (fw as usize) * (fh as usize) {
        return Err(format!(
            "{} camera rays are not a {fw}x{fh} film",
            primary.len()
        ));
    }
    let hit_count = hits.iter().filter(|&&h| h).count();
    if shadow.len() != hit_count {
        return Err(format!(
            "{} shadow rays, but {hit_count} camera rays hit: the shadow rays must be one per hit",
            shadow.len()
        ));
    }
    let mut shadow_of = vec![usize::MAX; primary.len()];
    for (k, i) in (0..primary.len()).filter(|&i| hits[i]).enumerate() {
        shadow_of[i] = k;
    }
    let (mut p, mut s) = (
        Vec::with_capacity(primary.len()),
        Vec::with_capacity(shadow.len()),
    );
    for y0 in (0..fh).step_by(th as usize) {
        for x0 in (0..fw).step_by(tw as usize) {
            for y in y0..(y0 + th).min(fh) {
                for x in x0..(x0 + tw).min(fw) {
                    let i = (y * fw + x) as usize;
                    p.push(primary[i]);
                    if hits[i] {
                        s.push(shadow[shadow_of[i]]);
                    }
                }
            }
        }
    }
    Ok((p, s))
}

/// Which eyes `bench accel` makes camera rays for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Eyes {
    /// One pinhole at the camera.
    #[default]
    Center,
    /// The left eye of the stereo rig alone, in the same 2x2 quads (the baseline for `both`).
    Left,
    /// Both eyes of an off-axis rig over the same film, in the order `eye_reuse = "paired"`
    /// traces them: a 2x2 quad of the left eye's pixels, then the same quad of the right's.
    Both,
}

/// Camera rays of an off-axis stereo rig at the camera: eyes `interaxial` apart along the
/// camera's x axis, their frusta sheared to meet on the plane `convergence` ahead.
pub fn stereo_camera_rays(
    world: Mat4,
    yfov: f32,
    film: u32,
    eyes: Eyes,
    (interaxial, convergence): (f32, f32),
) -> Vec<TimedRay> {
    let half = 0.5 * interaxial;
    let mut rays = Vec::with_capacity(2 * (film * film) as usize);
    let sides: &[f32] = match eyes {
        Eyes::Center => &[0.0],
        Eyes::Left => &[-half],
        Eyes::Both => &[-half, half],
    };
    // The centre camera's rays in rows, as `camera_rays`; an eye's in 2x2 quads, as the
    // renderer's packets take them.
    let quad: (u32, u32) = if eyes == Eyes::Center { (1, 1) } else { (2, 2) };
    for y0 in (0..film).step_by(quad.1 as usize) {
        for x0 in (0..film).step_by(quad.0 as usize) {
            for &side in sides {
                for y in y0..(y0 + quad.1).min(film) {
                    for x in x0..(x0 + quad.0).min(film) {
                        rays.push(eye_ray(world, yfov, film, (x, y), side, convergence));
                    }
                }
            }
        }
    }
    rays
}

/// The ray of pixel `(x, y)` from the eye `side` along the camera's x axis, through the point
/// the centre camera's ray of that pixel meets at depth `convergence`.
fn eye_ray(
    world: Mat4,
    yfov: f32,
    film: u32,
    (x, y): (u32, u32),
    side: f32,
    convergence: f32,
) -> TimedRay {
    let t = (yfov * 0.5).tan();
    let (fx, fy) = (x as f32 + 0.5, y as f32 + 0.5);
    let on_plane = Vec3::new(
        (2.0 * fx / film as f32 - 1.0) * t,
        (1.0 - 2.0 * fy / film as f32) * t,
        -1.0,
    ) * convergence;
    let eye = Vec3::new(side, 0.0, 0.0);
    (
        Ray::new(
            world.transform_point3(eye),
            world.transform_vector3(on_plane - eye).normalize(),
        ),
        f32::INFINITY,
    )
}

/// Shadow rays from every primary hit toward a point light above and in front of the scene.
pub fn shadow_rays(tree: &KdTree, tris: &[[Vec3; 3]], primary: &[TimedRay]) -> Vec<TimedRay> {
    let (lo, hi) = tris
        .iter()
        .flatten()
        .fold((Vec3::MAX, Vec3::MIN), |(a, b), &p| (a.min(p), b.max(p)));
    let light = (lo + hi) * 0.5 + Vec3::new(0.3, 1.5, 1.0) * (hi - lo).length();
    primary
        .par_iter()
        .filter_map(|(r, t)| {
            let h = tree.closest_hit(r, *t)?;
            let [a, b, c] = tris[h.prim as usize];
            let p = a * (1.0 - h.b1 - h.b2) + b * h.b1 + c * h.b2;
            let ng = (b - a).cross(c - a).normalize_or_zero();
            let n = if ng.dot(light - p) >= 0.0 { ng } else { -ng };
            let o = offset_origin(p, n);
            Some((Ray::new(o, light - o), 1.0 - 1e-4))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ray_files_round_trip_and_reject_truncation() {
        let dir = std::env::temp_dir().join(format!("st-rays-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("r.bin");
        let rays = vec![(
            Ray::new(Vec3::new(1.0, 2.0, 3.0), Vec3::new(0.0, 0.0, -1.0)),
            7.5,
        )];
        write_rays(&path, &rays).unwrap();
        let back = read_rays(&path).unwrap();
        assert_eq!(back[0].0.origin, rays[0].0.origin);
        assert_eq!(back[0].1, 7.5);
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() - 1]).unwrap();
        assert!(read_rays(&path).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// The stereo set: each pixel's two rays start `interaxial` apart and meet on the
    /// convergence plane; groups of eight are a quad of left-eye pixels then the same quad of
    /// the right, the left set is the left halves, and the centre camera's rays are unchanged.
    #[test]
    fn stereo_rays_meet_on_the_convergence_plane_in_paired_order() {
        let world = Mat4::from_translation(Vec3::new(1.0, 2.0, 3.0));
        let (film, rig) = (6, (0.2, 4.0));
        let both = stereo_camera_rays(world, 0.8, film, Eyes::Both, rig);
        let left = stereo_camera_rays(world, 0.8, film, Eyes::Left, rig);
        let center = stereo_camera_rays(world, 0.8, film, Eyes::Center, rig);
        assert_eq!(both.len(), 2 * left.len());
        assert_eq!(left.len(), (film * film) as usize);
        for (k, group) in both.chunks(8).enumerate() {
            for i in 0..4 {
                let (l, r) = (group[i].0, group[i + 4].0);
                assert_eq!(l.origin, left[4 * k + i].0.origin);
                assert_eq!(l.dir, left[4 * k + i].0.dir);
                assert!(((r.origin - l.origin).length() - 0.2).abs() < 1e-5);
                // Both reach depth 4 (z = 3 - 4) at the same point.
                let meet = |ray: Ray| ray.at((-1.0 - ray.origin.z) / ray.dir.z);
                assert!((meet(l) - meet(r)).length() < 1e-4, "pixel group {k}");
            }
        }
        let plain = camera_rays(world, 0.8, film);
        let bits = |rays: &[TimedRay]| -> Vec<[u32; 6]> {
            rays.iter()
                .map(|(r, _)| {
                    let [a, b, c] = r.origin.to_array().map(f32::to_bits);
                    let [d, e, f] = r.dir.to_array().map(f32::to_bits);
                    [a, b, c, d, e, f]
                })
                .collect()
        };
        assert_eq!(bits(&center), bits(&plain));
    }

    /// Tiles of a 3x3 film in 2x2 tiles: the camera rays tile by tile (ragged tiles at the
    /// edges), each hit's shadow ray following its camera ray; counts that do not fit refused.
    #[test]
    fn regrouping_takes_tiles_and_carries_each_shadow_ray_with_its_camera_ray() {
        let ray = |i: usize| (Ray::new(Vec3::splat(i as f32), Vec3::Z), i as f32);
        let primary: Vec<TimedRay> = (0..9).map(ray).collect();
        let hits: Vec<bool> = (0..9).map(|i| i % 3 != 1).collect();
        let shadow: Vec<TimedRay> = (0..9)
            .filter(|i| i % 3 != 1)
            .map(|i| ray(100 + i))
            .collect();
        let (p, s) = regroup_tiles(&primary, &shadow, &hits, (3, 3), (2, 2)).unwrap();
        let order = |rays: &[TimedRay]| rays.iter().map(|r| r.1 as usize).collect::<Vec<_>>();
        assert_eq!(order(&p), [0, 1, 3, 4, 2, 5, 6, 7, 8]);
        assert_eq!(order(&s), [100, 103, 102, 105, 106, 108]);
        assert!(regroup_tiles(&primary, &shadow[1..], &hits, (3, 3), (2, 2)).is_err());
        assert!(regroup_tiles(&primary, &shadow, &hits, (4, 2), (2, 2)).is_err());
    }
}
