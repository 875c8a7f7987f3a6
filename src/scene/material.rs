//! Surface materials: the glTF metallic-roughness model with every texture a Whitted renderer
//! reads (base colour, metallic-roughness, normal, emissive), `KHR_texture_transform` on each slot,
//! `alphaMode`, `KHR_materials_emissive_strength`, `KHR_materials_transmission` and
//! `KHR_materials_ior` (the convention is WHITTED-materials.md in `tests/data`). Textures are
//! decoded here (and sampled in `texture`), once per transfer function a material samples them with, and only those some
//! material samples: a scene pays for the images it uses. Occlusion textures are never decoded:
//! the specification makes them darken indirect (ambient) light only, and Whitted has none.

use super::buffers::{read_uri, view_bytes};
use super::texture::{Encoding, Texels, Texture, Wrap};
use crate::error::{Error, Result};
use glam::{Vec2, Vec3, Vec4};
use std::collections::BTreeMap;
use std::path::Path;

/// glTF `alphaMode`: what the coverage `a` (base colour alpha x texel alpha x COLOR_0 alpha)
/// does to a hit (WHITTED-materials.md section 4).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AlphaMode {
    /// Coverage is ignored.
    Opaque,
    /// A hit with `a < cutoff` does not exist for any ray; the rest is opaque.
    Mask { cutoff: f32 },
    /// The surface is blended "over" what lies behind it: `a L_surf + (1 - a) L_behind`.
    Blend,
}

#[derive(Clone, Debug)]
pub struct Material {
    pub name: Option<String>,
    /// Linear RGBA factor; its alpha is a factor of the coverage.
    pub base_color: Vec4,
    pub base_color_texture: Option<TextureRef>,
    pub metallic: f32,
    pub roughness: f32,
    /// Roughness in G and metalness in B, multiplying the factors.
    pub metallic_roughness_texture: Option<TextureRef>,
    pub normal_texture: Option<NormalMap>,
    /// `emissiveFactor` times `KHR_materials_emissive_strength` (1 when absent).
    pub emissive: Vec3,
    pub emissive_texture: Option<TextureRef>,
    pub alpha: AlphaMode,
    /// KHR_materials_transmission factor; the integrator treats > 0.5 as a smooth dielectric.
    pub transmission: f32,
    /// KHR_materials_ior (glTF default 1.5).
    pub ior: f32,
    pub double_sided: bool,
    /// Inputs of the file the renderer leaves out, each with the reason.
    pub unused: Vec<&'static str>,
}

/// `Material::unused` entries.
pub const OCCLUSION_UNUSED: &str = "occlusionTexture: no effect, it darkens only indirect (ambient) light, which Whitted has none of";
pub const TRANSMISSION_TEXTURE_UNUSED: &str =
    "transmissionTexture: ignored, the factor alone decides glass";
pub const GLASS_ALPHA_UNUSED: &str =
    "alphaMode: ignored on a transmissive material, which passes light by refraction";

impl Default for Material {
    /// glTF 2.0 section 3.9.6: the default material when a primitive names none.
    fn default() -> Self {
        Material {
            name: Some("default".into()),
            base_color: Vec4::ONE,
            base_color_texture: None,
            metallic: 1.0,
            roughness: 1.0,
            metallic_roughness_texture: None,
            normal_texture: None,
            emissive: Vec3::ZERO,
            emissive_texture: None,
            alpha: AlphaMode::Opaque,
            transmission: 0.0,
            ior: 1.5,
            double_sided: false,
            unused: Vec::new(),
        }
    }
}

impl Material {
    /// Whether the material needs the texture coordinates and colours of a hit before it knows
    /// whether the hit exists (MASK) or what lies behind it matters (BLEND).
    pub fn is_transparent(&self) -> bool {
        self.alpha != AlphaMode::Opaque
    }
}

/// A normal map: its texture and the `scale` of its tangent-space X and Y.
#[derive(Clone, Copy, Debug)]
pub struct NormalMap {
    pub texture: TextureRef,
    pub scale: f32,
}

#[derive(Clone, Copy, Debug)]
pub struct TextureRef {
    /// Index into `Scene::textures`.
    pub texture: usize,
    /// Which TEXCOORD_n set the texture reads (KHR_texture_transform's `texCoord` applied).
    pub tex_coord: usize,
    pub transform: Option<UvTransform>,
}

impl TextureRef {
    /// The texture coordinates this slot samples at, from a hit's two interpolated sets.
    #[inline]
    pub fn uv(&self, sets: &[Vec2; 2]) -> Vec2 {
        let uv = sets[self.tex_coord];
        match &self.transform {
            Some(t) => t.apply(uv),
            None => uv,
        }
    }
}

/// KHR_texture_transform as two rows of the affine map `T * R * S` on `(u, v, 1)`: scale first,
/// then rotation, then offset, with +rotation turning +u toward -v (the extension's text, which
/// Blender, three.js and the Khronos sample model follow; WHITTED-materials.md section 5).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvTransform {
    pub u: Vec3,
    pub v: Vec3,
}

impl UvTransform {
    pub fn new(offset: [f32; 2], rotation: f32, scale: [f32; 2]) -> UvTransform {
        let (sin, cos) = rotation.sin_cos();
        UvTransform {
            u: Vec3::new(cos * scale[0], sin * scale[1], offset[0]),
            v: Vec3::new(-sin * scale[0], cos * scale[1], offset[1]),
        }
    }

    #[inline]
    pub fn apply(&self, uv: Vec2) -> Vec2 {
        let p = uv.extend(1.0);
        Vec2::new(self.u.dot(p), self.v.dot(p))
    }
}

/// What loading a document's materials gathers: each (texture, encoding) a slot samples gets
/// one entry of the decoded list, in the order first named.
struct Loader<'a> {
    file: &'a Path,
    decoded: BTreeMap<(usize, Encoding), usize>,
    order: Vec<(usize, Encoding)>,
}

impl Loader<'_> {
    /// A slot's texture reference, its texture coordinate set and transform checked.
    fn slot(
        &mut self,
        object: &str,
        info: (gltf::Texture, u32),
        transform: Option<gltf::texture::TextureTransform>,
        encoding: Encoding,
    ) -> Result<TextureRef> {
        let (texture, tex_coord) = info;
        let mut tex_coord = tex_coord;
        let transform = match transform {
            Some(t) => {
                let at = format!("{object}.extensions.KHR_texture_transform");
                let (offset, rotation, scale) = (t.offset(), t.rotation(), t.scale());
                if !offset
                    .iter()
                    .chain(&scale)
                    .chain([&rotation])
                    .all(|v| v.is_finite())
                {
                    return Err(Error::scene(
                        self.file,
                        at,
                        format!(
                            "offset, rotation and scale must be finite, got offset {offset:?}, \
                             rotation {rotation}, scale {scale:?}"
                        ),
                    ));
                }
                if let Some(set) = t.tex_coord() {
                    tex_coord = set;
                }
                Some(UvTransform::new(offset, rotation, scale))
            }
            None => None,
        };
        if tex_coord > 1 {
            return Err(Error::scene(
                self.file,
                object,
                format!("texCoord {tex_coord} is not supported (only TEXCOORD_0 and TEXCOORD_1)"),
            ));
        }
        let key = (texture.index(), encoding);
        let next = self.order.len();
        let index = *self.decoded.entry(key).or_insert(next);
        if index == next {
            self.order.push(key);
        }
        Ok(TextureRef {
            texture: index,
            tex_coord: tex_coord as usize,
            transform,
        })
    }

    fn material(&mut self, m: &gltf::Material) -> Result<Material> {
        let mut unused = Vec::new();
        let index = m.index().unwrap_or(0);
        let at = |key: &str| format!("materials[{index}].{key}");
        let pbr = m.pbr_metallic_roughness();
        let mut info_slot = |key: &str, info: Option<gltf::texture::Info>, encoding| {
            info.map(|i| {
                let texture = (i.texture(), i.tex_coord());
                self.slot(&at(key), texture, i.texture_transform(), encoding)
            })
            .transpose()
        };
        let base_color_texture = info_slot(
            "pbrMetallicRoughness.baseColorTexture",
            pbr.base_color_texture(),
            Encoding::Srgb,
        )?;
        let metallic_roughness_texture = info_slot(
            "pbrMetallicRoughness.metallicRoughnessTexture",
            pbr.metallic_roughness_texture(),
            Encoding::Linear,
        )?;
        let emissive_texture = info_slot("emissiveTexture", m.emissive_texture(), Encoding::Srgb)?;
        let normal_texture = match m.normal_texture() {
            Some(n) => {
                let scale = n.scale();
                if !scale.is_finite() {
                    return Err(Error::scene(
                        self.file,
                        at("normalTexture.scale"),
                        format!("must be a finite number, got {scale}"),
                    ));
                }
                // The gltf crate reads no KHR_texture_transform on a normal texture; one there
                // would also have to turn the tangent frame (WHITTED-materials.md: not covered).
                let texture = self.slot(
                    &at("normalTexture"),
                    (n.texture(), n.tex_coord()),
                    None,
                    Encoding::Linear,
                )?;
                Some(NormalMap { texture, scale })
            }
            None => None,
        };
        if m.occlusion_texture().is_some() {
            unused.push(OCCLUSION_UNUSED);
        }
        let transmission = m.transmission();
        if transmission
            .as_ref()
            .is_some_and(|t| t.transmission_texture().is_some())
        {
            unused.push(TRANSMISSION_TEXTURE_UNUSED);
        }
        let bc = pbr.base_color_factor();
        // The schema's ranges: no factor may give infinite, NaN or negative radiance.
        let in_unit = |key: &str, values: &[f32]| {
            if values.iter().all(|v| (0.0..=1.0).contains(v)) {
                Ok(())
            } else {
                Err(Error::scene(
                    self.file,
                    at(key),
                    format!("must be numbers in [0, 1], got {values:?}"),
                ))
            }
        };
        in_unit("pbrMetallicRoughness.baseColorFactor", &bc)?;
        in_unit("emissiveFactor", &m.emissive_factor())?;
        in_unit(
            "pbrMetallicRoughness.metallicFactor",
            &[pbr.metallic_factor()],
        )?;
        in_unit(
            "pbrMetallicRoughness.roughnessFactor",
            &[pbr.roughness_factor()],
        )?;
        if let Some(t) = &transmission {
            in_unit(
                "extensions.KHR_materials_transmission.transmissionFactor",
                &[t.transmission_factor()],
            )?;
        }
        if let Some(ior) = m.ior()
            && !(ior.is_finite() && ior > 0.0)
        {
            return Err(Error::scene(
                self.file,
                at("extensions.KHR_materials_ior.ior"),
                format!("must be a finite number > 0, got {ior}"),
            ));
        }
        let strength = m.emissive_strength().unwrap_or(1.0);
        if !(strength.is_finite() && strength >= 0.0) {
            return Err(Error::scene(
                self.file,
                at("extensions.KHR_materials_emissive_strength.emissiveStrength"),
                format!("must be a finite number >= 0, got {strength}"),
            ));
        }
        let mut alpha = match m.alpha_mode() {
            gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
            gltf::material::AlphaMode::Blend => AlphaMode::Blend,
            gltf::material::AlphaMode::Mask => {
                let cutoff = m.alpha_cutoff().unwrap_or(0.5);
                if !(cutoff.is_finite() && cutoff >= 0.0) {
                    return Err(Error::scene(
                        self.file,
                        at("alphaCutoff"),
                        format!("must be a finite number >= 0, got {cutoff}"),
                    ));
                }
                AlphaMode::Mask { cutoff }
            }
        };
        let transmission = transmission.map_or(0.0, |t| t.transmission_factor());
        // A smooth dielectric already passes light by refraction; coverage on top of it is
        // outside the convention (WHITTED-materials.md section 1), and a hit would spawn
        // three rays.
        if alpha != AlphaMode::Opaque && transmission >= 0.5 {
            unused.push(GLASS_ALPHA_UNUSED);
            alpha = AlphaMode::Opaque;
        }
        Ok(Material {
            name: m.name().map(str::to_owned),
            base_color: Vec4::from(bc),
            base_color_texture,
            metallic: pbr.metallic_factor(),
            roughness: pbr.roughness_factor(),
            metallic_roughness_texture,
            normal_texture,
            emissive: Vec3::from(m.emissive_factor()) * strength,
            emissive_texture,
            alpha,
            transmission,
            ior: m.ior().unwrap_or(1.5),
            double_sided: m.double_sided(),
            unused,
        })
    }
}

/// Materials of the document plus the default material at the end; the textures they sample,
/// decoded once per transfer function.
pub(super) fn load_materials(
    file: &Path,
    document: &gltf::Document,
    buffers: &[Vec<u8>],
    warnings: &mut Vec<String>,
) -> Result<(Vec<Material>, Vec<Texture>)> {
    let mut loader = Loader {
        file,
        decoded: BTreeMap::new(),
        order: Vec::new(),
    };
    let mut materials = document
        .materials()
        .map(|m| loader.material(&m))
        .collect::<Result<Vec<_>>>()?;
    materials.push(Material::default());
    let mut unused: Vec<&str> = materials.iter().flat_map(|m| m.unused.clone()).collect();
    unused.sort_unstable();
    unused.dedup();
    for what in unused {
        warnings.push(format!("{}: {what}", file.display()));
    }
    let textures: Vec<gltf::Texture> = document.textures().collect();
    let textures = loader
        .order
        .iter()
        .map(|&(t, encoding)| load_texture(file, buffers, &textures[t], encoding))
        .collect::<Result<_>>()?;
    Ok((materials, textures))
}

fn load_texture(
    file: &Path,
    buffers: &[Vec<u8>],
    t: &gltf::Texture,
    encoding: Encoding,
) -> Result<Texture> {
    let image = t.source();
    let object = format!("images[{}]", image.index());
    let bytes: Vec<u8> = match image.source() {
        gltf::image::Source::View { view, .. } => view_bytes(file, buffers, &view)?.to_vec(),
        gltf::image::Source::Uri { uri, .. } => read_uri(file, &object, uri)?,
    };
    let decoded = image::load_from_memory(&bytes)
        .map_err(|e| Error::scene(file, &object, format!("cannot decode image: {e}")))?;
    let (width, height) = (decoded.width() as usize, decoded.height() as usize);
    // Colour slots are sRGB-encoded per the glTF specification, alpha and the data slots are
    // linear (`Texels::decode`).
    let texels = Texels::decode(decoded, encoding);
    let sampler = t.sampler();
    let wrap = |w: gltf::texture::WrappingMode| match w {
        gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
        gltf::texture::WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
        gltf::texture::WrappingMode::ClampToEdge => Wrap::ClampToEdge,
    };
    Ok(Texture {
        source: t.index(),
        encoding,
        width,
        height,
        texels,
        wrap: [wrap(sampler.wrap_s()), wrap(sampler.wrap_t())],
        nearest: sampler.mag_filter() == Some(gltf::texture::MagFilter::Nearest),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texture_transform_scales_then_rotates_toward_minus_v_then_offsets() {
        // KHR_texture_transform's text: r = pi/2 turns (1, 0) to (0, -1).
        let quarter = UvTransform::new([0.0, 0.0], std::f32::consts::FRAC_PI_2, [1.0, 1.0]);
        assert!(quarter.apply(Vec2::X).distance(Vec2::new(0.0, -1.0)) < 1e-6);
        // Scale before rotation: (1, 0) scaled by 2 in u, turned, then offset.
        let t = UvTransform::new([0.25, -0.5], std::f32::consts::FRAC_PI_2, [2.0, 3.0]);
        assert!(t.apply(Vec2::X).distance(Vec2::new(0.25, -2.5)) < 1e-6);
        assert!(t.apply(Vec2::Y).distance(Vec2::new(3.25, -0.5)) < 1e-6);
    }
}
