//! The graphics adapter and its device: which one is chosen, what it can hold, and how it is
//! named in every timing.

use crate::error::{Error, Result};

/// Names a substring of the adapter to use (`vulkaninfo --summary` lists them), for machines with
/// several.
pub const ADAPTER_VAR: &str = "STEREOTRACE_GPU_ADAPTER";

pub struct Gpu {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    pub limits: wgpu::Limits,
}

/// Preference among adapter kinds: a card before anything emulated, a software rasteriser last,
/// so that a machine with a real GPU never runs on its software one unless told to.
fn rank(kind: wgpu::DeviceType) -> u8 {
    match kind {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    }
}

impl Gpu {
    /// The preferred adapter (or the one `STEREOTRACE_GPU_ADAPTER` names) with a device asking
    /// for all of its limits; wgpu's defaults would cap a storage binding at 128 MiB.
    pub fn open() -> Result<Gpu> {
        // Vulkan, Metal and DX12 (`WGPU_BACKEND` narrows them further): the compute shaders
        // are written for them, and OpenGL (through EGL) is not built in.
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
        desc.backends = wgpu::Backends::PRIMARY;
        let desc = desc.with_env();
        let backends = desc.backends;
        let instance = wgpu::Instance::new(desc);
        let adapters = pollster::block_on(instance.enumerate_adapters(backends));
        let listed: Vec<String> = adapters.iter().map(|a| a.get_info().name).collect();
        let wanted = std::env::var(ADAPTER_VAR).ok().filter(|v| !v.is_empty());
        let chosen = match &wanted {
            Some(name) => adapters.into_iter().find(|a| {
                a.get_info()
                    .name
                    .to_lowercase()
                    .contains(&name.to_lowercase())
            }),
            None => adapters
                .into_iter()
                .min_by_key(|a| rank(a.get_info().device_type)),
        };
        let Some(adapter) = chosen else {
            return Err(Error::Device {
                message: match wanted {
                    Some(name) => format!(
                        "no adapter matches {ADAPTER_VAR}={name:?} (found: {})",
                        if listed.is_empty() {
                            "none".to_string()
                        } else {
                            listed.join(", ")
                        }
                    ),
                    None => "no graphics adapter found (Vulkan, Metal or DX12); without a card, \
                             Mesa's software Vulkan driver runs the GPU backend (Debian: \
                             mesa-vulkan-drivers)"
                        .into(),
                },
            });
        };
        let info = adapter.get_info();
        let limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("stereotrace"),
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .map_err(|e| Error::Device {
            message: format!("{}: cannot open a device: {e}", info.name),
        })?;
        Ok(Gpu {
            device,
            queue,
            info,
            limits,
        })
    }

    /// Whether this adapter runs on the CPU (a software rasteriser such as lavapipe): its timings
    /// check correctness, they are no GPU's speed.
    pub fn is_software(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// The adapter, its driver and the limits that bound a scene, for every timing's log line.
    pub fn describe(&self) -> String {
        let mib = |b: u64| b as f64 / (1024.0 * 1024.0);
        format!(
            "{} ({:?}, {:?}; driver {} {}; storage binding {:.0} MiB, buffer {:.0} MiB)",
            self.info.name,
            self.info.device_type,
            self.info.backend,
            self.info.driver,
            self.info.driver_info,
            mib(self.limits.max_storage_buffer_binding_size),
            mib(self.limits.max_buffer_size),
        )
    }
}
