//! `stereotrace info`'s material list: every input a material has and what the renderer does
//! with it (WHITTED-materials.md), so that a user sees at once whether an asset renders as made.

use crate::scene::Scene;
use crate::scene::material::{AlphaMode, Material, TextureRef};
use serde::Serialize;

#[derive(Debug, Serialize)]
pub struct MaterialInputs {
    pub index: usize,
    pub name: Option<String>,
    /// One line per input: what it is and what it becomes.
    pub inputs: Vec<String>,
}

/// The document's materials (not the default material that primitives without one get).
pub fn material_inputs(scene: &Scene) -> Vec<MaterialInputs> {
    let documented = scene.materials.len() - 1;
    scene.materials[..documented]
        .iter()
        .enumerate()
        .map(|(index, m)| MaterialInputs {
            index,
            name: m.name.clone(),
            inputs: describe(m),
        })
        .collect()
}

/// Where a slot reads: its texture coordinate set and transform.
fn slot(t: &TextureRef) -> String {
    match &t.transform {
        Some(_) => format!("TEXCOORD_{}, KHR_texture_transform", t.tex_coord),
        None => format!("TEXCOORD_{}", t.tex_coord),
    }
}

fn describe(m: &Material) -> Vec<String> {
    let mut out = Vec::new();
    let c = m.base_color;
    let mut base = format!("base colour ({:.3}, {:.3}, {:.3})", c.x, c.y, c.z);
    if let Some(t) = &m.base_color_texture {
        base += &format!(" x baseColorTexture ({}, sRGB)", slot(t));
    }
    out.push(base + " x COLOR_0 where the mesh has it");
    let mut mr = format!("metallic {:.3}, roughness {:.3}", m.metallic, m.roughness);
    if let Some(t) = &m.metallic_roughness_texture {
        mr += &format!(
            " x metallicRoughnessTexture ({}, linear: G roughness, B metalness)",
            slot(t)
        );
    }
    out.push(mr);
    if let Some(n) = &m.normal_texture {
        out.push(format!(
            "normalTexture ({}, scale {}): shading normal in the TANGENT frame (MikkTSpace where \
             the mesh has none), clamped to face the viewer",
            slot(&n.texture),
            n.scale
        ));
    }
    if m.emissive != glam::Vec3::ZERO || m.emissive_texture.is_some() {
        let e = m.emissive;
        let mut emissive = format!(
            "emission ({:.3}, {:.3}, {:.3}) (factor x KHR_materials_emissive_strength)",
            e.x, e.y, e.z
        );
        if let Some(t) = &m.emissive_texture {
            emissive += &format!(" x emissiveTexture ({}, sRGB)", slot(t));
        }
        out.push(emissive);
    }
    out.push(match m.alpha {
        AlphaMode::Opaque => "alpha OPAQUE: coverage ignored".to_string(),
        AlphaMode::Mask { cutoff } => format!(
            "alpha MASK {cutoff}: hits with coverage below it do not exist for any ray, shadow \
             rays included"
        ),
        AlphaMode::Blend => {
            "alpha BLEND: the surface over what lies behind it, shadows let 1 - coverage through"
                .to_string()
        }
    });
    if m.transmission >= 0.5 {
        out.push(format!(
            "transmission {}, ior {}: smooth dielectric (reflection and refraction)",
            m.transmission, m.ior
        ));
    }
    out.extend(m.unused.iter().map(|u| u.to_string()));
    out
}
