//! Buffers on the GPU: created within the adapter's limits, with errors instead of wgpu's
//! panics, and read back to the host.

use super::device::Gpu;
use crate::error::{Error, Result};
use wgpu::util::DeviceExt;

/// Runs `make` inside an error scope, so that running out of memory or a limit the adapter
/// refuses comes back as an error instead of wgpu's default of panicking.
pub fn checked<T>(gpu: &Gpu, what: &str, make: impl FnOnce() -> T) -> Result<T> {
    let memory = gpu.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let validation = gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
    let value = make();
    let invalid = pollster::block_on(validation.pop());
    let out_of_memory = pollster::block_on(memory.pop());
    match invalid.or(out_of_memory) {
        Some(e) => Err(Error::Device {
            message: format!("{}: {what}: {e}", gpu.info.name),
        }),
        None => Ok(value),
    }
}

/// The most bytes the adapter binds in one storage buffer.
pub fn binding_limit(gpu: &Gpu) -> u64 {
    gpu.limits
        .max_storage_buffer_binding_size
        .min(gpu.limits.max_buffer_size)
}

/// A storage buffer holding `bytes` (at least 4, since a binding may not be empty), after
/// checking it against the adapter's limits.
pub fn storage(
    gpu: &Gpu,
    what: &str,
    bytes: &[u8],
    usage: wgpu::BufferUsages,
) -> Result<wgpu::Buffer> {
    let limit = binding_limit(gpu);
    if bytes.len() as u64 > limit {
        return Err(Error::Device {
            message: format!(
                "{what} need {:.1} MiB, more than the {:.1} MiB {} binds in one buffer; render \
                 this scene with the CPU backend",
                bytes.len() as f64 / 1048576.0,
                limit as f64 / 1048576.0,
                gpu.info.name
            ),
        });
    }
    let padded;
    let contents = if bytes.is_empty() {
        padded = [0u8; 4];
        &padded[..]
    } else {
        bytes
    };
    checked(gpu, what, || {
        gpu.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(what),
                contents,
                usage: wgpu::BufferUsages::STORAGE | usage,
            })
    })
}

/// A buffer the host reads back after copying into it.
pub fn readback(gpu: &Gpu, what: &str, size: u64) -> Result<wgpu::Buffer> {
    checked(gpu, what, || {
        gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(what),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    })
}

pub fn wait(gpu: &Gpu) -> Result<()> {
    gpu.device
        .poll(wgpu::PollType::wait_indefinitely())
        .map(|_| ())
        .map_err(|e| Error::Device {
            message: format!("{}: waiting for the GPU failed: {e}", gpu.info.name),
        })
}

/// Copies `source` into the mappable `staging` buffer, waits, and decodes its bytes.
pub fn read_back<T>(
    gpu: &Gpu,
    source: &wgpu::Buffer,
    staging: &wgpu::Buffer,
    decode: impl FnOnce(&[u8]) -> T,
) -> Result<T> {
    let mut encoder = gpu
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    encoder.copy_buffer_to_buffer(source, 0, staging, 0, source.size());
    gpu.queue.submit([encoder.finish()]);
    let slice = staging.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    wait(gpu)?;
    let failed = |e: String| Error::Device {
        message: format!("{}: reading results back failed: {e}", gpu.info.name),
    };
    rx.recv()
        .map_err(|e| failed(e.to_string()))?
        .map_err(|e| failed(e.to_string()))?;
    let value = {
        let view = slice
            .get_mapped_range()
            .map_err(|e| failed(e.to_string()))?;
        decode(&view)
    };
    staging.unmap();
    Ok(value)
}

/// Rays per dispatch, so that no single dispatch runs for long enough to trip a driver's
/// watchdog (a second or two on desktop systems) on a large scene: 2^18 rays at a few Mrays/s.
pub const DISPATCH_RAYS: usize = 1 << 18;
/// Invocations per workgroup, as `@workgroup_size` in the kernels.
pub const WORKGROUP: usize = 64;

/// Runs `pipeline` over `count` rays in dispatches of at most `per_dispatch` (a multiple of
/// `WORKGROUP`), all in one submission, and waits; the seconds from submission to completion.
/// Bindings 0-4 are `first`, 5 the dispatch's uniform (`uniform(first ray, rays)`), then `rest`
/// at the bindings it names.
pub fn dispatch_rays(
    gpu: &Gpu,
    pipeline: &wgpu::ComputePipeline,
    (count, per_dispatch): (usize, usize),
    uniform: impl Fn(usize, usize) -> Vec<u8>,
    first: &[&wgpu::Buffer; 5],
    rest: &[(u32, &wgpu::Buffer)],
) -> Result<f64> {
    let layout = pipeline.get_bind_group_layout(0);
    let groups: Vec<(wgpu::BindGroup, u32)> = (0..count)
        .step_by(per_dispatch)
        .map(|start| {
            let n = per_dispatch.min(count - start);
            let params = gpu
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("dispatch"),
                    contents: &uniform(start, n),
                    usage: wgpu::BufferUsages::UNIFORM,
                });
            let entries: Vec<wgpu::BindGroupEntry> = first
                .iter()
                .copied()
                .chain([&params])
                .enumerate()
                .map(|(i, b)| (i as u32, b))
                .chain(rest.iter().copied())
                .map(|(binding, b)| wgpu::BindGroupEntry {
                    binding,
                    resource: b.as_entire_binding(),
                })
                .collect();
            let group = checked(gpu, "binding the buffers", || {
                gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("rays"),
                    layout: &layout,
                    entries: &entries,
                })
            })?;
            Ok((group, n.div_ceil(WORKGROUP) as u32))
        })
        .collect::<Result<_>>()?;
    let mut encoder = gpu
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
        pass.set_pipeline(pipeline);
        for (group, workgroups) in &groups {
            pass.set_bind_group(0, group, &[]);
            pass.dispatch_workgroups(*workgroups, 1, 1);
        }
    }
    let start = std::time::Instant::now();
    gpu.queue.submit([encoder.finish()]);
    wait(gpu)?;
    Ok(start.elapsed().as_secs_f64())
}
