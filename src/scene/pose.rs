//! A scene at one instant, in world space: the triangles with their shading attributes, the lights
//! and the cameras where the node hierarchy puts them. This is what `accel/` and `render/` consume.

use super::animation::NodeOverrides;
use super::light::Light;
use super::{Scene, Transform};
use glam::{Mat3, Mat4, Vec2, Vec3, Vec4};

/// World-space triangle soup with per-vertex shading data.
#[derive(Clone, Debug, Default)]
pub struct Geometry {
    pub positions: Vec<Vec3>,
    /// Unit normals, or zero for vertices of primitives without normals (shade flat).
    pub normals: Vec<Vec3>,
    pub tex_coords: [Vec<Vec2>; 2],
    pub colors: Vec<Vec4>,
    /// World tangents (xyz unit, w the bitangent's sign) of normal-mapped primitives, zero for
    /// the other vertices; empty when no primitive of the scene is normal-mapped.
    pub tangents: Vec<Vec4>,
    pub triangles: Vec<[u32; 3]>,
    /// Material index per triangle.
    pub triangle_materials: Vec<u32>,
}

impl Geometry {
    pub fn triangle(&self, i: usize) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[i];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// Every triangle's three world-space vertices, in triangle order (what `accel/` builds on).
    pub fn triangle_list(&self) -> Vec<[Vec3; 3]> {
        (0..self.triangles.len())
            .map(|i| self.triangle(i))
            .collect()
    }

    /// Axis-aligned bounds of every vertex; `None` for an empty scene.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let first = *self.positions.first()?;
        Some(
            self.positions
                .iter()
                .fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p))),
        )
    }
}

#[derive(Clone, Debug)]
pub struct PosedCamera {
    pub node: usize,
    /// Index into `Scene::cameras`.
    pub camera: usize,
    /// Rigid world transform (scale removed: a camera's frame is orthonormal).
    pub world: Mat4,
}

#[derive(Clone, Debug, Default)]
pub struct PosedScene {
    pub geometry: Geometry,
    pub lights: Vec<Light>,
    /// Camera instances in scene traversal order.
    pub cameras: Vec<PosedCamera>,
    /// World matrix of every node at this instant.
    pub node_world: Vec<Mat4>,
}

/// World matrix of every node reachable from the roots, given each node's local matrix.
pub fn world_matrices(scene: &Scene, locals: &[Mat4]) -> Vec<Mat4> {
    let mut world = vec![Mat4::IDENTITY; scene.nodes.len()];
    let mut stack: Vec<(usize, Mat4)> = scene.roots.iter().map(|&r| (r, Mat4::IDENTITY)).collect();
    while let Some((n, parent)) = stack.pop() {
        world[n] = parent * locals[n];
        for &c in &scene.nodes[n].children {
            stack.push((c, world[n]));
        }
    }
    world
}

/// Local matrices with animated TRS parts applied (`overrides` empty: the rest pose). Animation
/// targets only TRS nodes; a node stored as a matrix keeps its matrix.
pub fn local_matrices(scene: &Scene, overrides: &[NodeOverrides]) -> Vec<Mat4> {
    scene
        .nodes
        .iter()
        .enumerate()
        .map(|(i, n)| match (n.transform, overrides.get(i)) {
            (
                Transform::Trs {
                    translation,
                    rotation,
                    scale,
                },
                Some(o),
            ) => Mat4::from_scale_rotation_translation(
                o.scale.unwrap_or(scale),
                o.rotation.unwrap_or(rotation),
                o.translation.unwrap_or(translation),
            ),
            (t, _) => t.matrix(),
        })
        .collect()
}

/// Places every mesh, light and camera of the scene; `overrides` (per node, from
/// `animation::sample`) may be empty for the rest pose.
pub fn pose(scene: &Scene, overrides: &[NodeOverrides]) -> PosedScene {
    let world = world_matrices(scene, &local_matrices(scene, overrides));
    let mut out = PosedScene {
        node_world: world.clone(),
        ..Default::default()
    };
    let tangents = scene
        .meshes
        .iter()
        .any(|m| m.primitives.iter().any(|p| p.tangents.is_some()));
    for n in scene.traversal() {
        let node = &scene.nodes[n];
        let m = world[n];
        if let Some(mesh) = node.mesh {
            // Morph weights: the animated channel, else node.weights, else mesh.weights, else 0.
            let weights = overrides
                .get(n)
                .and_then(|o| o.weights.clone())
                .or_else(|| node.weights.clone())
                .unwrap_or_else(|| scene.meshes[mesh].weights.clone());
            let skin = node.skin.map(|s| joint_matrices(scene, s, &world));
            append_mesh(
                &mut out.geometry,
                (scene, mesh, tangents),
                &m,
                &weights,
                skin.as_deref(),
            );
        }
        if let Some(l) = node.light {
            out.lights.push(Light::place(&scene.lights[l], &m));
        }
        if let Some(c) = node.camera {
            out.cameras.push(PosedCamera {
                node: n,
                camera: c,
                world: rigid(&m),
            });
        }
    }
    out
}

/// Per joint: the skinning matrix (joint world x inverse bind) and its normal matrix.
fn joint_matrices(scene: &Scene, skin: usize, world: &[Mat4]) -> Vec<(Mat4, Mat3)> {
    let s = &scene.skins[skin];
    s.joints
        .iter()
        .zip(&s.inverse_bind)
        .map(|(&j, ibm)| {
            let m = world[j] * *ibm;
            (m, Mat3::from_mat4(m).inverse().transpose())
        })
        .collect()
}

/// Rotation and translation of a matrix, with scale and shear removed (Gram-Schmidt on the axes).
fn rigid(m: &Mat4) -> Mat4 {
    let x = m.x_axis.truncate().normalize_or(Vec3::X);
    let y = (m.y_axis.truncate() - x * x.dot(m.y_axis.truncate())).normalize_or(Vec3::Y);
    let z = x.cross(y);
    Mat4::from_cols(
        x.extend(0.0),
        y.extend(0.0),
        z.extend(0.0),
        m.w_axis.truncate().extend(1.0),
    )
}

/// Appends mesh `mesh` of `scene` posed by `m` (or its skin's joints) to `g`, with tangents
/// when `tangents` says the scene keeps them.
fn append_mesh(
    g: &mut Geometry,
    (scene, mesh, tangents): (&Scene, usize, bool),
    m: &Mat4,
    weights: &[f32],
    skin: Option<&[(Mat4, Mat3)]>,
) {
    // Rigid meshes: normals transform with the inverse transpose, and a mirroring transform
    // (negative determinant) reverses the winding, so two indices swap to keep CCW as "front".
    let normal_matrix = Mat3::from_mat4(*m).inverse().transpose();
    let mirrored = skin.is_none() && m.determinant() < 0.0;
    for prim in &scene.meshes[mesh].primitives {
        let base = g.positions.len() as u32;
        let count = prim.positions.len();
        // Morph deltas first (DESIGN.md: before skinning).
        let mut positions = prim.positions.clone();
        let mut normals = prim.normals.clone();
        let mut prim_tangents = prim.tangents.clone();
        for (target, &w) in prim.morph_targets.iter().zip(weights) {
            if w == 0.0 {
                continue;
            }
            if let Some(d) = &target.positions {
                positions.iter_mut().zip(d).for_each(|(p, d)| *p += w * *d);
            }
            if let (Some(ns), Some(d)) = (normals.as_mut(), &target.normals) {
                ns.iter_mut().zip(d).for_each(|(n, d)| *n += w * *d);
            }
            if let (Some(ts), Some(d)) = (prim_tangents.as_mut(), &target.tangents) {
                ts.iter_mut()
                    .zip(d)
                    .for_each(|(t, d)| *t += (w * *d).extend(0.0));
            }
        }
        // Tangents are surface directions: they follow the mesh's 3x3 (or each joint's),
        // not the normals' inverse transpose (WHITTED-materials.md section 1). A mirroring
        // transform flips the bitangent cross(N, T), so w flips with it.
        let tangent_of = |t: Vec4, m3: Mat3, w_sign: f32| {
            (m3 * t.truncate()).normalize_or_zero().extend(t.w * w_sign)
        };
        match (skin, prim.skin_sets.is_empty()) {
            (Some(joints), false) => {
                // Skinned: only the joints place the mesh (the mesh node's own transform is
                // ignored, glTF 2.0 section 3.7.3). Normals blend the per-joint normal matrices,
                // as the Khronos sample viewer does (DESIGN.md).
                for v in 0..count {
                    let (mut p, mut n) = (Vec3::ZERO, Vec3::ZERO);
                    for (js, ws) in &prim.skin_sets {
                        for k in 0..4 {
                            let w = ws[v][k];
                            if w == 0.0 {
                                continue;
                            }
                            let (jm, nm) = joints
                                .get(js[v][k] as usize)
                                .copied()
                                .unwrap_or((Mat4::IDENTITY, Mat3::IDENTITY));
                            p += w * jm.transform_point3(positions[v]);
                            if let Some(ns) = &normals {
                                n += w * (nm * ns[v]);
                            }
                        }
                    }
                    g.positions.push(p);
                    g.normals.push(n.normalize_or_zero());
                    if let Some(ts) = &prim_tangents {
                        let mut t = Vec3::ZERO;
                        for (js, ws) in &prim.skin_sets {
                            for k in 0..4 {
                                if let Some((jm, _)) = joints.get(js[v][k] as usize) {
                                    t += ws[v][k] * (Mat3::from_mat4(*jm) * ts[v].truncate());
                                }
                            }
                        }
                        g.tangents
                            .push(tangent_of(t.extend(ts[v].w), Mat3::IDENTITY, 1.0));
                    }
                }
            }
            _ => {
                g.positions
                    .extend(positions.iter().map(|&p| m.transform_point3(p)));
                match &normals {
                    Some(ns) => g
                        .normals
                        .extend(ns.iter().map(|&n| (normal_matrix * n).normalize_or_zero())),
                    None => g.normals.extend(std::iter::repeat_n(Vec3::ZERO, count)),
                }
                if let Some(ts) = &prim_tangents {
                    let m3 = Mat3::from_mat4(*m);
                    let w_sign = m3.determinant().signum();
                    g.tangents
                        .extend(ts.iter().map(|&t| tangent_of(t, m3, w_sign)));
                }
            }
        }
        if tangents && prim_tangents.is_none() {
            g.tangents.extend(std::iter::repeat_n(Vec4::ZERO, count));
        }
        for (set, uv) in prim.tex_coords.iter().enumerate() {
            match uv {
                Some(uv) => g.tex_coords[set].extend_from_slice(uv),
                None => g.tex_coords[set].extend(std::iter::repeat_n(Vec2::ZERO, count)),
            }
        }
        match &prim.colors {
            Some(c) => g.colors.extend_from_slice(c),
            None => g.colors.extend(std::iter::repeat_n(Vec4::ONE, count)),
        }
        for t in &prim.triangles {
            let [a, b, c] = t.map(|i| i + base);
            g.triangles
                .push(if mirrored { [a, c, b] } else { [a, b, c] });
            g.triangle_materials.push(prim.material as u32);
        }
    }
}
