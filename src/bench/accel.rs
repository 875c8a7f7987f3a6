//! `bench accel`: times kd-tree builds and ray throughput per split strategy on a ladder of meshes, with brute force (and, with the
//! `baselines` cargo feature, the `bvh` crate) measured on the identical rays in the same run.

pub use super::accel_options::{AccelBenchOptions, AccelMethod, Walk};
pub use super::accel_table::{AccelRow, chart, csv_header, read_table};

use super::accel_table::write_table;
use super::median;
use super::rays::{
    Eyes, TimedRay, camera_rays, read_rays, regroup_tiles, shadow_rays, stereo_camera_rays,
    write_rays,
};
use crate::accel::{
    BruteForce, BuildParams, Intersect, KdTree, Ray, WalkCounts, force_narrow_packets,
};
use crate::error::{Error, Result};
use crate::render::Backend;
use crate::scene::Scene;
use crate::scene::framing_camera;
use crate::scene::pose;
use glam::{Mat4, Vec3};
use rayon::prelude::*;
use std::path::Path;
use std::time::Instant;

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

/// What tracing a set of rays found: rays that hit (or were occluded) and the sum of the hit
/// distances (closest hit only).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Found {
    hits: u64,
    sum_t: f64,
}

/// Per walk of a method: its row, primary and shadow times, and what the last pass found.
type WalkRun = (AccelRow, Vec<f64>, Vec<f64>, Found, Found);

/// Rays split into directions and limits once, so that packets take slices of both.
struct RaySet {
    rays: Vec<Ray>,
    t_max: Vec<f32>,
}

impl RaySet {
    fn new(timed: &[TimedRay]) -> RaySet {
        RaySet {
            rays: timed.iter().map(|(r, _)| *r).collect(),
            t_max: timed.iter().map(|(_, t)| *t).collect(),
        }
    }

    fn len(&self) -> usize {
        self.rays.len()
    }

    /// Runs `f(rays, t_max)` on chunks of 256 rays in parallel, results in chunk order.
    fn chunks<R: Send>(&self, f: impl Fn(&[Ray], &[f32]) -> R + Sync) -> Vec<R> {
        self.rays
            .par_chunks(256)
            .zip(self.t_max.par_chunks(256))
            .map(|(r, t)| f(r, t))
            .collect()
    }
}

/// Traces all rays (closest hit or any hit) in parallel chunks; seconds and what was found. The
/// sums are added chunk by chunk in order, so they do not depend on the thread count.
fn time_rays(accel: &dyn Intersect, rays: &RaySet, any: bool, walk: Walk) -> (f64, Found) {
    force_narrow_packets(walk == Walk::Packet4);
    let t = Instant::now();
    let chunks: Vec<Found> = rays.chunks(|rays, t_max| {
        let mut f = Found::default();
        let mut hits = [None; 256];
        let mut occluded = [false; 256];
        let n = rays.len();
        match (walk, any) {
            (Walk::Single, true) => {
                for (r, &tm) in rays.iter().zip(t_max) {
                    f.hits += accel.any_hit(r, tm) as u64;
                }
                return f;
            }
            (Walk::Single, false) => {
                for (h, (r, &tm)) in hits.iter_mut().zip(rays.iter().zip(t_max)) {
                    *h = accel.closest_hit(r, tm);
                }
            }
            (Walk::Packet | Walk::Packet4, true) => {
                accel.any_hits(rays, t_max, &mut occluded[..n]);
                f.hits = occluded[..n].iter().filter(|&&o| o).count() as u64;
                return f;
            }
            (Walk::Packet | Walk::Packet4, false) => {
                accel.closest_hits(rays, t_max, &mut hits[..n])
            }
        }
        for h in hits[..n].iter().flatten() {
            f.hits += 1;
            f.sum_t += h.t as f64;
        }
        f
    });
    let secs = t.elapsed().as_secs_f64();
    let found = chunks.iter().fold(Found::default(), |a, c| Found {
        hits: a.hits + c.hits,
        sum_t: a.sum_t + c.sum_t,
    });
    (secs, found)
}

/// Per ray: inner nodes, leaves and triangle tests of a kd-tree walk (an untimed pass). A packet
/// counts a node once for all its rays.
fn walk_work(tree: &KdTree, rays: &RaySet, any: bool, walk: Walk) -> [f64; 3] {
    force_narrow_packets(walk == Walk::Packet4);
    let chunks: Vec<WalkCounts> = rays.chunks(|rays, t_max| {
        let mut c = WalkCounts::default();
        let mut hits = [None; 256];
        let mut occluded = [false; 256];
        let n = rays.len();
        match (walk, any) {
            (Walk::Single, true) => rays.iter().zip(t_max).for_each(|(r, &tm)| {
                tree.any_hit_counted(r, tm, &mut c);
            }),
            (Walk::Single, false) => rays.iter().zip(t_max).for_each(|(r, &tm)| {
                tree.closest_hit_counted(r, tm, &mut c);
            }),
            (Walk::Packet | Walk::Packet4, true) => {
                tree.any_hits_counted(rays, t_max, &mut occluded[..n], &mut c)
            }
            (Walk::Packet | Walk::Packet4, false) => {
                tree.closest_hits_counted(rays, t_max, &mut hits[..n], &mut c)
            }
        }
        c
    });
    let mut total = WalkCounts::default();
    chunks.iter().for_each(|c| total.add(c));
    let n = rays.len().max(1) as f64;
    [total.inner, total.leaves, total.tests].map(|v| v as f64 / n)
}

/// Runs the accel benchmark; one row per (scene, method).
///
/// `progress` gets each row as it is measured, `log` what else the run has to say (the GPU
/// adapter).
pub fn bench_accel(
    opts: &AccelBenchOptions,
    mut progress: impl FnMut(&AccelRow),
    #[cfg_attr(not(feature = "gpu"), allow(unused_mut, unused_variables))] mut log: impl FnMut(String),
) -> Result<Vec<AccelRow>> {
    let on_gpu = opts.backends.contains(&Backend::Gpu);
    #[cfg(not(feature = "gpu"))]
    if on_gpu {
        return Err(Error::input(
            Path::new("--backend"),
            crate::render::NOT_BUILT,
        ));
    }
    let on_cpu = opts.backends.contains(&Backend::Cpu);
    let threads = rayon::current_num_threads();
    let repeat = opts.repeat.max(1);
    let mut rows = Vec::new();
    for spec in &opts.scenes {
        let (name, tris, camera, yfov) = load(spec)?;
        let sah_tree = KdTree::build(tris.clone(), BuildParams::default());
        let primary = match (&opts.rays, opts.eyes) {
            (Some(p), _) => read_rays(p)?,
            (None, Eyes::Center) => camera_rays(camera, yfov, opts.film),
            (None, eyes) => {
                let b = sah_tree.bounds();
                let to_centre = (b.min + b.max) * 0.5 - camera.transform_point3(Vec3::ZERO);
                let convergence = to_centre.length().max(1e-3);
                // The stereographers' one-thirtieth rule for the interaxial distance.
                let rig = (convergence / 30.0, convergence);
                stereo_camera_rays(camera, yfov, opts.film, eyes, rig)
            }
        };
        let shadow = match &opts.shadow_rays {
            Some(p) => read_rays(p)?,
            None => shadow_rays(&sah_tree, &tris, &primary),
        };
        let (primary, shadow) = match (opts.rays_film, opts.tile) {
            (Some(film), Some(tile)) => {
                let (rays, t_max): (Vec<Ray>, Vec<f32>) = primary.iter().copied().unzip();
                let mut found = vec![None; rays.len()];
                sah_tree.closest_hits(&rays, &t_max, &mut found);
                let hits: Vec<bool> = found.iter().map(Option::is_some).collect();
                regroup_tiles(&primary, &shadow, &hits, film, tile)
                    .map_err(|why| Error::input(Path::new("--tile"), why))?
            }
            _ => (primary, shadow),
        };
        drop(sah_tree);
        if let Some(dir) = &opts.save_rays {
            write_rays(&dir.join(format!("{name}_primary.rays")), &primary)?;
            write_rays(&dir.join(format!("{name}_shadow.rays")), &shadow)?;
        }
        let mrays = |rays: usize, secs: f64| rays as f64 * 1e-6 / secs;
        let costs: Vec<Option<f32>> = match opts.traversal_costs.as_slice() {
            [] => vec![None],
            c => c.iter().copied().map(Some).collect(),
        };
        let mut methods: Vec<AccelMethod> = opts
            .splits
            .iter()
            .flat_map(|&s| costs.iter().map(move |&kt| AccelMethod::Split(s, kt)))
            .collect();
        #[cfg(feature = "baselines")]
        methods.push(AccelMethod::BvhCrate);
        if tris.len() as f64 * (primary.len() + shadow.len()) as f64 <= opts.brute_force_budget {
            methods.push(AccelMethod::BruteForce);
        }
        let (primary, shadow) = (RaySet::new(&primary), RaySet::new(&shadow));
        #[cfg(feature = "gpu")]
        let gpu_bench = on_gpu
            .then(|| {
                super::accel_gpu::GpuBench::new(
                    (&primary.rays, &primary.t_max),
                    (&shadow.rays, &shadow.t_max),
                    &mut log,
                )
            })
            .transpose()?;
        for method in methods {
            let walks = match method {
                AccelMethod::Split(..) if on_cpu => opts.walks.clone(),
                AccelMethod::Split(..) => Vec::new(),
                _ => vec![Walk::Single],
            };
            #[cfg(feature = "gpu")]
            let mut gpu_runs = match (&gpu_bench, method) {
                (Some(g), AccelMethod::Split(..)) => g.runs(&AccelRow {
                    scene: name.clone(),
                    method: method.label(),
                    triangles: tris.len(),
                    threads,
                    ..Default::default()
                }),
                _ => Vec::new(),
            };
            let mut runs: Vec<WalkRun> = walks
                .iter()
                .map(|w| {
                    let row = AccelRow {
                        scene: name.clone(),
                        method: match w {
                            Walk::Single => method.label(),
                            Walk::Packet => format!("{}+packets", method.label()),
                            Walk::Packet4 => format!("{}+packets4", method.label()),
                        },
                        triangles: tris.len(),
                        threads,
                        ..Default::default()
                    };
                    (
                        row,
                        Vec::new(),
                        Vec::new(),
                        Found::default(),
                        Found::default(),
                    )
                })
                .collect();
            let mut builds = Vec::new();
            for _ in 0..repeat {
                let t = Instant::now();
                let accel: Box<dyn Intersect> = match method {
                    AccelMethod::Split(s, kt) => {
                        let params = match kt {
                            Some(kt) => BuildParams {
                                traversal_cost: kt,
                                traversal_by_size: false,
                                ..BuildParams::with_method(s)
                            },
                            None => BuildParams::with_method(s),
                        };
                        let tree = KdTree::build(tris.clone(), params);
                        let st = tree.stats();
                        builds.push(tree.build_seconds);
                        for ((row, ..), &walk) in runs.iter_mut().zip(&walks) {
                            row.sah_cost = Some(st.sah_cost);
                            row.nodes = Some(st.nodes);
                            row.leaves = Some(st.leaves);
                            row.max_depth = Some(st.max_depth);
                            row.refs_per_triangle = Some(st.references_per_triangle);
                            row.bytes = Some(st.bytes);
                            if row.primary_work.is_none() {
                                row.primary_work = Some(walk_work(&tree, &primary, false, walk));
                                row.shadow_work = Some(walk_work(&tree, &shadow, true, walk));
                            }
                        }
                        #[cfg(feature = "gpu")]
                        if let Some(g) = &gpu_bench {
                            g.measure(&tree, opts.trace_repeat, &mut gpu_runs)?;
                            for run in &mut gpu_runs {
                                run.row.sah_cost = Some(st.sah_cost);
                                run.row.nodes = Some(st.nodes);
                                run.row.bytes = Some(st.bytes);
                            }
                        }
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
                // The walks alternate within each repeat, so machine noise hits them alike.
                for _ in 0..opts.trace_repeat.max(1) {
                    for ((_, prim_t, shadow_t, prim_found, shadow_found), &walk) in
                        runs.iter_mut().zip(&walks)
                    {
                        let (secs, hits) = time_rays(accel.as_ref(), &primary, false, walk);
                        prim_t.push(secs);
                        *prim_found = hits;
                        let (secs, occluded) = time_rays(accel.as_ref(), &shadow, true, walk);
                        shadow_t.push(secs);
                        *shadow_found = occluded;
                    }
                }
            }
            #[cfg(feature = "gpu")]
            runs.extend(gpu_runs.into_iter().map(|g| {
                let found = |(hits, sum_t)| Found { hits, sum_t };
                (
                    g.row,
                    g.primary_s,
                    g.shadow_s,
                    found(g.primary_found),
                    found(g.shadow_found),
                )
            }));
            for (mut row, prim_t, shadow_t, primary_found, shadow_found) in runs {
                row.build_s = median(&builds);
                row.build_ns_per_triangle = row.build_s * 1e9 / tris.len().max(1) as f64;
                row.primary_mrays_s = mrays(primary.len(), median(&prim_t));
                row.shadow_mrays_s = mrays(shadow.len(), median(&shadow_t));
                row.primary_hits = Some(primary_found.hits);
                row.mean_t = Some(primary_found.sum_t / primary_found.hits.max(1) as f64);
                row.shadow_occluded = Some(shadow_found.hits);
                progress(&row);
                rows.push(row);
            }
        }
    }
    if let Some(path) = &opts.csv {
        write_table(path, &rows)?;
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
    fn generated_meshes_have_about_the_requested_size() {
        let n = generated_mesh(10_000).len();
        assert!((9_000..11_000).contains(&n), "{n}");
    }
}
