//! What a hit's surface is, as shading sees it: the hit point, its normals turned to the viewer,
//! its texture coordinates and vertex colour (`Shading`), and the material's values there from
//! factors, textures and COLOR_0, with the normal map's shading normal (`Surface`;
//! WHITTED-materials.md sections 1 to 3). Rays, lights and recursion belong to the integrator.

use super::shading::SurfacePoint;
use crate::accel::{Hit, Intersect, Ray};
use crate::scene::light::Light;
use crate::scene::material::{AlphaMode, Material, NormalMap, TextureRef};
use crate::scene::pose::Geometry;
use crate::scene::texture::Texture;
use glam::{Vec2, Vec3, Vec4};

/// What the integrator reads of a posed frame.
pub struct SceneView<'a, A: Intersect> {
    pub accel: &'a A,
    pub geometry: &'a Geometry,
    pub materials: &'a [Material],
    pub textures: &'a [Texture],
    pub lights: &'a [Light],
}

/// The least `dot(n, v)` a normal-mapped shading normal keeps (WHITTED-materials.md section 3,
/// the facing clamp): bumps tilted away from the viewer still get light and a mirror direction.
const FACING_MIN: f32 = 0.01;

/// Geometry of a hit, with normals flipped to the side the ray came from.
pub(super) struct Shading {
    pub(super) p: Vec3,
    /// Shading normal on the viewer's side.
    pub(super) n: Vec3,
    /// Geometric normal on the viewer's side.
    pub(super) ng: Vec3,
    /// The ray arrived on the front (counter-clockwise) face.
    pub(super) front: bool,
    pub(super) uv: [Vec2; 2],
    /// COLOR_0 (RGB tint and alpha coverage).
    pub(super) color: Vec4,
    pub(super) material: u32,
    /// The triangle's vertices and the hit's barycentrics (b0, b1, b2), for the tangents.
    pub(super) vertices: [usize; 3],
    pub(super) barycentric: Vec3,
}

/// A hit's surface, as shading sees it.
pub(super) struct Surface<'m> {
    pub(super) sh: Shading,
    pub(super) mat: &'m Material,
    pub(super) point: SurfacePoint,
    /// Emitted radiance (factor, texture and strength).
    pub(super) emissive: Vec3,
    /// Coverage of a BLEND surface (1 for every other).
    pub(super) alpha: f32,
    /// Direction to the viewer.
    pub(super) v: Vec3,
    pub(super) glass: bool,
    /// The shading normal comes from a normal map: rays it would send below the surface are
    /// dropped (WHITTED-materials.md section 3).
    pub(super) mapped: bool,
}

impl<A: Intersect> SceneView<'_, A> {
    /// The hit's shading point when the hit is on a MASK surface where its coverage is below
    /// the cutoff (a hit no ray sees), else `None`.
    pub(super) fn cut_out(&self, ray: &Ray, hit: &Hit) -> Option<Shading> {
        let material = self.geometry.triangle_materials[hit.prim as usize];
        let mat = &self.materials[material as usize];
        let AlphaMode::Mask { cutoff } = mat.alpha else {
            return None;
        };
        let sh = self.shading_point(ray, hit);
        (self.base_color(mat, &sh).w < cutoff).then_some(sh)
    }

    /// The material's values at a hit (WHITTED-materials.md section 1): base colour, roughness
    /// and metalness, emission and coverage from factors, textures and COLOR_0; the shading
    /// normal from the normal map.
    #[inline]
    pub(super) fn surface(&self, ray: &Ray, hit: &Hit) -> Surface<'_> {
        let mut sh = self.shading_point(ray, hit);
        let mat = &self.materials[sh.material as usize];
        let v = -ray.dir;
        let base = self.base_color(mat, &sh);
        let (mut metallic, mut roughness) = (mat.metallic, mat.roughness);
        if let Some(t) = self.texel(&mat.metallic_roughness_texture, &sh) {
            roughness *= t.y;
            metallic *= t.z;
        }
        let mut emissive = mat.emissive;
        if let Some(t) = self.texel(&mat.emissive_texture, &sh) {
            emissive *= t.truncate();
        }
        if let Some(map) = &mat.normal_texture {
            self.map_normal(map, &mut sh, v);
        }
        Surface {
            sh,
            mat,
            point: SurfacePoint {
                base_color: base.truncate(),
                metallic,
                roughness,
            },
            emissive,
            alpha: if mat.alpha == AlphaMode::Blend {
                base.w
            } else {
                1.0
            },
            v,
            glass: mat.transmission >= 0.5,
            mapped: mat.normal_texture.is_some(),
        }
    }

    /// A texture slot's value at a shading point (`None`: the material has no texture there).
    #[inline]
    pub(super) fn texel(&self, slot: &Option<TextureRef>, sh: &Shading) -> Option<Vec4> {
        let slot = slot.as_ref()?;
        Some(self.textures[slot.texture].sample(slot.uv(&sh.uv)))
    }

    /// The normal map's normal in the interpolated tangent frame (WHITTED-materials.md section
    /// 2), turned to the viewer's side and clamped to face it (section 3). A vertex without a
    /// tangent (a degenerate UV triangle) keeps the interpolated normal.
    pub(super) fn map_normal(&self, map: &NormalMap, sh: &mut Shading, v: Vec3) {
        let side = if sh.front { 1.0 } else { -1.0 };
        let n = sh.n * side;
        let g = self.geometry;
        let [i0, i1, i2] = sh.vertices;
        let b = sh.barycentric;
        let (Some(t0), Some(t1), Some(t2)) =
            (g.tangents.get(i0), g.tangents.get(i1), g.tangents.get(i2))
        else {
            return;
        };
        let interp = t0.truncate() * b.x + t1.truncate() * b.y + t2.truncate() * b.z;
        let t = (interp - n * n.dot(interp)).normalize_or_zero();
        let mapped = if t == Vec3::ZERO {
            n
        } else {
            let bitangent = n.cross(t) * t0.w;
            let c = self.textures[map.texture.texture].sample(map.texture.uv(&sh.uv));
            let local = Vec3::new(
                (2.0 * c.x - 1.0) * map.scale,
                (2.0 * c.y - 1.0) * map.scale,
                2.0 * c.z - 1.0,
            );
            (local.x * t + local.y * bitangent + local.z * n).normalize_or(n)
        };
        let mut shading = mapped * side;
        let facing = shading.dot(v);
        if facing < FACING_MIN {
            shading = (shading + (FACING_MIN - facing) * v).normalize();
        }
        sh.n = shading;
    }

    #[inline]
    pub(super) fn shading_point(&self, ray: &Ray, hit: &Hit) -> Shading {
        let g = self.geometry;
        let [i0, i1, i2] = g.triangles[hit.prim as usize];
        let (i0, i1, i2) = (i0 as usize, i1 as usize, i2 as usize);
        // Every per-vertex array cut to the vertex count, and the three indices checked once
        // against it: the compiler then drops the fifteen bounds checks of the reads below
        // (callgrind, diffuse scene: 394 instructions a call before, 266 after).
        let n = g.positions.len();
        let (positions, normals, colors) = (&g.positions[..], &g.normals[..n], &g.colors[..n]);
        let (uv0, uv1) = (&g.tex_coords[0][..n], &g.tex_coords[1][..n]);
        assert!(
            i0.max(i1).max(i2) < n,
            "a triangle's vertex beyond the vertex arrays"
        );
        let (b1, b2) = (hit.b1, hit.b2);
        let b0 = 1.0 - b1 - b2;
        let (p0, p1, p2) = (positions[i0], positions[i1], positions[i2]);
        // The barycentric point is more accurate than origin + t * dir, which the offset relies on.
        let p = p0 * b0 + p1 * b1 + p2 * b2;
        let ng = (p1 - p0).cross(p2 - p0).normalize_or_zero();
        let interp = normals[i0] * b0 + normals[i1] * b1 + normals[i2] * b2;
        let ns = if interp.length_squared() > 1e-12 {
            interp.normalize()
        } else {
            ng
        };
        let front = ng.dot(-ray.dir) > 0.0;
        let s = if front { 1.0 } else { -1.0 };
        let uv = [
            uv0[i0] * b0 + uv0[i1] * b1 + uv0[i2] * b2,
            uv1[i0] * b0 + uv1[i1] * b1 + uv1[i2] * b2,
        ];
        let color = colors[i0] * b0 + colors[i1] * b1 + colors[i2] * b2;
        Shading {
            p,
            n: ns * s,
            ng: ng * s,
            front,
            uv,
            color,
            material: g.triangle_materials[hit.prim as usize],
            vertices: [i0, i1, i2],
            barycentric: Vec3::new(b0, b1, b2),
        }
    }

    /// Base colour (RGB) and coverage (A): factor x texture x COLOR_0.
    #[inline]
    pub(super) fn base_color(&self, mat: &Material, sh: &Shading) -> Vec4 {
        let mut c = mat.base_color * sh.color;
        if let Some(t) = self.texel(&mat.base_color_texture, sh) {
            c *= t;
        }
        c
    }
}
