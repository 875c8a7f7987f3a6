//! A scene at one instant, in world space: the triangles with their shading attributes, the lights
//! and the cameras where the node hierarchy puts them. This is what `accel/` and `render/` consume.

use super::Scene;
use super::light::Light;
use glam::{Mat3, Mat4, Vec2, Vec3, Vec4};

/// World-space triangle soup with per-vertex shading data.
#[derive(Clone, Debug, Default)]
pub struct Geometry {
    pub positions: Vec<Vec3>,
    /// Unit normals, or zero for vertices of primitives without normals (shade flat).
    pub normals: Vec<Vec3>,
    pub tex_coords: [Vec<Vec2>; 2],
    pub colors: Vec<Vec4>,
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

/// Local matrices as the file stores them (no animation applied).
pub fn rest_locals(scene: &Scene) -> Vec<Mat4> {
    scene.nodes.iter().map(|n| n.transform.matrix()).collect()
}

/// Places every mesh, light and camera of the scene with the given local node matrices.
pub fn pose(scene: &Scene, locals: &[Mat4]) -> PosedScene {
    let world = world_matrices(scene, locals);
    let mut out = PosedScene::default();
    for n in scene.traversal() {
        let node = &scene.nodes[n];
        let m = world[n];
        if let Some(mesh) = node.mesh {
            append_mesh(&mut out.geometry, scene, mesh, &m);
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

fn append_mesh(g: &mut Geometry, scene: &Scene, mesh: usize, m: &Mat4) {
    // Normals transform with the inverse transpose; a mirroring transform (negative determinant)
    // reverses the winding, so swap two indices to keep CCW meaning "front".
    let normal_matrix = Mat3::from_mat4(*m).inverse().transpose();
    let mirrored = m.determinant() < 0.0;
    for prim in &scene.meshes[mesh].primitives {
        let base = g.positions.len() as u32;
        g.positions
            .extend(prim.positions.iter().map(|&p| m.transform_point3(p)));
        match &prim.normals {
            Some(ns) => g
                .normals
                .extend(ns.iter().map(|&n| (normal_matrix * n).normalize_or_zero())),
            None => g
                .normals
                .extend(std::iter::repeat_n(Vec3::ZERO, prim.positions.len())),
        }
        for (set, uv) in prim.tex_coords.iter().enumerate() {
            match uv {
                Some(uv) => g.tex_coords[set].extend_from_slice(uv),
                None => {
                    g.tex_coords[set].extend(std::iter::repeat_n(Vec2::ZERO, prim.positions.len()))
                }
            }
        }
        match &prim.colors {
            Some(c) => g.colors.extend_from_slice(c),
            None => g
                .colors
                .extend(std::iter::repeat_n(Vec4::ONE, prim.positions.len())),
        }
        for t in &prim.triangles {
            let [a, b, c] = t.map(|i| i + base);
            g.triangles
                .push(if mirrored { [a, c, b] } else { [a, b, c] });
            g.triangle_materials.push(prim.material as u32);
        }
    }
}
