//! Rays through the CPU's kd-trees on the GPU (`accel.rs`): rays in a storage buffer, one compute
//! invocation per ray (`walk.wgsl`, `parts.wgsl`, `rays.wgsl`), hits read back. Closest hit and
//! any hit, each with three published GPU walks of a kd-tree (`GpuWalk`).

use super::accel::GpuAccel;
use super::buffers::{
    DISPATCH_RAYS, WORKGROUP, checked, dispatch_rays, read_back, readback, storage,
};
use super::device::Gpu;
use crate::accel::{Hit, MAX_DEPTH, Ray};
use crate::error::Result;
use bytemuck::{Pod, Zeroable};

/// How a ray walks the tree on the GPU.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum GpuWalk {
    /// A per-ray stack as deep as the tree: the CPU walk, node for node.
    Stack,
    /// Horn et al.'s short stack (2007): a few entries, and a restart from the root when they
    /// run out.
    Short,
    /// Foley and Sugerman's kd-restart (2005): no stack; every leaf exit restarts at the root.
    Restart,
}

/// The full stack: one entry per level of the depth cap, as the CPU walk's (`traverse.rs`).
pub(super) const FULL_STACK: u32 = MAX_DEPTH + 4;
/// The short stack's entries. Horn et al. keep "a few"; four keeps a ray's stack at 48 bytes.
/// Not tuned on a card (none was at hand when it was written).
pub(super) const SHORT_STACK: u32 = 4;
impl GpuWalk {
    pub const ALL: [GpuWalk; 3] = [GpuWalk::Stack, GpuWalk::Short, GpuWalk::Restart];

    pub fn name(&self) -> &'static str {
        match self {
            GpuWalk::Stack => "stack",
            GpuWalk::Short => "short-stack",
            GpuWalk::Restart => "kd-restart",
        }
    }

    fn stack_entries(&self) -> u32 {
        match self {
            GpuWalk::Stack => FULL_STACK,
            GpuWalk::Short => SHORT_STACK,
            GpuWalk::Restart => 0,
        }
    }
}

/// A ray as the shaders read it (32 bytes, `Ray` in `rays.wgsl` and `whitted.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(super) struct GpuRay {
    pub origin: [f32; 3],
    pub t_max: f32,
    pub dir: [f32; 3],
    pub pad: f32,
}

impl GpuRay {
    /// Rays and their limits as the shaders read them. An infinite limit becomes the largest
    /// float: WGSL lets a compiler assume no value is infinite, and no hit lies beyond it.
    pub(super) fn batch(rays: &[Ray], t_max: &[f32]) -> Vec<GpuRay> {
        rays.iter()
            .zip(t_max)
            .map(|(r, &t)| GpuRay {
                origin: r.origin.to_array(),
                t_max: t.min(f32::MAX),
                dir: r.dir.to_array(),
                pad: 0.0,
            })
            .collect()
    }
}

/// A hit as the shader writes it (`HitOut`); `prim == u32::MAX` is none.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct GpuHit {
    t: f32,
    prim: u32,
    b1: f32,
    b2: f32,
}

/// One dispatch's range of rays and the parts to walk (`Params`).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Params {
    first: u32,
    count: u32,
    parts: u32,
    pad: u32,
}

/// The WGSL that walks a frame's parts: the kd-tree walk with `stack` entries per ray (see
/// `walk.wgsl`) and the parts' walk, before the kernel `main`.
pub(super) fn walk_source(stack: u32, main: &str) -> String {
    [include_str!("walk.wgsl"), include_str!("parts.wgsl"), main]
        .concat()
        .replace("__STACK_CAP__", &stack.to_string())
        .replace("__FULL_STACK__", &FULL_STACK.to_string())
}

/// The bindings of a frame's parts other than 0-2 (the first parts of the nodes, references
/// and triangles): the arrays' second parts (13-15), the boxes (17-18) and the table (19).
pub(super) fn part_bindings(accel: &GpuAccel) -> [(u32, &wgpu::Buffer); 6] {
    [
        (13, &accel.nodes.rest),
        (14, &accel.prim_refs.rest),
        (15, &accel.triangles.rest),
        (17, &accel.boxes.first),
        (18, &accel.boxes.rest),
        (19, &accel.parts),
    ]
}

/// A batch of rays resident on the GPU, with room for their hits and for the work counts of a
/// counted walk (three per workgroup).
pub struct GpuRays {
    rays: wgpu::Buffer,
    hits: wgpu::Buffer,
    readback: wgpu::Buffer,
    work: wgpu::Buffer,
    work_readback: wgpu::Buffer,
    count: usize,
}

impl GpuRays {
    pub fn upload(gpu: &Gpu, rays: &[Ray], t_max: &[f32]) -> Result<GpuRays> {
        assert_eq!(rays.len(), t_max.len(), "one limit per ray");
        let packed = GpuRay::batch(rays, t_max);
        let none = wgpu::BufferUsages::empty();
        let ray_buf = storage(gpu, "the rays", bytemuck::cast_slice(&packed), none)?;
        let blank = vec![GpuHit::zeroed(); rays.len()];
        let hits = storage(
            gpu,
            "the hits",
            bytemuck::cast_slice(&blank),
            wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        )?;
        let hits_back = readback(gpu, "the hits' read-back buffer", hits.size())?;
        let counters = vec![0u32; 3 * rays.len().div_ceil(WORKGROUP)];
        let work = storage(
            gpu,
            "the work counts",
            bytemuck::cast_slice(&counters),
            wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        )?;
        let work_back = readback(gpu, "the work counts' read-back buffer", work.size())?;
        Ok(GpuRays {
            rays: ray_buf,
            hits,
            readback: hits_back,
            work,
            work_readback: work_back,
            count: rays.len(),
        })
    }

    pub fn len(&self) -> usize {
        self.count
    }

    pub fn is_empty(&self) -> bool {
        self.count == 0
    }
}

/// The compiled walks: one pipeline per walk, query (closest hit, any hit) and counting.
pub struct GpuTracer {
    pipelines: Vec<(Query, wgpu::ComputePipeline)>,
}

#[derive(Clone, Copy, PartialEq, Eq)]
struct Query {
    walk: GpuWalk,
    any: bool,
    count: bool,
}

impl GpuTracer {
    pub fn new(gpu: &Gpu) -> Result<GpuTracer> {
        let mut pipelines = Vec::new();
        for walk in GpuWalk::ALL {
            let source = walk_source(walk.stack_entries(), include_str!("rays.wgsl"));
            let module = checked(gpu, "compiling the kd-tree shader", || {
                gpu.device
                    .create_shader_module(wgpu::ShaderModuleDescriptor {
                        label: Some(walk.name()),
                        source: wgpu::ShaderSource::Wgsl(source.into()),
                    })
            })?;
            for (any, count) in [(false, false), (true, false), (false, true), (true, true)] {
                let flag = |on: bool| if on { 1.0 } else { 0.0 };
                let constants = [("ANY_HIT", flag(any)), ("COUNT", flag(count))];
                let pipeline = checked(gpu, "building the kd-tree pipeline", || {
                    gpu.device
                        .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                            label: Some(walk.name()),
                            layout: None,
                            module: &module,
                            entry_point: Some("main"),
                            compilation_options: wgpu::PipelineCompilationOptions {
                                constants: &constants,
                                ..Default::default()
                            },
                            cache: None,
                        })
                })?;
                pipelines.push((Query { walk, any, count }, pipeline));
            }
        }
        Ok(GpuTracer { pipelines })
    }

    /// Walks every ray of `rays` through `accel` (closest hit, or any hit with `any`) and waits
    /// for the GPU; the seconds from submission to completion. The hits stay on the GPU until
    /// `read_hits`.
    pub fn trace(
        &self,
        gpu: &Gpu,
        accel: &GpuAccel,
        rays: &GpuRays,
        walk: GpuWalk,
        any: bool,
    ) -> Result<f64> {
        let query = Query {
            walk,
            any,
            count: false,
        };
        self.dispatch(gpu, accel, rays, query)
    }

    /// Per ray: the inner nodes, leaves and triangle tests of the walk (an untimed pass; the
    /// GPU keeps no mailbox, so a triangle referenced by several leaves is tested in each).
    pub fn work(
        &self,
        gpu: &Gpu,
        accel: &GpuAccel,
        rays: &GpuRays,
        walk: GpuWalk,
        any: bool,
    ) -> Result<[f64; 3]> {
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
        encoder.clear_buffer(&rays.work, 0, None);
        gpu.queue.submit([encoder.finish()]);
        let count = true;
        self.dispatch(gpu, accel, rays, Query { walk, any, count })?;
        let counts: Vec<u32> = read_back(gpu, &rays.work, &rays.work_readback, |b| {
            bytemuck::cast_slice(b).to_vec()
        })?;
        let mut sums = [0u64; 3];
        for c in counts.chunks(3) {
            for k in 0..3 {
                sums[k] += c[k] as u64;
            }
        }
        let n = rays.count.max(1) as f64;
        Ok(sums.map(|v| v as f64 / n))
    }

    fn dispatch(&self, gpu: &Gpu, accel: &GpuAccel, rays: &GpuRays, query: Query) -> Result<f64> {
        if accel.part_count == 0 {
            // Nothing to hit: the hits buffer still says so.
            let blank = vec![
                GpuHit {
                    t: 0.0,
                    prim: u32::MAX,
                    b1: 0.0,
                    b2: 0.0
                };
                rays.count
            ];
            gpu.queue
                .write_buffer(&rays.hits, 0, bytemuck::cast_slice(&blank));
            return Ok(0.0);
        }
        let pipeline = self
            .pipelines
            .iter()
            .find(|(q, _)| *q == query)
            .map(|(_, p)| p)
            .expect("a pipeline per walk and query");
        let bindings = [
            &accel.nodes.first,
            &accel.prim_refs.first,
            &accel.triangles.first,
            &rays.rays,
            &rays.hits,
        ];
        let uniform = |first: usize, count: usize| {
            bytemuck::bytes_of(&Params {
                first: first as u32,
                count: count as u32,
                parts: accel.part_count,
                pad: 0,
            })
            .to_vec()
        };
        let mut rest = vec![(6, &rays.work)];
        rest.extend(part_bindings(accel));
        dispatch_rays(
            gpu,
            pipeline,
            (rays.count, DISPATCH_RAYS),
            uniform,
            &bindings,
            &rest,
        )
    }

    /// The hits of the last `trace` of `rays`.
    pub fn read_hits(&self, gpu: &Gpu, rays: &GpuRays) -> Result<Vec<Option<Hit>>> {
        if rays.count == 0 {
            return Ok(Vec::new());
        }
        read_back(gpu, &rays.hits, &rays.readback, |bytes| {
            let raw: &[GpuHit] = bytemuck::cast_slice(&bytes[..rays.count * 16]);
            raw.iter()
                .map(|h| {
                    (h.prim != u32::MAX).then_some(Hit {
                        t: h.t,
                        prim: h.prim,
                        b1: h.b1,
                        b2: h.b2,
                    })
                })
                .collect()
        })
    }
}
