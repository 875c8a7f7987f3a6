//! Surface materials: the glTF metallic-roughness model (factors and the base-colour texture),
//! emission, KHR_materials_transmission and KHR_materials_ior. Textures are decoded here, and only
//! those some material samples: a scene pays for the images it uses.

use super::buffers::{read_uri, view_bytes};
use crate::error::{Error, Result};
use glam::{Vec2, Vec3, Vec4};
use std::collections::BTreeSet;
use std::path::Path;

#[derive(Clone, Debug)]
pub struct Material {
    pub name: Option<String>,
    /// Linear RGBA factor (alpha is read but the Whitted model ignores coverage).
    pub base_color: Vec4,
    pub base_color_texture: Option<TextureRef>,
    pub metallic: f32,
    pub roughness: f32,
    pub emissive: Vec3,
    /// KHR_materials_transmission factor; the integrator treats > 0.5 as a smooth dielectric.
    pub transmission: f32,
    /// KHR_materials_ior (glTF default 1.5).
    pub ior: f32,
    pub double_sided: bool,
}

impl Default for Material {
    /// glTF 2.0 section 3.9.6: the default material when a primitive names none.
    fn default() -> Self {
        Material {
            name: Some("default".into()),
            base_color: Vec4::ONE,
            base_color_texture: None,
            metallic: 1.0,
            roughness: 1.0,
            emissive: Vec3::ZERO,
            transmission: 0.0,
            ior: 1.5,
            double_sided: false,
        }
    }
}

#[derive(Clone, Copy, Debug)]
pub struct TextureRef {
    /// Index into `Scene::textures`.
    pub texture: usize,
    /// Which TEXCOORD_n set the texture reads.
    pub tex_coord: usize,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wrap {
    Repeat,
    MirroredRepeat,
    ClampToEdge,
}

/// A decoded texture: linear RGBA texels, top row first, and its sampler.
#[derive(Clone, Debug)]
pub struct Texture {
    pub width: usize,
    pub height: usize,
    pub texels: Vec<Vec4>,
    pub wrap: [Wrap; 2],
    pub nearest: bool,
}

impl Texture {
    /// Bilinear (or nearest) lookup with the sampler's wrap modes; glTF UV (0,0) is the top-left.
    pub fn sample(&self, uv: Vec2) -> Vec4 {
        let (w, h) = (self.width as f32, self.height as f32);
        let x = uv.x * w - 0.5;
        let y = uv.y * h - 0.5;
        if self.nearest {
            return self.texel((x + 0.5).floor() as i64, (y + 0.5).floor() as i64);
        }
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let top = self.texel(x0, y0).lerp(self.texel(x0 + 1, y0), fx);
        let bottom = self.texel(x0, y0 + 1).lerp(self.texel(x0 + 1, y0 + 1), fx);
        top.lerp(bottom, fy)
    }

    fn texel(&self, x: i64, y: i64) -> Vec4 {
        let x = wrap_index(x, self.width as i64, self.wrap[0]);
        let y = wrap_index(y, self.height as i64, self.wrap[1]);
        self.texels[y * self.width + x]
    }
}

fn wrap_index(i: i64, n: i64, wrap: Wrap) -> usize {
    let r = match wrap {
        Wrap::ClampToEdge => i.clamp(0, n - 1),
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::MirroredRepeat => {
            let period = i.rem_euclid(2 * n);
            if period < n {
                period
            } else {
                2 * n - 1 - period
            }
        }
    };
    r as usize
}

/// sRGB electro-optical transfer function (IEC 61966-2-1), for colour textures.
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Materials of the document plus the default material at the end; textures that materials use.
pub(super) fn load_materials(
    file: &Path,
    document: &gltf::Document,
    buffers: &[Vec<u8>],
    warnings: &mut Vec<String>,
) -> Result<(Vec<Material>, Vec<Option<Texture>>)> {
    let mut used_textures = BTreeSet::new();
    let mut ignored = BTreeSet::new();
    let mut materials = Vec::new();
    for m in document.materials() {
        let pbr = m.pbr_metallic_roughness();
        let base_color_texture = pbr.base_color_texture().map(|info| {
            used_textures.insert(info.texture().index());
            TextureRef {
                texture: info.texture().index(),
                tex_coord: info.tex_coord() as usize,
            }
        });
        if let Some(tr) = base_color_texture
            && tr.tex_coord > 1
        {
            return Err(Error::scene(
                file,
                format!(
                    "materials[{}].pbrMetallicRoughness.baseColorTexture",
                    m.index().unwrap_or(0)
                ),
                format!(
                    "texCoord {} is not supported (only TEXCOORD_0 and TEXCOORD_1)",
                    tr.tex_coord
                ),
            ));
        }
        if pbr.metallic_roughness_texture().is_some() {
            ignored.insert("metallicRoughnessTexture");
        }
        if m.normal_texture().is_some() {
            ignored.insert("normalTexture");
        }
        if m.occlusion_texture().is_some() {
            ignored.insert("occlusionTexture");
        }
        if m.emissive_texture().is_some() {
            ignored.insert("emissiveTexture");
        }
        let transmission = m.transmission();
        if transmission
            .as_ref()
            .is_some_and(|t| t.transmission_texture().is_some())
        {
            ignored.insert("transmissionTexture");
        }
        let bc = pbr.base_color_factor();
        let index = m.index().unwrap_or(0);
        // The schema's ranges: no factor may give infinite, NaN or negative radiance.
        let in_unit = |key: &str, values: &[f32]| {
            if values.iter().all(|v| (0.0..=1.0).contains(v)) {
                Ok(())
            } else {
                Err(Error::scene(
                    file,
                    format!("materials[{index}].{key}"),
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
                file,
                format!("materials[{index}].extensions.KHR_materials_ior.ior"),
                format!("must be a finite number > 0, got {ior}"),
            ));
        }
        materials.push(Material {
            name: m.name().map(str::to_owned),
            base_color: Vec4::from(bc),
            base_color_texture,
            metallic: pbr.metallic_factor().clamp(0.0, 1.0),
            roughness: pbr.roughness_factor().clamp(0.0, 1.0),
            emissive: Vec3::from(m.emissive_factor()),
            transmission: transmission.map_or(0.0, |t| t.transmission_factor()),
            ior: m.ior().unwrap_or(1.5),
            double_sided: m.double_sided(),
        });
    }
    materials.push(Material::default());
    if !ignored.is_empty() {
        let list: Vec<&str> = ignored.into_iter().collect();
        warnings.push(format!(
            "{}: material textures not used by the Whitted model, factors only: {}",
            file.display(),
            list.join(", ")
        ));
    }

    let mut textures: Vec<Option<Texture>> = vec![None; document.textures().len()];
    for t in document.textures() {
        if used_textures.contains(&t.index()) {
            textures[t.index()] = Some(load_texture(file, buffers, &t)?);
        }
    }
    Ok((materials, textures))
}

fn load_texture(file: &Path, buffers: &[Vec<u8>], t: &gltf::Texture) -> Result<Texture> {
    let image = t.source();
    let object = format!("images[{}]", image.index());
    let bytes: Vec<u8> = match image.source() {
        gltf::image::Source::View { view, .. } => view_bytes(file, buffers, &view)?.to_vec(),
        gltf::image::Source::Uri { uri, .. } => read_uri(file, &object, uri)?,
    };
    let decoded = image::load_from_memory(&bytes)
        .map_err(|e| Error::scene(file, &object, format!("cannot decode image: {e}")))?
        .to_rgba32f();
    let (width, height) = (decoded.width() as usize, decoded.height() as usize);
    // The image crate returns the stored (sRGB-encoded) values scaled to [0,1]; base colour textures
    // are sRGB per the glTF specification, alpha is linear.
    let texels = decoded
        .pixels()
        .map(|p| {
            Vec4::new(
                srgb_to_linear(p[0]),
                srgb_to_linear(p[1]),
                srgb_to_linear(p[2]),
                p[3],
            )
        })
        .collect();
    let sampler = t.sampler();
    let wrap = |w: gltf::texture::WrappingMode| match w {
        gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
        gltf::texture::WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
        gltf::texture::WrappingMode::ClampToEdge => Wrap::ClampToEdge,
    };
    Ok(Texture {
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
    fn wrap_modes_follow_the_opengl_definitions() {
        assert_eq!(wrap_index(-1, 4, Wrap::Repeat), 3);
        assert_eq!(wrap_index(5, 4, Wrap::Repeat), 1);
        assert_eq!(wrap_index(-1, 4, Wrap::ClampToEdge), 0);
        assert_eq!(wrap_index(9, 4, Wrap::ClampToEdge), 3);
        assert_eq!(wrap_index(4, 4, Wrap::MirroredRepeat), 3);
        assert_eq!(wrap_index(-1, 4, Wrap::MirroredRepeat), 0);
    }

    #[test]
    fn srgb_decode_matches_the_standard_at_its_knee_and_ends() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
        assert!((srgb_to_linear(0.5) - 0.214_041).abs() < 1e-5);
    }
}
