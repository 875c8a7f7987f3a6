//! `bench accel`: times kd-tree builds and ray throughput per split strategy on a ladder of meshes, with brute force (and, with the
//! `baselines` cargo feature, the `bvh` crate) measured on the identical rays in the same run.

use super::chart::{self, Chart, Front, Point, Series};
use super::median;
use crate::accel::{BruteForce, BuildParams, Intersect, KdTree, Ray, SplitMethod};
use crate::error::{Error, Result};
use crate::render::integrator::offset_origin;
use crate::scene::Scene;
use crate::scene::camera::framing_camera;
use crate::scene::pose;
use glam::{Mat4, Vec3};
use rayon::prelude::*;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// A method measured by `bench accel`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AccelMethod {
    Split(SplitMethod),
    BruteForce,
    #[cfg(feature = "baselines")]
    BvhCrate,
}

impl AccelMethod {
    pub fn name(&self) -> &'static str {
        match self {
            AccelMethod::Split(SplitMethod::Sah) => "sah",
            AccelMethod::Split(SplitMethod::Center) => "center",
            AccelMethod::Split(SplitMethod::Median) => "median",
            AccelMethod::BruteForce => "brute-force",
            #[cfg(feature = "baselines")]
            AccelMethod::BvhCrate => "bvh-crate",
        }
    }
}

#[derive(Clone, Debug, clap::Args)]
pub struct AccelBenchOptions {
    /// glTF files, or generated:N for a generated mesh of about N triangles.
    #[arg(required = true)]
    pub scenes: Vec<String>,
    /// Split strategies to measure.
    #[arg(
        long = "split",
        value_enum,
        value_delimiter = ',',
        default_value = "center,median,sah"
    )]
    pub splits: Vec<SplitMethod>,
    /// Runs per measurement; the median is reported.
    #[arg(long, default_value_t = 3)]
    pub repeat: usize,
    /// Write the table as CSV.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Replay primary rays from a file (u64 count, then 7 little-endian f32 per ray: origin,
    /// direction, t_max) instead of the camera's.
    #[arg(long)]
    pub rays: Option<PathBuf>,
    /// Replay shadow rays (any-hit) from a file in the same format.
    #[arg(long)]
    pub shadow_rays: Option<PathBuf>,
    /// Camera rays per side of the square film.
    #[arg(long, default_value_t = 512)]
    pub film: u32,
    /// Brute force runs only while triangles x rays stays below this.
    #[arg(skip = 2e9)]
    pub brute_force_budget: f64,
    /// Write each scene's primary and shadow rays into this folder in the replay format
    /// (`<scene>_primary.rays`, `<scene>_shadow.rays`), so other ray tracers can be timed on
    /// identical rays.
    #[arg(long)]
    pub save_rays: Option<PathBuf>,
    /// Also draw the table as a chart: CHART.svg and CHART.png (build time against trace time,
    /// Pareto front per scene).
    #[arg(long)]
    pub chart: Option<PathBuf>,
}

#[derive(Clone, Debug, Default)]
pub struct AccelRow {
    pub scene: String,
    pub method: String,
    pub triangles: usize,
    pub threads: usize,
    pub build_s: f64,
    pub build_ns_per_triangle: f64,
    pub primary_mrays_s: f64,
    pub shadow_mrays_s: f64,
    pub sah_cost: Option<f64>,
    pub nodes: Option<usize>,
    pub leaves: Option<usize>,
    pub max_depth: Option<usize>,
    pub refs_per_triangle: Option<f64>,
    pub bytes: Option<usize>,
}

pub const CSV_HEADER: &str = "scene,method,triangles,threads,build_s,build_ns_per_triangle,primary_mrays_s,shadow_mrays_s,sah_cost,nodes,leaves,max_depth,refs_per_triangle,bytes";

impl AccelRow {
    pub fn csv(&self) -> String {
        let opt = |v: Option<String>| v.unwrap_or_default();
        format!(
            "{},{},{},{},{:.6},{:.1},{:.4},{:.4},{},{},{},{},{},{}",
            self.scene,
            self.method,
            self.triangles,
            self.threads,
            self.build_s,
            self.build_ns_per_triangle,
            self.primary_mrays_s,
            self.shadow_mrays_s,
            opt(self.sah_cost.map(|v| format!("{v:.2}"))),
            opt(self.nodes.map(|v| v.to_string())),
            opt(self.leaves.map(|v| v.to_string())),
            opt(self.max_depth.map(|v| v.to_string())),
            opt(self.refs_per_triangle.map(|v| format!("{v:.3}"))),
            opt(self.bytes.map(|v| v.to_string())),
        )
    }
}

/// Charts a `bench accel` table: build time against nanoseconds per primary ray, one series per
/// scene, a Pareto front per scene (scenes of different sizes are not comparable points).
pub fn chart(rows: &[AccelRow], stem: &Path) -> Result<()> {
    let series = Series::group(rows.iter().map(|r| {
        let point = Point {
            label: r.method.clone(),
            x: r.build_s,
            y: 1e3 / r.primary_mrays_s,
        };
        (format!("{} ({} tris)", r.scene, r.triangles), point)
    }));
    chart::write(
        &Chart {
            title: "kd-tree split strategies: build time against trace time".into(),
            x_label: "build time (s)".into(),
            y_label: format!(
                "ns per primary ray ({} threads)",
                rows.first().map_or(0, |r| r.threads)
            ),
            series,
            front: Front::PerSeries,
        },
        stem,
    )
}

/// Reads a table written by `bench accel --csv` (or its standard output) back.
pub fn read_csv(path: &Path) -> Result<Vec<AccelRow>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let mut lines = text.lines();
    if lines.next() != Some(CSV_HEADER) {
        return Err(Error::input(
            path,
            "not a bench accel table: the header differs",
        ));
    }
    lines
        .enumerate()
        .map(|(i, line)| {
            let bad = |what: &str| Error::input(path, format!("line {}: {what}", i + 2));
            let f: Vec<&str> = line.split(',').collect();
            if f.len() != CSV_HEADER.split(',').count() {
                return Err(bad("wrong number of fields"));
            }
            let num = |k: usize| {
                f[k].parse::<f64>()
                    .map_err(|_| bad(&format!("'{}' is not a number", f[k])))
            };
            let opt = |k: usize| {
                (!f[k].is_empty())
                    .then(|| f[k].parse::<f64>().ok())
                    .flatten()
            };
            Ok(AccelRow {
                scene: f[0].to_string(),
                method: f[1].to_string(),
                triangles: num(2)? as usize,
                threads: num(3)? as usize,
                build_s: num(4)?,
                build_ns_per_triangle: num(5)?,
                primary_mrays_s: num(6)?,
                shadow_mrays_s: num(7)?,
                sah_cost: opt(8),
                nodes: opt(9).map(|v| v as usize),
                leaves: opt(10).map(|v| v as usize),
                max_depth: opt(11).map(|v| v as usize),
                refs_per_triangle: opt(12),
                bytes: opt(13).map(|v| v as usize),
            })
        })
        .collect()
}

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

/// A UV sphere of about `n` triangles with a deterministic bumpy radius, so the mesh is not a
/// perfectly regular grid.
pub fn generated_mesh(n: usize) -> Vec<[Vec3; 3]> {
    let lat = ((n as f64 / 4.0).sqrt().round() as usize).max(2);
    let lon = 2 * lat;
    let point = |i: usize, j: usize| {
        let th = std::f32::consts::PI * i as f32 / lat as f32;
        let ph = 2.0 * std::f32::consts::PI * j as f32 / lon as f32;
        let r = 1.0 + 0.05 * (7.0 * th).sin() * (5.0 * ph).cos();
        Vec3::new(th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin()) * r
    };
    let mut tris = Vec::with_capacity(2 * lat * lon);
    for i in 0..lat {
        for j in 0..lon {
            let (a, b, c, d) = (
                point(i, j),
                point(i + 1, j),
                point(i + 1, j + 1),
                point(i, j + 1),
            );
            tris.push([a, b, c]);
            tris.push([a, c, d]);
        }
    }
    tris
}

/// Triangles of a scene (or generated mesh) in world space and the camera looking at them.
fn load(spec: &str) -> Result<(String, Vec<[Vec3; 3]>, Mat4, f32)> {
    if let Some(n) = spec.strip_prefix("generated:") {
        let n: usize = n.parse().map_err(|_| {
            Error::input(
                Path::new(spec),
                "expected generated:N with a triangle count",
            )
        })?;
        let tris = generated_mesh(n);
        let (cam, world) = framing_camera(Vec3::splat(-1.05), Vec3::splat(1.05));
        return Ok((format!("generated-{}", tris.len()), tris, world, cam.yfov));
    }
    let path = Path::new(spec);
    let scene = Scene::load(path)?;
    let posed = pose::pose(&scene, &[]);
    let g = &posed.geometry;
    let tris = g.triangle_list();
    let (lo, hi) = g.bounds().unwrap_or((Vec3::splat(-1.0), Vec3::splat(1.0)));
    let (world, yfov) = match posed.cameras.first() {
        Some(c) => (c.world, scene.cameras[c.camera].yfov),
        None => {
            let (cam, world) = framing_camera(lo, hi);
            (world, cam.yfov)
        }
    };
    let name = path
        .file_stem()
        .map_or(spec.to_string(), |s| s.to_string_lossy().into_owned());
    Ok((name, tris, world, yfov))
}

/// Square pinhole film of `film` x `film` rays through pixel centres.
fn camera_rays(world: Mat4, yfov: f32, film: u32) -> Vec<TimedRay> {
    let t = (yfov * 0.5).tan();
    let origin = world.transform_point3(Vec3::ZERO);
    (0..film * film)
        .map(|i| {
            let (x, y) = ((i % film) as f32 + 0.5, (i / film) as f32 + 0.5);
            let d = Vec3::new(
                (2.0 * x / film as f32 - 1.0) * t,
                (1.0 - 2.0 * y / film as f32) * t,
                -1.0,
            );
            (
                Ray::new(origin, world.transform_vector3(d).normalize()),
                f32::INFINITY,
            )
        })
        .collect()
}

/// Shadow rays from every primary hit toward a point light above and in front of the scene.
fn shadow_rays(tree: &KdTree, tris: &[[Vec3; 3]], primary: &[TimedRay]) -> Vec<TimedRay> {
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

/// Seconds to trace all rays (closest hit or any hit), in parallel chunks.
fn time_rays(accel: &dyn Intersect, rays: &[TimedRay], any: bool) -> f64 {
    let t = Instant::now();
    let hits: usize = rays
        .par_chunks(256)
        .map(|chunk| {
            chunk
                .iter()
                .filter(|(r, tm)| {
                    if any {
                        accel.any_hit(r, *tm)
                    } else {
                        accel.closest_hit(r, *tm).is_some()
                    }
                })
                .count()
        })
        .sum();
    std::hint::black_box(hits);
    t.elapsed().as_secs_f64()
}

/// Runs the accel benchmark; one row per (scene, method).
pub fn bench_accel(
    opts: &AccelBenchOptions,
    mut progress: impl FnMut(&AccelRow),
) -> Result<Vec<AccelRow>> {
    let threads = rayon::current_num_threads();
    let repeat = opts.repeat.max(1);
    let mut rows = Vec::new();
    for spec in &opts.scenes {
        let (name, tris, camera, yfov) = load(spec)?;
        let sah_tree = KdTree::build(tris.clone(), BuildParams::default());
        let primary = match &opts.rays {
            Some(p) => read_rays(p)?,
            None => camera_rays(camera, yfov, opts.film),
        };
        let shadow = match &opts.shadow_rays {
            Some(p) => read_rays(p)?,
            None => shadow_rays(&sah_tree, &tris, &primary),
        };
        drop(sah_tree);
        if let Some(dir) = &opts.save_rays {
            write_rays(&dir.join(format!("{name}_primary.rays")), &primary)?;
            write_rays(&dir.join(format!("{name}_shadow.rays")), &shadow)?;
        }
        let mrays = |rays: &[TimedRay], secs: f64| rays.len() as f64 * 1e-6 / secs;
        let mut methods: Vec<AccelMethod> =
            opts.splits.iter().map(|&s| AccelMethod::Split(s)).collect();
        #[cfg(feature = "baselines")]
        methods.push(AccelMethod::BvhCrate);
        if tris.len() as f64 * (primary.len() + shadow.len()) as f64 <= opts.brute_force_budget {
            methods.push(AccelMethod::BruteForce);
        }
        for method in methods {
            let mut row = AccelRow {
                scene: name.clone(),
                method: method.name().into(),
                triangles: tris.len(),
                threads,
                ..Default::default()
            };
            let (mut builds, mut prim_t, mut shadow_t) = (Vec::new(), Vec::new(), Vec::new());
            for _ in 0..repeat {
                let t = Instant::now();
                let accel: Box<dyn Intersect> = match method {
                    AccelMethod::Split(s) => {
                        let tree = KdTree::build(tris.clone(), BuildParams::with_method(s));
                        let st = tree.stats();
                        row.sah_cost = Some(st.sah_cost);
                        row.nodes = Some(st.nodes);
                        row.leaves = Some(st.leaves);
                        row.max_depth = Some(st.max_depth);
                        row.refs_per_triangle = Some(st.references_per_triangle);
                        row.bytes = Some(st.bytes);
                        builds.push(tree.build_seconds);
                        Box::new(tree)
                    }
                    AccelMethod::BruteForce => {
                        let b = BruteForce {
                            triangles: tris.clone(),
                        };
                        builds.push(t.elapsed().as_secs_f64());
                        Box::new(b)
                    }
                    #[cfg(feature = "baselines")]
                    AccelMethod::BvhCrate => {
                        let b = baseline::BvhCrate::build(&tris);
                        builds.push(t.elapsed().as_secs_f64());
                        Box::new(b)
                    }
                };
                prim_t.push(time_rays(accel.as_ref(), &primary, false));
                shadow_t.push(time_rays(accel.as_ref(), &shadow, true));
            }
            row.build_s = median(&builds);
            row.build_ns_per_triangle = row.build_s * 1e9 / tris.len().max(1) as f64;
            row.primary_mrays_s = mrays(&primary, median(&prim_t));
            row.shadow_mrays_s = mrays(&shadow, median(&shadow_t));
            progress(&row);
            rows.push(row);
        }
    }
    if let Some(path) = &opts.csv {
        crate::output::write_atomic(path, |w| {
            writeln!(w, "{CSV_HEADER}")?;
            for r in &rows {
                writeln!(w, "{}", r.csv())?;
            }
            Ok(())
        })?;
    }
    Ok(rows)
}

#[cfg(feature = "baselines")]
mod baseline {
    //! The `bvh` crate as a baseline: its SAH BVH finds candidate triangles whose boxes the ray
    //! crosses, and our watertight test intersects them (the crate has no triangle test of its own).
    use crate::accel::triangle::{RayPre, intersect};
    use crate::accel::{Hit, Intersect, Ray};
    use bvh::aabb::{Aabb, Bounded};
    use bvh::bounding_hierarchy::BHShape;
    use bvh::bvh::Bvh;
    use glam::Vec3;
    use nalgebra::{Point3, Vector3};

    pub struct Tri {
        v: [Vec3; 3],
        index: u32,
        node: usize,
    }

    impl Bounded<f32, 3> for Tri {
        fn aabb(&self) -> Aabb<f32, 3> {
            let lo = self.v[0].min(self.v[1]).min(self.v[2]);
            let hi = self.v[0].max(self.v[1]).max(self.v[2]);
            Aabb::with_bounds(Point3::new(lo.x, lo.y, lo.z), Point3::new(hi.x, hi.y, hi.z))
        }
    }

    impl BHShape<f32, 3> for Tri {
        fn set_bh_node_index(&mut self, i: usize) {
            self.node = i;
        }
        fn bh_node_index(&self) -> usize {
            self.node
        }
    }

    pub struct BvhCrate {
        bvh: Bvh<f32, 3>,
        tris: Vec<Tri>,
    }

    impl BvhCrate {
        pub fn build(tris: &[[Vec3; 3]]) -> BvhCrate {
            let mut shapes: Vec<Tri> = tris
                .iter()
                .enumerate()
                .map(|(i, v)| Tri {
                    v: *v,
                    index: i as u32,
                    node: 0,
                })
                .collect();
            let bvh = Bvh::build(&mut shapes);
            BvhCrate { bvh, tris: shapes }
        }

        fn ray(r: &Ray) -> bvh::ray::Ray<f32, 3> {
            bvh::ray::Ray::new(
                Point3::new(r.origin.x, r.origin.y, r.origin.z),
                Vector3::new(r.dir.x, r.dir.y, r.dir.z),
            )
        }
    }

    impl Intersect for BvhCrate {
        fn closest_hit(&self, ray: &Ray, t_max: f32) -> Option<Hit> {
            let pre = RayPre::new(ray);
            let r = Self::ray(ray);
            let mut best: Option<Hit> = None;
            for t in self.bvh.traverse_iterator(&r, &self.tris) {
                let limit = best.map_or(t_max, |h| h.t);
                if let Some((d, b1, b2)) = intersect(&pre, &t.v, limit) {
                    best = Some(Hit {
                        t: d,
                        prim: t.index,
                        b1,
                        b2,
                    });
                }
            }
            best
        }

        fn any_hit(&self, ray: &Ray, t_max: f32) -> bool {
            let pre = RayPre::new(ray);
            let r = Self::ray(ray);
            self.bvh
                .traverse_iterator(&r, &self.tris)
                .any(|t| intersect(&pre, &t.v, t_max).is_some())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_read_back_what_was_written() {
        let rows = [
            AccelRow {
                scene: "bunny".into(),
                method: "sah".into(),
                triangles: 948,
                threads: 2,
                build_s: 0.0115,
                build_ns_per_triangle: 12102.0,
                primary_mrays_s: 19.1684,
                shadow_mrays_s: 6.4806,
                sah_cost: Some(583.91),
                nodes: Some(7055),
                leaves: Some(3528),
                max_depth: Some(21),
                refs_per_triangle: Some(5.026),
                bytes: Some(109628),
            },
            AccelRow {
                scene: "bunny".into(),
                method: "brute-force".into(),
                triangles: 948,
                threads: 2,
                build_s: 0.0003,
                primary_mrays_s: 0.5,
                ..Default::default()
            },
        ];
        let path = std::env::temp_dir().join(format!("accel-{}.csv", std::process::id()));
        let text: Vec<String> = std::iter::once(CSV_HEADER.to_string())
            .chain(rows.iter().map(AccelRow::csv))
            .collect();
        std::fs::write(&path, text.join("\n")).unwrap();
        let back = read_csv(&path).unwrap();
        assert_eq!(back.len(), 2);
        for (a, b) in rows.iter().zip(&back) {
            assert_eq!(a.csv(), b.csv());
        }
        std::fs::write(&path, "scene,method\nx,y\n").unwrap();
        assert!(read_csv(&path).unwrap_err().to_string().contains("header"));
        std::fs::remove_file(path).unwrap();
    }

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

    #[test]
    fn generated_meshes_have_about_the_requested_size() {
        let n = generated_mesh(10_000).len();
        assert!((9_000..11_000).contains(&n), "{n}");
    }
}
