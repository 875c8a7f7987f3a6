//! The GPU backend against the CPU on the same kd-tree: every GPU walk (full stack, short stack,
//! kd-restart) must find the CPU's closest hits and occlusion. Runs on whatever adapter the
//! machine has; in CI that is Mesa's software Vulkan driver (lavapipe). A machine with no adapter
//! fails these tests, or skips them out loud with STEREOTRACE_SKIP_GPU=1.

mod common;

#[cfg(not(feature = "gpu"))]
#[test]
fn the_gpu_backend_is_built_and_checked() {
    common::missing_tool(
        "the GPU backend (the suite runs with `--features gpu`: scripts/test.sh)",
        "STEREOTRACE_SKIP_GPU",
    );
}

#[cfg(feature = "gpu")]
mod on_gpu {
    use glam::Vec3;
    use stereotrace::accel::{BuildParams, Hit, Intersect, KdTree, Ray, SplitMethod};
    use stereotrace::gpu::{Gpu, GpuAccel, GpuRays, GpuTracer, GpuWalk};

    fn gpu() -> Option<Gpu> {
        super::common::gpu_adapter()
    }

    struct Rng(u64);
    impl Rng {
        fn f(&mut self) -> f32 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((self.0 >> 40) as f32) / (1u64 << 24) as f32
        }
        fn v(&mut self, s: f32) -> Vec3 {
            Vec3::new(self.f(), self.f(), self.f()) * s
        }
    }

    /// A random soup and an axis-aligned grid whose triangles lie on split candidates.
    fn scene(rng: &mut Rng) -> Vec<[Vec3; 3]> {
        let mut tris: Vec<[Vec3; 3]> = (0..3000)
            .map(|_| {
                let c = rng.v(10.0);
                [c, c + rng.v(1.0) - 0.5, c + rng.v(1.0) - 0.5]
            })
            .collect();
        for i in 0..8 {
            for j in 0..8 {
                let (x, y) = (i as f32, j as f32);
                tris.push([
                    Vec3::new(x, y, 0.0),
                    Vec3::new(x + 1.0, y, 0.0),
                    Vec3::new(x, y + 1.0, 0.0),
                ]);
                tris.push([
                    Vec3::new(x, 0.0, y),
                    Vec3::new(x, 1.0, y),
                    Vec3::new(x, 0.0, y + 1.0),
                ]);
            }
        }
        tris
    }

    /// A pinhole's fan, random rays, and (with `on_planes`) rays starting on and running along
    /// the grid's planes, some with zero direction components.
    fn rays(rng: &mut Rng, on_planes: bool) -> Vec<Ray> {
        let mut rays = Vec::new();
        let eye = Vec3::new(5.0, 5.0, -8.0);
        for y in 0..48 {
            for x in 0..48 {
                let d = Vec3::new(x as f32 / 48.0 - 0.5, y as f32 / 48.0 - 0.5, 1.0);
                rays.push(Ray::new(eye, d));
            }
        }
        for _ in 0..3000 {
            rays.push(Ray::new(rng.v(14.0) - 2.0, rng.v(2.0) - 1.0));
        }
        if on_planes {
            for i in 0..400 {
                let f = i as f32 * 0.02;
                rays.push(Ray::new(Vec3::new(f, 0.5, 5.0), Vec3::NEG_Z));
                rays.push(Ray::new(Vec3::new(f, 0.0, 0.5), Vec3::Y));
                rays.push(Ray::new(Vec3::new(2.0, f, -1.0), Vec3::new(0.3, 0.01, 1.0)));
            }
        }
        rays
    }

    /// The GPU's hit is the CPU's: the same triangle at a distance within a few ulps (the GPU
    /// may fuse a multiply and an add where the CPU rounds twice), or, where rounding moved a ray
    /// across a shared edge, an adjacent triangle at the same distance.
    fn agree(cpu: Option<Hit>, gpu: Option<Hit>) -> bool {
        match (cpu, gpu) {
            (None, None) => true,
            (Some(c), Some(g)) => (c.t - g.t).abs() <= 1e-5 * c.t.abs().max(1e-3),
            _ => false,
        }
    }

    fn check(
        gpu: &Gpu,
        tracer: &GpuTracer,
        tris: Vec<[Vec3; 3]>,
        rays: &[Ray],
        walks: &[GpuWalk],
        halves: bool,
    ) {
        let tree = KdTree::build(tris, BuildParams::with_method(SplitMethod::Sah));
        let mut on_gpu = if halves {
            GpuAccel::in_halves(gpu).unwrap()
        } else {
            GpuAccel::new(gpu).unwrap()
        };
        on_gpu.upload_tree(gpu, &tree).unwrap();
        // Every third ray stops short, so limits are checked too.
        let t_max: Vec<f32> = (0..rays.len())
            .map(|i| if i % 3 == 0 { 9.0 } else { f32::INFINITY })
            .collect();
        let batch = GpuRays::upload(gpu, rays, &t_max).unwrap();
        let mut found = 0;
        for &walk in walks {
            tracer.trace(gpu, &on_gpu, &batch, walk, false).unwrap();
            let closest = tracer.read_hits(gpu, &batch).unwrap();
            tracer.trace(gpu, &on_gpu, &batch, walk, true).unwrap();
            let any = tracer.read_hits(gpu, &batch).unwrap();
            let (mut differ, mut same_prim) = (Vec::new(), 0);
            for (i, r) in rays.iter().enumerate() {
                let cpu = tree.closest_hit(r, t_max[i]);
                let occluded = tree.any_hit(r, t_max[i]);
                if !agree(cpu, closest[i]) || any[i].is_some() != occluded {
                    differ.push(format!(
                        "ray {i} {r:?}: GPU {:?} / {:?}, CPU {cpu:?} / {occluded}",
                        closest[i], any[i]
                    ));
                }
                same_prim += (cpu.map(|h| h.prim) == closest[i].map(|h| h.prim)) as usize;
                if let Some(h) = any[i] {
                    assert!(h.t > 0.0 && h.t < t_max[i], "{walk:?} ray {i}: {h:?}");
                }
                found += cpu.is_some() as usize;
            }
            eprintln!(
                "{walk:?}: {} of {} rays differ from the CPU, {same_prim} hit its triangle",
                differ.len(),
                rays.len()
            );
            // Every walk visits the CPU walk's nodes in its order (restarts follow the trail).
            assert!(
                differ.is_empty(),
                "{walk:?}: {} rays differ from the CPU, first: {}",
                differ.len(),
                differ[0]
            );
            // Distinct triangles at one distance only where a ray meets a shared edge.
            assert!(
                same_prim * 1000 >= rays.len() * 999,
                "{walk:?}: {same_prim} of {} rays hit the CPU's triangle",
                rays.len()
            );
        }
        assert!(
            found > rays.len() / 4,
            "the rays must hit something: {found}"
        );
    }

    #[test]
    fn every_gpu_walk_finds_the_cpu_hits() {
        let Some(gpu) = gpu() else { return };
        let tracer = GpuTracer::new(&gpu).unwrap();
        let mut rng = Rng(7);
        let tris = scene(&mut rng);
        check(
            &gpu,
            &tracer,
            tris.clone(),
            &rays(&mut rng, false),
            &GpuWalk::ALL,
            false,
        );
    }

    /// Rays lying in a split plane visit both sides on the CPU; every GPU walk does the same.
    #[test]
    fn rays_lying_in_split_planes_visit_both_sides() {
        let Some(gpu) = gpu() else { return };
        let tracer = GpuTracer::new(&gpu).unwrap();
        let mut rng = Rng(9);
        let tris = scene(&mut rng);
        check(
            &gpu,
            &tracer,
            tris,
            &rays(&mut rng, true),
            &GpuWalk::ALL,
            false,
        );
    }

    /// A tree whose arrays do not fit one binding goes in two parts per array; its walks find
    /// the same hits (every array split at its middle, as a tree over the limit would be).
    #[test]
    fn a_tree_in_two_parts_finds_the_same_hits() {
        let Some(gpu) = gpu() else { return };
        let tracer = GpuTracer::new(&gpu).unwrap();
        let mut rng = Rng(13);
        let tris = scene(&mut rng);
        check(
            &gpu,
            &tracer,
            tris,
            &rays(&mut rng, true),
            &GpuWalk::ALL,
            true,
        );
    }

    #[test]
    fn an_empty_scene_and_no_rays() {
        let Some(gpu) = gpu() else { return };
        let tracer = GpuTracer::new(&gpu).unwrap();
        let empty = KdTree::build(Vec::new(), BuildParams::default());
        let mut on_gpu = GpuAccel::new(&gpu).unwrap();
        on_gpu.upload_tree(&gpu, &empty).unwrap();
        let r = [Ray::new(Vec3::new(0.2, 0.2, 1.0), Vec3::NEG_Z)];
        let batch = GpuRays::upload(&gpu, &r, &[f32::INFINITY]).unwrap();
        tracer
            .trace(&gpu, &on_gpu, &batch, GpuWalk::Short, false)
            .unwrap();
        assert_eq!(tracer.read_hits(&gpu, &batch).unwrap(), vec![None]);
        let none = GpuRays::upload(&gpu, &[], &[]).unwrap();
        tracer
            .trace(&gpu, &on_gpu, &none, GpuWalk::Stack, true)
            .unwrap();
        assert!(tracer.read_hits(&gpu, &none).unwrap().is_empty());
        // The integrator over a frame with nothing in it: every camera ray sees the background.
        use stereotrace::accel::TwoLevel;
        use stereotrace::gpu::{GpuScene, GpuWhitted};
        use stereotrace::render::{ShadingModel, TraceSettings};
        use stereotrace::scene::pose::Geometry;
        on_gpu.update(&gpu, &TwoLevel::default(), 0).unwrap();
        let nothing = GpuScene::upload(&gpu, &Geometry::default(), &[], &[], &[]).unwrap();
        let settings = TraceSettings {
            max_depth: 4,
            shading: ShadingModel::CookTorrance,
            background: Vec3::new(0.25, 0.5, 0.75),
        };
        let (radiance, _) = GpuWhitted::new(&gpu)
            .unwrap()
            .radiance(&gpu, &on_gpu, &nothing, &settings, &r, &[f32::INFINITY])
            .unwrap();
        assert_eq!(radiance, vec![settings.background]);
    }

    /// A frame's parts on the GPU: static geometry, a rigid instance and a refitted deforming
    /// mesh, as `accel::Updater` makes them. Every walk finds the CPU's hits (global triangle
    /// indices included) on the first frame and, after the instance moved and the mesh was
    /// refitted, on the second, which writes only the refit and the table of parts; a rebuilt
    /// mesh on the third is written in place or lays the arrays out again.
    #[test]
    fn instances_and_refitted_parts_find_the_cpu_hits_frame_after_frame() {
        use glam::{Mat4, Quat};
        use std::sync::Arc;
        use stereotrace::accel::{Part, PrimMap, RefitTree, TwoLevel};
        let Some(gpu) = gpu() else { return };
        let tracer = GpuTracer::new(&gpu).unwrap();
        let mut rng = Rng(21);
        let mut soup = |n: usize, c: Vec3| -> Vec<[Vec3; 3]> {
            (0..n)
                .map(|_| {
                    let p = c + rng.v(4.0);
                    [p, p + rng.v(1.0) - 0.5, p + rng.v(1.0) - 0.5]
                })
                .collect()
        };
        let world = soup(400, Vec3::ZERO);
        let object = soup(300, Vec3::splat(-2.0));
        let rest = soup(500, Vec3::new(3.0, 0.0, 1.0));
        let params = BuildParams::default();
        let static_tree = Arc::new(KdTree::build(world.clone(), params));
        let object_tree = Arc::new(KdTree::build(object.clone(), params));
        let topology = RefitTree::build(rest.clone(), params).topology().clone();
        let pose = |step: f32| {
            let place = Mat4::from_scale_rotation_translation(
                Vec3::splat(1.2 + 0.1 * step),
                Quat::from_rotation_y(0.5 + step),
                Vec3::new(2.0 * step, 1.0, -1.0),
            );
            let bent: Vec<[Vec3; 3]> = rest
                .iter()
                .map(|t| t.map(|v| v + Vec3::new((v.y * 0.7).sin(), 0.0, (v.x * 0.5).cos()) * step))
                .collect();
            (place, bent)
        };
        let rays: Vec<Ray> = (0..4000)
            .map(|_| Ray::new(rng.v(16.0) - 6.0, rng.v(2.0) - 1.0))
            .collect();
        let t_max: Vec<f32> = (0..rays.len())
            .map(|i| if i % 3 == 0 { 6.0 } else { f32::INFINITY })
            .collect();
        let batch = GpuRays::upload(&gpu, &rays, &t_max).unwrap();
        for halves in [false, true] {
            let mut on_gpu = if halves {
                GpuAccel::in_halves(&gpu).unwrap()
            } else {
                GpuAccel::new(&gpu).unwrap()
            };
            for frame in 0..3 {
                let (place, bent) = pose(frame as f32);
                let deforming = if frame < 2 {
                    Part::refitted(
                        Arc::new(RefitTree::refit(topology.clone(), bent)),
                        PrimMap::Offset(700),
                    )
                } else {
                    Part::world(Arc::new(KdTree::build(bent, params)), PrimMap::Offset(700))
                };
                let accel = TwoLevel::new(vec![
                    Part::world(static_tree.clone(), PrimMap::Offset(0)),
                    Part::instance(object_tree.clone(), PrimMap::Offset(400), place),
                    deforming,
                ]);
                let before = on_gpu.uploads();
                on_gpu.update(&gpu, &accel, 1200).unwrap();
                let after = on_gpu.uploads();
                match frame {
                    0 => assert_eq!((after.layouts, after.trees, after.refits), (1, 3, 0)),
                    // The moved instance and the refit: the refit's boxes and triangles and the
                    // table, nothing of the static tree or the instance's.
                    1 => {
                        assert_eq!((after.layouts, after.trees, after.refits), (1, 3, 1));
                        let boxes = 48 * topology.arrays().nodes.len() as u64;
                        let written = after.bytes - before.bytes;
                        assert!(written <= boxes + 36 * 500 + 3 * 144, "{written} bytes");
                    }
                    // A kd-tree where the refitted tree was: another kind of tree, so the arrays
                    // are laid out again, every part written.
                    _ => assert_eq!((after.layouts, after.trees), (2, 6), "{after:?}"),
                }
                let mut differ = Vec::new();
                for walk in GpuWalk::ALL {
                    tracer.trace(&gpu, &on_gpu, &batch, walk, false).unwrap();
                    let closest = tracer.read_hits(&gpu, &batch).unwrap();
                    tracer.trace(&gpu, &on_gpu, &batch, walk, true).unwrap();
                    let any = tracer.read_hits(&gpu, &batch).unwrap();
                    for (i, r) in rays.iter().enumerate() {
                        let cpu = accel.closest_hit(r, t_max[i]);
                        let occluded = accel.any_hit(r, t_max[i]);
                        let same_prim = cpu.map(|h| h.prim) == closest[i].map(|h| h.prim);
                        if !agree(cpu, closest[i]) || !same_prim || any[i].is_some() != occluded {
                            differ.push(format!(
                                "frame {frame} {walk:?} ray {i}: GPU {:?} / {:?}, CPU {cpu:?} / {occluded}",
                                closest[i], any[i]
                            ));
                        }
                    }
                }
                let hits = rays
                    .iter()
                    .zip(&t_max)
                    .filter(|(r, t)| accel.closest_hit(r, **t).is_some_and(|h| h.prim >= 400))
                    .count();
                assert!(hits > 200, "rays must hit the moving parts: {hits}");
                assert!(
                    differ.len() <= 3,
                    "halves {halves}: {} differ, first: {:?}",
                    differ.len(),
                    differ.first()
                );
            }
        }
    }

    fn bench(args: &[&str], adapter: Option<&str>) -> std::process::Output {
        let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_stereotrace"));
        c.args(["bench", "accel"]).args(args);
        if let Some(a) = adapter {
            c.env(stereotrace::gpu::ADAPTER_VAR, a);
        }
        c.output().unwrap()
    }

    /// `bench accel --backend cpu,gpu`: a row per GPU walk next to the CPU's, the adapter named,
    /// the same hits (count, mean distance, occluded count) as the CPU rows of the run, and the
    /// work counters that say how the walks differ.
    #[test]
    fn bench_accel_reports_the_gpu_walks_next_to_the_cpu() {
        let Some(_) = gpu() else { return };
        let out = bench(
            &[
                "generated:20000",
                "--split",
                "sah",
                "--backend",
                "cpu,gpu",
                "--repeat",
                "1",
                "--film",
                "96",
                "--threads",
                "2",
            ],
            None,
        );
        let (stdout, stderr) = (
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr),
        );
        assert!(out.status.success(), "{stderr}");
        assert!(stderr.contains("GPU adapter: "), "{stderr}");
        let mut lines = stdout.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
        let rows: Vec<Vec<String>> = lines
            .map(|l| {
                // The device column is quoted (adapter names hold commas).
                let (plain, device) = l.split_once(",\"").unwrap_or((l, ""));
                let mut f: Vec<String> = plain.split(',').map(String::from).collect();
                f.push(device.trim_end_matches('"').to_string());
                f
            })
            .collect();
        let row = |method: &str| {
            rows.iter()
                .find(|r| r[1] == method)
                .unwrap_or_else(|| panic!("no {method} row in\n{stdout}"))
        };
        let cpu = row("sah");
        for walk in ["stack", "short-stack", "kd-restart"] {
            let g = row(&format!("sah+gpu-{walk}"));
            assert!(!g[col("device")].is_empty(), "{walk}: no adapter named");
            for c in ["primary_hits", "shadow_occluded", "nodes"] {
                assert_eq!(g[col(c)], cpu[col(c)], "{walk}: {c}");
            }
            // Every walk reaches the CPU walk's leaves; the full stack visits exactly its inner
            // nodes too, the restarting walks more (the path back down from the root).
            for c in ["primary_leaves_per_ray", "shadow_leaves_per_ray"] {
                assert_eq!(g[col(c)], cpu[col(c)], "{walk}: {c}");
            }
            let inner = |r: &Vec<String>| r[col("shadow_inner_per_ray")].parse::<f64>().unwrap();
            if walk == "stack" {
                assert_eq!(inner(g), inner(cpu), "stack: inner nodes");
            } else {
                assert!(inner(g) >= inner(cpu), "{walk}: inner nodes");
            }
            let mean = |r: &Vec<String>| r[col("mean_t")].parse::<f64>().unwrap();
            assert!(
                (mean(g) - mean(cpu)).abs() <= 1e-5 * mean(cpu),
                "{walk}: mean_t"
            );
            assert!(g[col("primary_mrays_s")].parse::<f64>().unwrap() > 0.0);
        }
    }

    /// An adapter named that the machine lacks is an error naming it, never a quiet fallback.
    #[test]
    fn a_named_adapter_that_is_not_there_is_an_error() {
        let out = bench(
            &[
                "generated:2000",
                "--split",
                "sah",
                "--backend",
                "gpu",
                "--film",
                "16",
            ],
            Some("no-such-adapter"),
        );
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.contains("no adapter matches STEREOTRACE_GPU_ADAPTER=\"no-such-adapter\""),
            "{stderr}"
        );
    }

    /// Camera rays over a `w` x `h` film from a camera framing the whole scene (the posed
    /// scene's own camera could miss most of it).
    fn framing_rays(lo: Vec3, hi: Vec3, w: u32, h: u32) -> Vec<Ray> {
        let (cam, world) = stereotrace::scene::framing_camera(lo, hi);
        let tan_y = (cam.yfov * 0.5).tan();
        let tan_x = tan_y * w as f32 / h as f32;
        let origin = world.transform_point3(Vec3::ZERO);
        (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| {
                let d = Vec3::new(
                    (2.0 * (x as f32 + 0.5) / w as f32 - 1.0) * tan_x,
                    (1.0 - 2.0 * (y as f32 + 0.5) / h as f32) * tan_y,
                    -1.0,
                );
                Ray::new(origin, world.transform_vector3(d).normalize())
            })
            .collect()
    }

    /// The GPU integrator against the CPU's (`Integrator::radiance`) on the reference scenes,
    /// the default scenes, a textured model and two with every material input, each with a spot and a directional light added,
    /// with both shading models: every camera ray's radiance within 1e-3 of the CPU's in every
    /// channel and within 1e-6 on average. Measured when written: at most 9.2e-5 (a glass
    /// path), on average at most 2.8e-8; they differ where the GPU fuses a multiply and an add
    /// that the CPU rounds apart.
    #[test]
    fn the_gpu_integrator_shades_as_the_cpu_does() {
        use stereotrace::gpu::{GpuScene, GpuWhitted};
        use stereotrace::render::{Integrator, SceneView, ShadingModel, TraceSettings};
        use stereotrace::scene::{Light, LightKind, Scene, pose};
        let Some(gpu) = gpu() else { return };
        let whitted = GpuWhitted::new(&gpu).unwrap();
        let data = super::common::data();
        let repo = super::common::repo();
        let mut scenes: Vec<std::path::PathBuf> = super::common::reference_dirs()
            .into_iter()
            .map(|d| d.join("scene.gltf"))
            .collect();
        scenes.push(repo.join("scenes/whitted.gltf"));
        scenes.push(repo.join("scenes/whitted_diffuse.gltf"));
        scenes.push(data.join("scenes/Duck/Duck.glb"));
        // Every material input: normal, metallic-roughness and emissive textures, MASK and
        // BLEND, texture transforms (besides materials_public among the references).
        scenes.push(repo.join("scenes/cutout.gltf"));
        scenes.push(data.join("scenes/DamagedHelmet/DamagedHelmet.glb"));
        assert!(scenes.len() >= 9, "{scenes:?}");
        for path in &scenes {
            let scene = Scene::load(path).unwrap();
            let posed = pose::pose(&scene, &[]);
            let g = &posed.geometry;
            let (lo, hi) = g.bounds().unwrap();
            let tree = KdTree::build(g.triangle_list(), BuildParams::default());
            // Every other scene's tree and surfaces in two parts per array (the path of a scene
            // over the binding limit), so that the integrator's bindings of the second parts are
            // checked.
            let halves = scenes.iter().position(|s| s == path).unwrap() % 2 == 0;
            let mut on_gpu = if halves {
                GpuAccel::in_halves(&gpu).unwrap()
            } else {
                GpuAccel::new(&gpu).unwrap()
            };
            on_gpu.upload_tree(&gpu, &tree).unwrap();
            // The scene's lights, and one of each kind more (the Duck has none of its own).
            let centre = (lo + hi) * 0.5;
            let size = (hi - lo).length();
            let eye = centre + Vec3::new(0.3, 0.8, 1.0) * size;
            let mut lights = posed.lights.clone();
            lights.push(Light {
                kind: LightKind::Spot {
                    inner_cone: 0.2,
                    outer_cone: 0.5,
                },
                power: Vec3::new(3.0, 2.5, 2.0) * size * size,
                position: eye,
                direction: (centre - eye).normalize(),
                range: Some(3.0 * size),
            });
            lights.push(Light {
                kind: LightKind::Directional,
                power: Vec3::splat(0.7),
                position: Vec3::ZERO,
                direction: Vec3::new(-0.4, -1.0, -0.3).normalize(),
                range: None,
            });
            let upload = match halves {
                true => GpuScene::upload_in_halves,
                false => GpuScene::upload,
            };
            let gpu_scene = upload(&gpu, g, &scene.materials, &scene.textures, &lights).unwrap();
            let rays = framing_rays(lo, hi, 96, 72);
            let t_max = vec![f32::INFINITY; rays.len()];
            for shading in [ShadingModel::CookTorrance, ShadingModel::Phong] {
                let settings = TraceSettings {
                    max_depth: 8,
                    shading,
                    background: Vec3::new(0.1, 0.2, 0.3),
                };
                let cpu = Integrator::new(
                    SceneView {
                        accel: &tree,
                        geometry: g,
                        materials: &scene.materials,
                        textures: &scene.textures,
                        lights: &lights,
                    },
                    settings,
                );
                let counts = std::cell::Cell::new(Default::default());
                let (got, _) = whitted
                    .radiance(&gpu, &on_gpu, &gpu_scene, &settings, &rays, &t_max)
                    .unwrap();
                let (mut over, mut sum, mut worst) = (0, 0.0f64, 0.0f32);
                const WORST: f32 = 1e-3;
                for (r, g) in rays.iter().zip(&got) {
                    let want = cpu.radiance(r, f32::INFINITY, &counts);
                    let diff = (want - *g).abs().max_element();
                    assert!(diff.is_finite(), "{path:?}: {g} against {want}");
                    over += (diff > WORST) as usize;
                    sum += diff as f64;
                    worst = worst.max(diff);
                }
                let mean = sum / rays.len() as f64;
                eprintln!(
                    "{}, {shading:?}: {over} of {} rays differ by more than {WORST}, mean {mean:.2e}, worst {worst:.2e}",
                    path.display(),
                    rays.len()
                );
                assert!(
                    over * 200 <= rays.len(),
                    "{path:?} {shading:?}: {over} rays"
                );
                assert!(mean < 1e-3, "{path:?} {shading:?}: mean difference {mean}");
            }
        }
    }

    /// The default pipeline rendered on both backends: every pixel of both eyes within 1e-3
    /// (measured when written: at most 1.1e-5, in 110 of 230,400 pixels above 1e-6), which
    /// passes the references' `--fail 0.02 --failpercent 0.5` with room to spare.
    #[test]
    fn the_default_pipeline_renders_the_same_on_both_backends() {
        use stereotrace::compare::{Planes, Thresholds, Verdict, compare};
        use stereotrace::output::exr::read_views;
        use stereotrace::pipeline::LoadedPipeline;
        use stereotrace::run::run;
        if gpu().is_none() {
            return;
        }
        let base =
            LoadedPipeline::load(&super::common::repo().join("pipelines/default.toml")).unwrap();
        let (mut eyes, mut counts) = (Vec::new(), Vec::new());
        for backend in ["cpu", "gpu"] {
            let p = base
                .with_overrides(&[("render.backend".into(), backend.into())])
                .unwrap();
            let out = super::common::scratch(&format!("default-{backend}"));
            let summary = run(&p, &super::common::whole_range_into(&out)).unwrap();
            // The summary names the adapter that traced (and only when one did).
            assert_eq!(summary.device.is_some(), backend == "gpu", "{summary}");
            counts.push(summary.rays);
            eyes.push(read_views(&out.join("out/whitted_0000.exr")).unwrap());
        }
        // The same rays, counted the same way on both (paths differ only where a sample's does).
        let (cpu, gpu) = (counts[0], counts[1]);
        eprintln!("rays: CPU {cpu:?}, GPU {gpu:?}");
        assert_eq!(cpu.primary, gpu.primary);
        for (c, g) in [(cpu.secondary, gpu.secondary), (cpu.shadow, gpu.shadow)] {
            assert!(
                c > 0 && c.abs_diff(g) * 1000 <= c,
                "rays: CPU {cpu:?}, GPU {gpu:?}"
            );
        }
        let rule = Thresholds {
            fail: 0.02,
            fail_percent: 0.5,
            ..Default::default()
        };
        let close = Thresholds {
            fail: 1e-3,
            fail_percent: 0.01,
            ..Default::default()
        };
        for ((eye, cpu), (_, gpu)) in eyes[0].iter().zip(&eyes[1]) {
            let (cpu, gpu) = (Planes::from_image(cpu), Planes::from_image(gpu));
            let d = compare(&gpu, &cpu, &rule);
            let near = compare(&gpu, &cpu, &close);
            eprintln!(
                "{eye}: max {:.2e} at {:?}, mean {:.2e}, {} pixels over 1e-3",
                d.max_error, d.max_at, d.mean_error, near.failures
            );
            assert_ne!(d.verdict, Verdict::Fail, "{eye}: {d:?}");
            assert_ne!(near.verdict, Verdict::Fail, "{eye}: {near:?}");
            assert!(d.mean_error < 1e-6, "{eye}: mean {}", d.mean_error);
        }
    }

    /// The GPU traces every view itself: a pipeline asking it to reproject one eye from the
    /// other is refused at the key, and `render --backend` goes through the same validation.
    #[test]
    fn reprojection_on_the_gpu_is_refused_at_the_key() {
        let dir = super::common::scratch("gpu-reproject");
        let scene = super::common::repo().join("scenes/whitted.gltf");
        let pipeline = dir.join("p.toml");
        std::fs::write(
            &pipeline,
            format!(
                "[scene]\npath = {scene:?}\n[render]\nwidth = 32\nheight = 16\neye_reuse = \"reproject\"\nbackend = \"gpu\"\n[[output]]\nkind = \"png\"\npath = \"f_{{eye}}.png\"\n"
            ),
        )
        .unwrap();
        let run = |args: &[&str]| {
            std::process::Command::new(env!("CARGO_BIN_EXE_stereotrace"))
                .args(args)
                .output()
                .unwrap()
        };
        let out = run(&["check", pipeline.to_str().unwrap()]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        assert!(
            stderr.contains("p.toml:6:") && stderr.contains("eye_reuse"),
            "{stderr}"
        );
        std::fs::write(
            &pipeline,
            std::fs::read_to_string(&pipeline)
                .unwrap()
                .replace("backend = \"gpu\"\n", ""),
        )
        .unwrap();
        let out = run(&[
            "render",
            pipeline.to_str().unwrap(),
            "--backend",
            "gpu",
            "--out",
            dir.to_str().unwrap(),
        ]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        assert!(
            stderr.contains("render.backend=gpu") && stderr.contains("eye_reuse"),
            "{stderr}"
        );
        assert!(!dir.join("f_left.png").exists());
    }

    /// A frame uploads only what changed (as (layouts, trees written, refits)): the static
    /// default scene lays out its tree once for three frames; the animated one, whose glass
    /// sphere moves rigidly, its static tree and the sphere's object-space tree once, then only
    /// the sphere's place; a skinned figure under `update = "refit"` its tree once, then its
    /// refitted boxes every frame, and under `rebuild` a tree every frame.
    #[test]
    fn frames_upload_only_what_changed() {
        use stereotrace::pipeline::LoadedPipeline;
        use stereotrace::run::FrameTracer;
        if gpu().is_none() {
            return;
        }
        let repo = super::common::repo();
        let dir = super::common::scratch("gpu-uploads");
        let figure = repo.join("tests/data/scenes/CesiumMan/CesiumMan.glb");
        for (scene, update, expected) in [
            (repo.join("scenes/whitted.gltf"), "auto", (1, 1, 0)),
            (repo.join("scenes/whitted_animated.gltf"), "auto", (1, 2, 0)),
            (figure.clone(), "refit", (1, 1, 2)),
            // The second frame's tree outgrows the first's room and lays the arrays out again,
            // with room to grow; the third's is written in place.
            (figure, "rebuild", (2, 3, 0)),
        ] {
            let file = dir.join("uploads.toml");
            std::fs::write(
                &file,
                format!(
                    "[scene]\npath = {scene:?}\n[render]\nbackend = \"gpu\"\nwidth = 64\nheight = 36\nspp = 1\n[accel]\nupdate = {update:?}\n[frames]\nstart = 0\nend = 2\n[[output]]\nkind = \"png\"\npath = \"f_{{frame}}_{{eye}}.png\"\n",
                ),
            )
            .unwrap();
            let p = LoadedPipeline::load(&file).unwrap();
            let mut tracer = FrameTracer::new(&p);
            for frame in 0..3 {
                tracer.trace(frame, &p.rig_views(), &|_| {}).unwrap();
            }
            let u = tracer.gpu_uploads().unwrap();
            eprintln!("{scene:?} {update}: {u:?}");
            assert_eq!(
                (u.layouts, u.trees, u.refits),
                expected,
                "{scene:?} {update}"
            );
        }
    }
}
