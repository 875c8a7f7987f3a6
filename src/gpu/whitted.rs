//! The Whitted integrator on the GPU (`whitted.wgsl`): a posed frame's surfaces, materials,
//! textures and lights uploaded once, then the radiance of every camera ray of a batch, both
//! eyes' rays in one batch if the caller likes, traced and shaded on the GPU through the frame's
//! trees (`accel.rs`).

use super::accel::GpuAccel;
use super::buffers::{
    WORKGROUP, binding_limit, checked, dispatch_rays, read_back, readback, storage,
};
use super::device::Gpu;
use super::kdtree::{GpuRay, SHORT_STACK, part_bindings, walk_source};
use super::split_array::SplitArray;
use crate::accel::Ray;
use crate::error::Result;
use crate::render::{ShadingModel, TraceSettings};
use crate::scene::light::{Light, LightKind};
use crate::scene::material::{AlphaMode, Material, TextureRef};
use crate::scene::pose::Geometry;
use crate::scene::texture::{Texture, Wrap};
use bytemuck::{Pod, Zeroable};
use glam::Vec3;

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Vertex {
    p: [f32; 3],
    u0: f32,
    n: [f32; 3],
    v0: f32,
    /// COLOR_0, alpha included.
    color: [f32; 4],
    u1: f32,
    v1: f32,
    pad: [f32; 2],
    /// Zero where the primitive is not normal-mapped.
    tangent: [f32; 4],
}

/// `Slot` in `whitted.wgsl`: a texture slot with its texture coordinate set and its
/// KHR_texture_transform rows (the identity without one; exact, since 1 u + 0 v + 0 = u).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct GpuSlot {
    u: [f32; 3],
    /// Index into the texture headers, or -1: no texture.
    texture: i32,
    v: [f32; 3],
    tex_coord: u32,
}

impl GpuSlot {
    fn of(slot: Option<&TextureRef>) -> GpuSlot {
        let (u, v) = slot
            .and_then(|s| s.transform)
            .map_or((Vec3::X, Vec3::Y), |t| (t.u, t.v));
        GpuSlot {
            u: u.to_array(),
            texture: slot.map_or(-1, |s| s.texture as i32),
            v: v.to_array(),
            tex_coord: slot.map_or(0, |s| s.tex_coord as u32),
        }
    }
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct GpuMaterial {
    base_color: [f32; 4],
    emissive: [f32; 3],
    metallic: f32,
    roughness: f32,
    transmission: f32,
    ior: f32,
    /// 0 opaque, 1 mask, 2 blend.
    alpha_mode: u32,
    alpha_cutoff: f32,
    normal_scale: f32,
    pad: [f32; 2],
    base_color_slot: GpuSlot,
    metallic_roughness_slot: GpuSlot,
    normal_slot: GpuSlot,
    emissive_slot: GpuSlot,
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct GpuLight {
    position: [f32; 3],
    kind: u32,
    direction: [f32; 3],
    range: f32,
    power: [f32; 3],
    cos_outer: f32,
    cos_inner: f32,
    pad: [f32; 3],
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct GpuTexture {
    offset: u32,
    width: u32,
    height: u32,
    flags: u32,
}

/// `Frame` in `whitted.wgsl`: one dispatch's rays and the settings.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct FrameParams {
    first: u32,
    count: u32,
    parts: u32,
    pad1: u32,
    background: [f32; 3],
    max_depth: u32,
    shading: u32,
    lights: u32,
    stride: u32,
    pad: u32,
}

/// A posed frame's shading data on the GPU. Materials and textures never change; a later frame
/// writes the span of vertices that moved, and the lights when they did.
///
/// The vertices, the triangles' vertex indices and the texels, the arrays that grow with the
/// scene, may each sit in two buffers when larger than the adapter binds in one (`SplitArray`).
pub struct GpuScene {
    vertices: SplitArray,
    /// The vertices as last written, to find what a frame moved.
    written: Vec<Vertex>,
    written_lights: Vec<Light>,
    triangles: SplitArray,
    materials: wgpu::Buffer,
    lights: wgpu::Buffer,
    textures: wgpu::Buffer,
    texels: SplitArray,
    light_count: u32,
    features: GpuFeatures,
}

/// A storage buffer of `items` that a frame may write again, holding one zeroed item when there
/// are none (a binding may not be smaller than its element).
fn array<T: Pod>(gpu: &Gpu, what: &str, items: &[T]) -> Result<wgpu::Buffer> {
    let zero = [T::zeroed()];
    let items = if items.is_empty() { &zero[..] } else { items };
    storage(
        gpu,
        what,
        bytemuck::cast_slice(items),
        wgpu::BufferUsages::COPY_DST,
    )
}

fn wrap_code(w: Wrap) -> u32 {
    match w {
        Wrap::Repeat => 0,
        Wrap::MirroredRepeat => 1,
        Wrap::ClampToEdge => 2,
    }
}

impl GpuScene {
    pub fn upload(
        gpu: &Gpu,
        geometry: &Geometry,
        materials: &[Material],
        textures: &[Texture],
        lights: &[Light],
    ) -> Result<GpuScene> {
        let limit = binding_limit(gpu);
        Self::upload_within(gpu, geometry, materials, textures, lights, limit)
    }

    /// `upload` with the vertices, triangles and texels each in two halves whatever their
    /// size: the path of a scene larger than the binding limit, for testing it on a small one.
    pub fn upload_in_halves(
        gpu: &Gpu,
        geometry: &Geometry,
        materials: &[Material],
        textures: &[Texture],
        lights: &[Light],
    ) -> Result<GpuScene> {
        Self::upload_within(gpu, geometry, materials, textures, lights, 0)
    }

    fn upload_within(
        gpu: &Gpu,
        geometry: &Geometry,
        materials: &[Material],
        textures: &[Texture],
        lights: &[Light],
        limit: u64,
    ) -> Result<GpuScene> {
        let g = geometry;
        let vertices = vertices_of(g);
        let triangles: Vec<[u32; 4]> = g
            .triangles
            .iter()
            .zip(&g.triangle_materials)
            .map(|(&[a, b, c], &m)| [a, b, c, m])
            .collect();
        // The decoded textures packed one after another, in the scene's order.
        let mut headers = Vec::new();
        let mut texels = Vec::new();
        for t in textures {
            headers.push(GpuTexture {
                offset: texels.len() as u32,
                width: t.width as u32,
                height: t.height as u32,
                flags: wrap_code(t.wrap[0])
                    | wrap_code(t.wrap[1]) << 2
                    | if t.nearest { 16 } else { 0 },
            });
            texels.extend(t.texels.iter().map(|v| v.to_array()));
        }
        let features = GpuFeatures::of(materials);
        let materials: Vec<GpuMaterial> = materials
            .iter()
            .map(|m| {
                let (alpha_mode, alpha_cutoff) = match m.alpha {
                    AlphaMode::Opaque => (0, 0.0),
                    AlphaMode::Mask { cutoff } => (1, cutoff),
                    AlphaMode::Blend => (2, 0.0),
                };
                GpuMaterial {
                    base_color: m.base_color.to_array(),
                    emissive: m.emissive.to_array(),
                    metallic: m.metallic,
                    roughness: m.roughness,
                    transmission: m.transmission,
                    ior: m.ior,
                    alpha_mode,
                    alpha_cutoff,
                    normal_scale: m.normal_texture.map_or(1.0, |n| n.scale),
                    pad: [0.0; 2],
                    base_color_slot: GpuSlot::of(m.base_color_texture.as_ref()),
                    metallic_roughness_slot: GpuSlot::of(m.metallic_roughness_texture.as_ref()),
                    normal_slot: GpuSlot::of(m.normal_texture.as_ref().map(|n| &n.texture)),
                    emissive_slot: GpuSlot::of(m.emissive_texture.as_ref()),
                }
            })
            .collect();
        let gpu_lights = lights_of(lights);
        Ok(GpuScene {
            vertices: SplitArray::filled(gpu, "the vertices", &vertices, limit)?,
            written: vertices,
            written_lights: lights.to_vec(),
            triangles: SplitArray::filled(gpu, "the triangles' vertex indices", &triangles, limit)?,
            materials: array(gpu, "the materials", &materials)?,
            light_count: gpu_lights.len() as u32,
            lights: array(gpu, "the lights", &gpu_lights)?,
            textures: array(gpu, "the textures", &headers)?,
            texels: SplitArray::filled(gpu, "the texels", &texels, limit)?,
            features,
        })
    }

    /// Bytes the scene holds on the GPU.
    pub fn resident_bytes(&self) -> u64 {
        [&self.materials, &self.lights, &self.textures]
            .iter()
            .map(|b| b.size())
            .sum::<u64>()
            + [&self.vertices, &self.triangles, &self.texels]
                .iter()
                .map(|a| a.size())
                .sum::<u64>()
    }

    /// Brings the vertices and lights up to date with a later pose of the same scene, writing
    /// the span of vertices that changed and the lights if they did; the bytes written.
    pub fn update(&mut self, gpu: &Gpu, geometry: &Geometry, lights: &[Light]) -> Result<u64> {
        let vertices = vertices_of(geometry);
        assert_eq!(
            vertices.len(),
            self.written.len(),
            "a pose of the same scene"
        );
        let same = |(a, b): (&Vertex, &Vertex)| bytemuck::bytes_of(a) == bytemuck::bytes_of(b);
        let first = vertices.iter().zip(&self.written).position(|v| !same(v));
        let mut bytes = 0;
        if let Some(first) = first {
            let end = vertices.len()
                - vertices
                    .iter()
                    .zip(&self.written)
                    .rev()
                    .position(|v| !same(v))
                    .expect("one differs");
            bytes += self.vertices.write(gpu, first, &vertices[first..end]);
            self.written = vertices;
        }
        if lights != self.written_lights {
            let gpu_lights = lights_of(lights);
            self.light_count = gpu_lights.len() as u32;
            self.lights = array(gpu, "the lights", &gpu_lights)?;
            self.written_lights = lights.to_vec();
            bytes += (gpu_lights.len() * std::mem::size_of::<GpuLight>()) as u64;
        }
        Ok(bytes)
    }
}

/// The posed vertices as the integrator reads them.
fn vertices_of(g: &Geometry) -> Vec<Vertex> {
    (0..g.positions.len())
        .map(|i| {
            let uv = |k: usize| g.tex_coords[k].get(i).copied().unwrap_or_default();
            Vertex {
                p: g.positions[i].to_array(),
                n: g.normals.get(i).copied().unwrap_or_default().to_array(),
                color: g.colors.get(i).map_or([1.0; 4], |c| c.to_array()),
                u0: uv(0).x,
                v0: uv(0).y,
                u1: uv(1).x,
                v1: uv(1).y,
                pad: [0.0; 2],
                tangent: g.tangents.get(i).map_or([0.0; 4], |t| t.to_array()),
            }
        })
        .collect()
}

/// The lights as the integrator reads them.
fn lights_of(lights: &[Light]) -> Vec<GpuLight> {
    lights
        .iter()
        .map(|l| {
            let (kind, cos_inner, cos_outer) = match l.kind {
                LightKind::Directional => (0, 1.0, 1.0),
                LightKind::Point => (1, 1.0, 1.0),
                LightKind::Spot {
                    inner_cone,
                    outer_cone,
                } => (2, inner_cone.cos(), outer_cone.cos()),
            };
            GpuLight {
                position: l.position.to_array(),
                kind,
                direction: l.direction.to_array(),
                range: l.range.filter(|r| *r > 0.0).unwrap_or(0.0),
                power: l.power.to_array(),
                cos_outer,
                cos_inner,
                pad: [0.0; 3],
            }
        })
        .collect()
}

/// The compiled integrator.
pub struct GpuWhitted {
    /// A kernel per set of material inputs, compiled when a scene first needs it.
    kernels: std::sync::Mutex<Vec<(GpuFeatures, std::sync::Arc<wgpu::ComputePipeline>)>>,
}

/// The material inputs a scene's materials use, each a constant of the Whitted kernel
/// (`whitted.wgsl`): a kernel leaves out the code of inputs its scene lacks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GpuFeatures {
    /// A MASK or BLEND material.
    pub transparent: bool,
    pub normal_maps: bool,
    pub metallic_roughness_textures: bool,
    pub emissive_textures: bool,
}

impl GpuFeatures {
    pub fn of(materials: &[Material]) -> GpuFeatures {
        let any = |f: fn(&Material) -> bool| materials.iter().any(f);
        GpuFeatures {
            transparent: any(Material::is_transparent),
            normal_maps: any(|m| m.normal_texture.is_some()),
            metallic_roughness_textures: any(|m| m.metallic_roughness_texture.is_some()),
            emissive_textures: any(|m| m.emissive_texture.is_some()),
        }
    }
}

impl GpuWhitted {
    /// The integrator, with the kernel of opaque, untextured scenes compiled (so that a shader
    /// the adapter refuses is an error here).
    pub fn new(gpu: &Gpu) -> Result<GpuWhitted> {
        let whitted = GpuWhitted {
            kernels: std::sync::Mutex::new(Vec::new()),
        };
        whitted.kernel(gpu, GpuFeatures::default())?;
        Ok(whitted)
    }

    /// The kernel for a scene's material inputs, compiled on first use.
    fn kernel(
        &self,
        gpu: &Gpu,
        features: GpuFeatures,
    ) -> Result<std::sync::Arc<wgpu::ComputePipeline>> {
        let mut kernels = self.kernels.lock().expect("no kernel compile panicked");
        if let Some((_, k)) = kernels.iter().find(|(f, _)| *f == features) {
            return Ok(k.clone());
        }
        let kernel = std::sync::Arc::new(Self::compile(gpu, features)?);
        kernels.push((features, kernel.clone()));
        Ok(kernel)
    }

    fn compile(gpu: &Gpu, features: GpuFeatures) -> Result<wgpu::ComputePipeline> {
        // The short stack: a ray's walk state stays small next to the integrator's own stack of
        // waiting rays, and every walk finds the same hits.
        let flag = |on: bool| if on { "true" } else { "false" };
        let source = walk_source(SHORT_STACK, include_str!("whitted.wgsl"))
            .replace("__TRANSPARENT__", flag(features.transparent))
            .replace("__NORMAL_MAPS__", flag(features.normal_maps))
            .replace(
                "__METALLIC_ROUGHNESS_TEXTURES__",
                flag(features.metallic_roughness_textures),
            )
            .replace("__EMISSIVE_TEXTURES__", flag(features.emissive_textures));
        let module = checked(gpu, "compiling the Whitted shader", || {
            gpu.device
                .create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some("whitted"),
                    source: wgpu::ShaderSource::Wgsl(source.into()),
                })
        })?;
        checked(gpu, "building the Whitted pipeline", || {
            gpu.device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some("whitted"),
                    layout: None,
                    module: &module,
                    entry_point: Some("main"),
                    compilation_options: Default::default(),
                    cache: None,
                })
        })
    }

    /// The radiance along each camera ray (`Integrator::radiance` on the CPU), with its limit,
    /// and the secondary and shadow rays traced for them.
    pub fn radiance(
        &self,
        gpu: &Gpu,
        accel: &GpuAccel,
        scene: &GpuScene,
        settings: &TraceSettings,
        rays: &[Ray],
        t_max: &[f32],
    ) -> Result<(Vec<Vec3>, [u64; 2])> {
        assert_eq!(rays.len(), t_max.len(), "one limit per ray");
        if rays.is_empty() {
            return Ok((Vec::new(), [0; 2]));
        }
        let packed = GpuRay::batch(rays, t_max);
        let none = wgpu::BufferUsages::empty();
        let ray_buf = storage(gpu, "the camera rays", bytemuck::cast_slice(&packed), none)?;
        let out = storage(
            gpu,
            "the radiance",
            &vec![0u8; 16 * rays.len()],
            wgpu::BufferUsages::COPY_SRC,
        )?;
        let back = readback(gpu, "the radiance's read-back buffer", out.size())?;
        let counts = storage(
            gpu,
            "the ray counts",
            &vec![0u8; 8 * rays.len().div_ceil(WORKGROUP)],
            wgpu::BufferUsages::COPY_SRC,
        )?;
        let counts_back = readback(gpu, "the ray counts' read-back buffer", counts.size())?;
        // Each invocation's waiting rays: one per level and the one traced (48 bytes each: a
        // hit pops one and pushes at most two, mirror and refraction or mirror and BLEND
        // continuation, since transmissive materials are opaque to alpha), for
        // as many rays per dispatch as fit the adapter's binding limit, at most 2^16.
        let stride = settings.max_depth + 1;
        let entry = 48 * stride as u64;
        let limit = binding_limit(gpu);
        let per_dispatch = ((limit / entry) as usize).clamp(WORKGROUP, 1 << 16);
        let pending = checked(gpu, "the waiting rays", || {
            gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("waiting rays"),
                size: entry * per_dispatch.min(rays.len().next_multiple_of(WORKGROUP)) as u64,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            })
        })?;
        let uniform = |first: usize, count: usize| {
            bytemuck::bytes_of(&FrameParams {
                first: first as u32,
                count: count as u32,
                parts: accel.part_count,
                pad1: 0,
                background: settings.background.to_array(),
                max_depth: settings.max_depth,
                shading: match settings.shading {
                    ShadingModel::CookTorrance => 0,
                    ShadingModel::Phong => 1,
                },
                lights: scene.light_count,
                stride,
                pad: 0,
            })
            .to_vec()
        };
        let first = [
            &accel.nodes.first,
            &accel.prim_refs.first,
            &accel.triangles.first,
            &ray_buf,
            &out,
        ];
        let mut rest = vec![
            (6, &scene.vertices.first),
            (7, &scene.triangles.first),
            (8, &scene.materials),
            (9, &scene.lights),
            (10, &scene.textures),
            (11, &scene.texels.first),
            (20, &scene.vertices.rest),
            (21, &scene.triangles.rest),
            (22, &scene.texels.rest),
            (12, &pending),
            (16, &counts),
        ];
        rest.extend(part_bindings(accel));
        dispatch_rays(
            gpu,
            &*self.kernel(gpu, scene.features)?,
            (rays.len(), per_dispatch),
            uniform,
            &first,
            &rest,
        )?;
        let radiance = read_back(gpu, &out, &back, |bytes| {
            let raw: &[[f32; 4]] = bytemuck::cast_slice(bytes);
            raw.iter().map(|c| Vec3::new(c[0], c[1], c[2])).collect()
        })?;
        let traced = read_back(gpu, &counts, &counts_back, |bytes| {
            let raw: &[[u32; 2]] = bytemuck::cast_slice(bytes);
            raw.iter()
                .fold([0u64; 2], |[a, b], c| [a + c[0] as u64, b + c[1] as u64])
        })?;
        Ok((radiance, traced))
    }
}
