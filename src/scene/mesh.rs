//! Triangle meshes as glTF stores them: object-space vertex attributes and index triples per
//! primitive. Strips and fans become lists here; points and lines are skipped with a warning
//! (a ray tracer has no width to give them).

use super::buffers::check_accessor;
use super::material::Material;
use crate::error::{Error, Result};
use glam::{Vec2, Vec3, Vec4};
use gltf::mesh::Mode;
use std::path::Path;

/// One glTF primitive, triangulated.
#[derive(Clone, Debug)]
pub struct Primitive {
    pub positions: Vec<Vec3>,
    /// Unit vertex normals; `None` when the file has none: shading then uses the flat geometric
    /// normal, which is what the glTF specification asks for ("flat normals").
    pub normals: Option<Vec<Vec3>>,
    /// TEXCOORD_0 and TEXCOORD_1 (zero when absent).
    pub tex_coords: [Option<Vec<Vec2>>; 2],
    /// COLOR_0 as linear RGBA (multiplies the base colour and the coverage, per the
    /// specification).
    pub colors: Option<Vec<Vec4>>,
    /// Tangents (xyz unit, w = +-1 the bitangent's sign), only where the material has a normal
    /// map: TANGENT as stored, else MikkTSpace on the normal map's texture coordinates.
    pub tangents: Option<Vec<Vec4>>,
    pub triangles: Vec<[u32; 3]>,
    /// Index into `Scene::materials` (the last entry is the default material).
    pub material: usize,
    /// Morph targets: position and normal deltas.
    pub morph_targets: Vec<MorphTarget>,
    /// Skinning influences: every JOINTS_n / WEIGHTS_n set, as stored.
    pub skin_sets: Vec<SkinSet>,
}

/// One JOINTS_n / WEIGHTS_n pair: per vertex, four joint indices and their weights.
pub type SkinSet = (Vec<[u16; 4]>, Vec<[f32; 4]>);

#[derive(Clone, Debug, Default)]
pub struct MorphTarget {
    pub positions: Option<Vec<Vec3>>,
    pub normals: Option<Vec<Vec3>>,
    /// Read only for primitives whose tangents are kept.
    pub tangents: Option<Vec<Vec3>>,
}

#[derive(Clone, Debug)]
pub struct Mesh {
    pub name: Option<String>,
    pub primitives: Vec<Primitive>,
    /// `mesh.weights`: default morph weights.
    pub weights: Vec<f32>,
}

impl Mesh {
    pub fn triangle_count(&self) -> usize {
        self.primitives.iter().map(|p| p.triangles.len()).sum()
    }
}

pub(super) fn load_mesh(
    file: &Path,
    buffers: &[Vec<u8>],
    mesh: &gltf::Mesh,
    materials: &[Material],
    warnings: &mut Vec<String>,
) -> Result<Mesh> {
    let mut primitives = Vec::new();
    for prim in mesh.primitives() {
        let object = format!("meshes[{}].primitives[{}]", mesh.index(), prim.index());
        if matches!(
            prim.mode(),
            Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip
        ) {
            warnings.push(format!(
                "{}: {object}: mode {:?} has no surface to ray trace; skipped",
                file.display(),
                prim.mode()
            ));
            continue;
        }
        primitives.push(load_primitive(file, buffers, &prim, &object, materials)?);
    }
    Ok(Mesh {
        name: mesh.name().map(str::to_owned),
        primitives,
        weights: mesh.weights().map(<[f32]>::to_vec).unwrap_or_default(),
    })
}

fn load_primitive(
    file: &Path,
    buffers: &[Vec<u8>],
    prim: &gltf::Primitive,
    object: &str,
    materials: &[Material],
) -> Result<Primitive> {
    for (semantic, accessor) in prim.attributes() {
        check_accessor(
            file,
            buffers,
            &accessor,
            &format!("{object}.attributes.{}", semantic.to_string()),
        )?;
    }
    if let Some(indices) = prim.indices() {
        check_accessor(file, buffers, &indices, &format!("{object}.indices"))?;
    }
    let reader = prim.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
    let positions: Vec<Vec3> = reader
        .read_positions()
        .ok_or_else(|| Error::scene(file, object, "has no POSITION attribute"))?
        .map(Vec3::from)
        .collect();
    let n = positions.len();
    check_finite(file, &format!("{object}.attributes.POSITION"), &positions)?;

    let normals = match reader.read_normals() {
        Some(it) => {
            let normals: Vec<Vec3> = it.map(Vec3::from).collect();
            check_count(
                file,
                &format!("{object}.attributes.NORMAL"),
                normals.len(),
                n,
            )?;
            check_finite(file, &format!("{object}.attributes.NORMAL"), &normals)?;
            Some(normals.iter().map(|v| v.normalize_or_zero()).collect())
        }
        None => None,
    };
    let mut tex_coords: [Option<Vec<Vec2>>; 2] = [None, None];
    for (set, slot) in tex_coords.iter_mut().enumerate() {
        if let Some(it) = reader.read_tex_coords(set as u32) {
            let uv: Vec<Vec2> = it.into_f32().map(Vec2::from).collect();
            let attribute = format!("{object}.attributes.TEXCOORD_{set}");
            check_count(file, &attribute, uv.len(), n)?;
            check_finite(file, &attribute, &uv)?;
            *slot = Some(uv);
        }
    }
    let colors = match reader.read_colors(0) {
        Some(it) => {
            let c: Vec<Vec4> = it.into_rgba_f32().map(Vec4::from).collect();
            let attribute = format!("{object}.attributes.COLOR_0");
            check_count(file, &attribute, c.len(), n)?;
            // The glTF specification's range for colours; outside it radiance would turn
            // negative or infinite.
            if let Some(i) = c
                .iter()
                .position(|v| !(v.cmpge(Vec4::ZERO).all() && v.cmple(Vec4::ONE).all()))
            {
                return Err(Error::scene(
                    file,
                    attribute,
                    format!("element {i} is outside [0, 1] ({:?})", c[i]),
                ));
            }
            Some(c)
        }
        None => None,
    };
    let indices: Vec<u32> = match reader.read_indices() {
        Some(it) => it.into_u32().collect(),
        None => (0..n as u32).collect(),
    };
    if let Some(bad) = indices.iter().position(|&i| i as usize >= n) {
        return Err(Error::scene(
            file,
            format!("{object}.indices"),
            format!(
                "index {} at position {bad} is out of range: the primitive has {n} vertices",
                indices[bad]
            ),
        ));
    }
    let triangles = triangulate(prim.mode(), &indices);

    // The default material is the last one (`load_materials`).
    let material = prim.material().index().unwrap_or(materials.len() - 1);
    let tangents = match &materials[material].normal_texture {
        // A TANGENT no normal map uses is not read.
        None => None,
        Some(map) => {
            let set = map.texture.tex_coord;
            let Some(uv) = &tex_coords[set] else {
                return Err(Error::scene(
                    file,
                    format!("{object}.attributes"),
                    format!(
                        "materials[{material}].normalTexture reads TEXCOORD_{set}, which the \
                         primitive does not have"
                    ),
                ));
            };
            Some(match reader.read_tangents() {
                Some(it) => {
                    let t: Vec<Vec4> = it.map(Vec4::from).collect();
                    let attribute = format!("{object}.attributes.TANGENT");
                    check_count(file, &attribute, t.len(), n)?;
                    check_tangents(file, &attribute, &t)?;
                    t
                }
                None => generated_tangents(&positions, normals.as_deref(), uv, &triangles),
            })
        }
    };

    let mut morph_targets = Vec::new();
    for (t, (p, nrm, tan)) in reader.read_morph_targets().enumerate() {
        let positions: Option<Vec<Vec3>> = p.map(|it| it.map(Vec3::from).collect());
        let normals: Option<Vec<Vec3>> = nrm.map(|it| it.map(Vec3::from).collect());
        let tangent_deltas: Option<Vec<Vec3>> = tan
            .filter(|_| tangents.is_some())
            .map(|it| it.map(Vec3::from).collect());
        for (what, v) in [
            ("POSITION", &positions),
            ("NORMAL", &normals),
            ("TANGENT", &tangent_deltas),
        ] {
            if let Some(v) = v {
                let obj = format!("{object}.targets[{t}].{what}");
                check_count(file, &obj, v.len(), n)?;
                check_finite(file, &obj, v)?;
            }
        }
        morph_targets.push(MorphTarget {
            positions,
            normals,
            tangents: tangent_deltas,
        });
    }

    let mut skin_sets = Vec::new();
    for set in 0.. {
        let (Some(j), Some(w)) = (reader.read_joints(set), reader.read_weights(set)) else {
            break;
        };
        let joints: Vec<[u16; 4]> = j.into_u16().collect();
        let weights: Vec<[f32; 4]> = w.into_f32().collect();
        check_count(
            file,
            &format!("{object}.attributes.JOINTS_{set}"),
            joints.len(),
            n,
        )?;
        check_count(
            file,
            &format!("{object}.attributes.WEIGHTS_{set}"),
            weights.len(),
            n,
        )?;
        if let Some((v, w)) = weights
            .iter()
            .enumerate()
            .find(|(_, w)| w.iter().any(|x| !(x.is_finite() && *x >= 0.0)))
        {
            return Err(Error::scene(
                file,
                format!("{object}.attributes.WEIGHTS_{set}"),
                format!("vertex {v} has weights {w:?}: weights must be finite and non-negative"),
            ));
        }
        skin_sets.push((joints, weights));
    }

    Ok(Primitive {
        positions,
        normals,
        tex_coords,
        colors,
        tangents,
        triangles,
        material,
        morph_targets,
        skin_sets,
    })
}

/// Index triples of a triangle list, strip or fan (glTF 2.0 section 3.7.2.1 gives the vertex order
/// of each so that every triangle keeps the primitive's winding).
fn triangulate(mode: Mode, idx: &[u32]) -> Vec<[u32; 3]> {
    match mode {
        Mode::TriangleStrip => (0..idx.len().saturating_sub(2))
            .map(|i| {
                if i % 2 == 0 {
                    [idx[i], idx[i + 1], idx[i + 2]]
                } else {
                    [idx[i + 1], idx[i], idx[i + 2]]
                }
            })
            .collect(),
        Mode::TriangleFan => (1..idx.len().saturating_sub(1))
            .map(|i| [idx[i], idx[i + 1], idx[0]])
            .collect(),
        _ => idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
    }
}

/// TANGENT as the glTF specification defines it: a finite, non-zero xyz and w = +1 or -1 (within
/// float rounding of a quantizing exporter).
fn check_tangents(file: &Path, object: &str, tangents: &[Vec4]) -> Result<()> {
    let bad = tangents.iter().position(|t| {
        !(t.is_finite() && t.truncate().length_squared() > 0.0 && (t.w.abs() - 1.0).abs() < 1e-3)
    });
    match bad {
        None => Ok(()),
        Some(i) => Err(Error::scene(
            file,
            object,
            format!(
                "element {i} is {:?}: a tangent needs a finite, non-zero xyz and w = +1 or -1",
                tangents[i]
            ),
        )),
    }
}

/// MikkTSpace tangents (what the glTF specification asks for when TANGENT is absent), per vertex.
/// MikkTSpace's bitangent follows +v, glTF's image up is -v: it is fed (u, 1 - v), so that its
/// w is glTF's (WHITTED-materials.md section 2). A vertex shared by triangles keeps the last
/// tangent written; MikkTSpace gives shared vertices one tangent except across mirrored UV
/// islands, where glTF exporters split vertices anyway. Without normals, the face normal stands in.
fn generated_tangents(
    positions: &[Vec3],
    normals: Option<&[Vec3]>,
    uv: &[Vec2],
    triangles: &[[u32; 3]],
) -> Vec<Vec4> {
    struct Mikk<'a> {
        positions: &'a [Vec3],
        normals: Option<&'a [Vec3]>,
        uv: &'a [Vec2],
        triangles: &'a [[u32; 3]],
        out: Vec<Vec4>,
    }
    impl Mikk<'_> {
        fn vertex(&self, face: usize, vert: usize) -> usize {
            self.triangles[face][vert] as usize
        }
    }
    impl bevy_mikktspace::Geometry for Mikk<'_> {
        fn num_faces(&self) -> usize {
            self.triangles.len()
        }
        fn num_vertices_of_face(&self, _: usize) -> usize {
            3
        }
        fn position(&self, face: usize, vert: usize) -> [f32; 3] {
            self.positions[self.vertex(face, vert)].to_array()
        }
        fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
            match self.normals {
                Some(n) => n[self.vertex(face, vert)].to_array(),
                None => {
                    let [a, b, c] = self.triangles[face].map(|i| self.positions[i as usize]);
                    (b - a).cross(c - a).normalize_or_zero().to_array()
                }
            }
        }
        fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
            let uv = self.uv[self.vertex(face, vert)];
            [uv.x, 1.0 - uv.y]
        }
        fn set_tangent(
            &mut self,
            tangent: Option<bevy_mikktspace::TangentSpace>,
            face: usize,
            vert: usize,
        ) {
            if let Some(t) = tangent {
                let v = self.vertex(face, vert);
                self.out[v] = Vec4::from(t.tangent_encoded());
            }
        }
    }
    let mut mikk = Mikk {
        positions,
        normals,
        uv,
        triangles,
        out: vec![Vec4::ZERO; positions.len()],
    };
    // Its error type has no variants: generation cannot fail, only leave vertices unset
    // (degenerate triangles), which keep a zero tangent and so their unperturbed normal.
    let _ = bevy_mikktspace::generate_tangents(&mut mikk);
    mikk.out
}

fn check_count(file: &Path, object: &str, got: usize, want: usize) -> Result<()> {
    if got == want {
        Ok(())
    } else {
        Err(Error::scene(
            file,
            object,
            format!("has {got} elements but POSITION has {want}"),
        ))
    }
}

fn check_finite<T: Finite + std::fmt::Debug>(
    file: &Path,
    object: &str,
    values: &[T],
) -> Result<()> {
    match values.iter().position(|v| !v.finite()) {
        None => Ok(()),
        Some(i) => Err(Error::scene(
            file,
            object,
            format!("element {i} is not finite ({:?})", values[i]),
        )),
    }
}

/// Vectors whose components can be checked for NaN and infinity.
trait Finite {
    fn finite(&self) -> bool;
}

impl Finite for Vec3 {
    fn finite(&self) -> bool {
        self.is_finite()
    }
}

impl Finite for Vec2 {
    fn finite(&self) -> bool {
        self.is_finite()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generated_tangents_follow_u_with_the_bitangent_toward_image_up() {
        // WHITTED-materials.md section 2: a quad in the XZ plane, normal +Y, u along +X and v
        // along +Z gets T = +X and w = +1 (B = cross(N, T) * w = -Z, decreasing v).
        let positions = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(0.0, 0.0, 1.0),
        ];
        let normals = [Vec3::Y; 4];
        let uv = [
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.0, 1.0),
        ];
        // Counter-clockwise seen from +Y.
        let triangles = [[0, 2, 1], [0, 3, 2]];
        for t in generated_tangents(&positions, Some(&normals), &uv, &triangles) {
            assert!(t.truncate().distance(Vec3::X) < 1e-5, "{t}");
            assert_eq!(t.w, 1.0);
        }
        // The UVs mirrored in u: the tangent turns to -X and the handedness flips.
        let mirrored = uv.map(|p| Vec2::new(1.0 - p.x, p.y));
        for t in generated_tangents(&positions, Some(&normals), &mirrored, &triangles) {
            assert!(t.truncate().distance(-Vec3::X) < 1e-5, "{t}");
            assert_eq!(t.w, -1.0);
        }
    }

    #[test]
    fn strips_and_fans_keep_the_winding_of_their_first_triangle() {
        assert_eq!(
            triangulate(Mode::TriangleStrip, &[0, 1, 2, 3, 4]),
            vec![[0, 1, 2], [2, 1, 3], [2, 3, 4]]
        );
        assert_eq!(
            triangulate(Mode::TriangleFan, &[0, 1, 2, 3]),
            vec![[1, 2, 0], [2, 3, 0]]
        );
        assert_eq!(triangulate(Mode::Triangles, &[0, 1, 2, 3]), vec![[0, 1, 2]]);
    }
}
