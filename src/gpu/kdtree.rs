//! The CPU's kd-tree on the GPU: its arrays uploaded as they are (`accel::TreeArrays`), rays in a
//! storage buffer, one compute invocation per ray (`walk.wgsl`, `rays.wgsl`), hits read back. Closest hit
//! and any hit, each with three published GPU walks (`GpuWalk`).

use super::buffers::{
    DISPATCH_RAYS, WORKGROUP, checked, dispatch_rays, read_back, readback, storage,
};
use super::device::Gpu;
use crate::accel::{Hit, KdTree, MAX_DEPTH, Ray};
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

/// One dispatch's range of rays and the scene box (`Params`).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Params {
    bounds_min: [f32; 3],
    first: u32,
    bounds_max: [f32; 3],
    count: u32,
}

/// A kd-tree resident on the GPU.
pub struct GpuTree {
    pub(super) nodes: wgpu::Buffer,
    pub(super) prim_refs: wgpu::Buffer,
    pub(super) triangles: wgpu::Buffer,
    /// The second parts of the three arrays (bindings 13-15): an array larger than the adapter
    /// binds in one buffer continues here; otherwise a placeholder the walk never reads.
    pub(super) rest: [wgpu::Buffer; 3],
    /// The root's box; `None` for a tree nothing can hit.
    pub(super) bounds: Option<([f32; 3], [f32; 3])>,
    /// Bytes uploaded.
    pub bytes: u64,
}

/// `items` in one storage buffer when they fit `limit` bytes, else in two (split between
/// elements, each within the limit; `limit` 0 splits at the middle, for tests); the second is a
/// one-element placeholder when unused. More than twice the limit is refused.
fn two_parts<T: Pod>(
    gpu: &Gpu,
    what: &str,
    items: &[T],
    limit: u64,
) -> Result<(wgpu::Buffer, wgpu::Buffer)> {
    let none = wgpu::BufferUsages::empty();
    let size = std::mem::size_of::<T>();
    // Within the limit, the first part takes everything and the second is the placeholder.
    let first = if limit == 0 {
        items.len().div_ceil(2)
    } else {
        ((limit / size as u64) as usize).min(items.len())
    };
    let (a, b) = items.split_at(first);
    let placeholder = vec![0u8; size];
    let rest = if b.is_empty() {
        &placeholder[..]
    } else {
        bytemuck::cast_slice(b)
    };
    Ok((
        storage(gpu, what, bytemuck::cast_slice(a), none)?,
        storage(gpu, what, rest, none)?,
    ))
}

impl GpuTree {
    /// Uploads the tree's arrays unchanged: the shader decodes the CPU's node words. An array
    /// larger than the adapter binds in one buffer goes in two.
    pub fn upload(gpu: &Gpu, tree: &KdTree) -> Result<GpuTree> {
        Self::upload_parts(gpu, tree, false)
    }

    /// `upload` with every array split in two halves whatever its size: the path a tree larger
    /// than the binding limit takes, for testing it on a small one.
    pub fn upload_in_halves(gpu: &Gpu, tree: &KdTree) -> Result<GpuTree> {
        Self::upload_parts(gpu, tree, true)
    }

    fn upload_parts(gpu: &Gpu, tree: &KdTree, halves: bool) -> Result<GpuTree> {
        let a = tree.arrays();
        let nodes: Vec<[u32; 2]> = a.nodes.iter().map(|n| n.words()).collect();
        let triangles: Vec<[f32; 9]> = a
            .triangles
            .iter()
            .map(|t| {
                let [p, q, r] = t.map(|v| v.to_array());
                [p[0], p[1], p[2], q[0], q[1], q[2], r[0], r[1], r[2]]
            })
            .collect();
        let limit = if halves {
            0
        } else {
            gpu.limits
                .max_storage_buffer_binding_size
                .min(gpu.limits.max_buffer_size)
        };
        let (nodes, nodes_rest) = two_parts(gpu, "the kd-tree's nodes", &nodes, limit)?;
        let (prim_refs, refs_rest) =
            two_parts(gpu, "the kd-tree's leaf references", a.prim_refs, limit)?;
        let (triangles, tris_rest) = two_parts(gpu, "the triangles", &triangles, limit)?;
        let rest = [nodes_rest, refs_rest, tris_rest];
        let bytes = [&nodes, &prim_refs, &triangles]
            .into_iter()
            .chain(&rest)
            .map(|b| b.size())
            .sum();
        Ok(GpuTree {
            nodes,
            prim_refs,
            triangles,
            rest,
            bounds: (!a.bounds.is_empty() && !a.nodes.is_empty())
                .then(|| (a.bounds.min.to_array(), a.bounds.max.to_array())),
            bytes,
        })
    }
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
            let source = [include_str!("walk.wgsl"), include_str!("rays.wgsl")]
                .concat()
                .replace("__STACK_CAP__", &walk.stack_entries().to_string())
                .replace("__FULL_STACK__", &FULL_STACK.to_string());
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

    /// Walks every ray of `rays` through `tree` (closest hit, or any hit with `any`) and waits
    /// for the GPU; the seconds from submission to completion. The hits stay on the GPU until
    /// `read_hits`.
    pub fn trace(
        &self,
        gpu: &Gpu,
        tree: &GpuTree,
        rays: &GpuRays,
        walk: GpuWalk,
        any: bool,
    ) -> Result<f64> {
        let query = Query {
            walk,
            any,
            count: false,
        };
        self.dispatch(gpu, tree, rays, query)
    }

    /// Per ray: the inner nodes, leaves and triangle tests of the walk (an untimed pass; the
    /// GPU keeps no mailbox, so a triangle referenced by several leaves is tested in each).
    pub fn work(
        &self,
        gpu: &Gpu,
        tree: &GpuTree,
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
        self.dispatch(gpu, tree, rays, Query { walk, any, count })?;
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

    fn dispatch(&self, gpu: &Gpu, tree: &GpuTree, rays: &GpuRays, query: Query) -> Result<f64> {
        let Some((lo, hi)) = tree.bounds else {
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
        };
        let pipeline = self
            .pipelines
            .iter()
            .find(|(q, _)| *q == query)
            .map(|(_, p)| p)
            .expect("a pipeline per walk and query");
        let bindings = [
            &tree.nodes,
            &tree.prim_refs,
            &tree.triangles,
            &rays.rays,
            &rays.hits,
        ];
        let uniform = |first: usize, count: usize| {
            bytemuck::bytes_of(&Params {
                bounds_min: lo,
                first: first as u32,
                bounds_max: hi,
                count: count as u32,
            })
            .to_vec()
        };
        dispatch_rays(
            gpu,
            pipeline,
            (rays.count, DISPATCH_RAYS),
            uniform,
            &bindings,
            &[
                (6, &rays.work),
                (13, &tree.rest[0]),
                (14, &tree.rest[1]),
                (15, &tree.rest[2]),
            ],
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
