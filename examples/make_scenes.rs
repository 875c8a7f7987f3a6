//! Writes the project's own scenes into `scenes/` as self-contained glTF 2.0 files (buffers and
//! images embedded as data URIs). Run `cargo run --example make_scenes` after changing it.
//!
//! `whitted_animated.gltf`: the same with the glass sphere moving (the default animation).
//! `whitted.gltf`: Whitted's 1980 set-up — a mirror sphere and a glass sphere over a red and
//! yellow checkered floor, two point lights, a sky-blue background (set by the pipeline).
//! `whitted_diffuse.gltf`: the same with the spheres made rough clay and plastic, the
//! diffuse-dominated scene on which `eye_reuse = "reproject"` is measured.

use base64::Engine;
use serde_json::{Value, json};
use std::f32::consts::PI;

/// Accumulates one binary buffer and the views/accessors into it.
#[derive(Default)]
struct Blob {
    bytes: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Blob {
    fn view(&mut self, data: &[u8], target: Option<u32>) -> usize {
        while !self.bytes.len().is_multiple_of(4) {
            self.bytes.push(0);
        }
        let mut v = json!({"buffer": 0, "byteOffset": self.bytes.len(), "byteLength": data.len()});
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        self.bytes.extend_from_slice(data);
        self.views.push(v);
        self.views.len() - 1
    }

    fn floats(&mut self, data: &[[f32; 3]], bounds: bool) -> usize {
        let raw: Vec<u8> = data
            .iter()
            .flatten()
            .flat_map(|f| f.to_le_bytes())
            .collect();
        let view = self.view(&raw, Some(34962));
        let mut a =
            json!({"bufferView": view, "componentType": 5126, "count": data.len(), "type": "VEC3"});
        if bounds {
            let mut lo = [f32::INFINITY; 3];
            let mut hi = [f32::NEG_INFINITY; 3];
            for p in data {
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
            a["min"] = json!(lo);
            a["max"] = json!(hi);
        }
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    fn uvs(&mut self, data: &[[f32; 2]]) -> usize {
        let raw: Vec<u8> = data
            .iter()
            .flatten()
            .flat_map(|f| f.to_le_bytes())
            .collect();
        let view = self.view(&raw, Some(34962));
        self.accessors.push(
            json!({"bufferView": view, "componentType": 5126, "count": data.len(), "type": "VEC2"}),
        );
        self.accessors.len() - 1
    }

    fn scalars(&mut self, data: &[f32]) -> usize {
        let raw: Vec<u8> = data.iter().flat_map(|f| f.to_le_bytes()).collect();
        let view = self.view(&raw, None);
        let (lo, hi) = data
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        self.accessors.push(json!({"bufferView": view, "componentType": 5126, "count": data.len(), "type": "SCALAR", "min": [lo], "max": [hi]}));
        self.accessors.len() - 1
    }

    fn indices(&mut self, data: &[[u32; 3]]) -> usize {
        let raw: Vec<u8> = data
            .iter()
            .flatten()
            .flat_map(|i| i.to_le_bytes())
            .collect();
        let view = self.view(&raw, Some(34963));
        self.accessors.push(
            json!({"bufferView": view, "componentType": 5125, "count": data.len() * 3, "type": "SCALAR"}),
        );
        self.accessors.len() - 1
    }
}

/// Positions, normals and index triples of a mesh.
type MeshData = (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<[u32; 3]>);

/// UV sphere with outward normals, counter-clockwise seen from outside.
fn sphere(radius: f32, n_lon: usize, n_lat: usize) -> MeshData {
    let (mut p, mut n, mut idx) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..=n_lat {
        let th = PI * i as f32 / n_lat as f32;
        for j in 0..=n_lon {
            let ph = 2.0 * PI * j as f32 / n_lon as f32;
            let d = [th.sin() * ph.cos(), th.cos(), -th.sin() * ph.sin()];
            n.push(d);
            p.push(d.map(|c| c * radius));
        }
    }
    let row = (n_lon + 1) as u32;
    for i in 0..n_lat as u32 {
        for j in 0..n_lon as u32 {
            let (a, b, c, d) = (
                i * row + j,
                (i + 1) * row + j,
                (i + 1) * row + j + 1,
                i * row + j + 1,
            );
            if i != 0 {
                idx.push([a, b, d]);
            }
            if i != n_lat as u32 - 1 {
                idx.push([b, c, d]);
            }
        }
    }
    (p, n, idx)
}

fn checker_png(a: [u8; 3], b: [u8; 3]) -> Vec<u8> {
    let mut img = image::RgbImage::new(2, 2);
    for (x, y, px) in img.enumerate_pixels_mut() {
        *px = image::Rgb(if (x + y) % 2 == 0 { a } else { b });
    }
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png)
        .expect("PNG encodes in memory");
    out.into_inner()
}

/// The Whitted scene; `animated` adds a 4-second animation in which the glass sphere glides
/// across the front of the mirror sphere and back (LINEAR translation keys).
fn whitted(animated: bool) -> Value {
    let mut blob = Blob::default();
    let mut meshes = Vec::new();
    let mut nodes = Vec::new();

    // Floor: a 40 m square with UVs repeating the 2x2 checker 20 times (1 m tiles).
    let half = 20.0;
    let fp = [
        [-half, 0.0, -half],
        [half, 0.0, -half],
        [half, 0.0, half],
        [-half, 0.0, half],
    ];
    let fn_ = [[0.0, 1.0, 0.0]; 4];
    let fuv = [[0.0, 0.0], [20.0, 0.0], [20.0, 20.0], [0.0, 20.0]];
    let fi = [[0u32, 2, 1], [0, 3, 2]];
    let (p, n, u, i) = (
        blob.floats(&fp, true),
        blob.floats(&fn_, false),
        blob.uvs(&fuv),
        blob.indices(&fi),
    );
    meshes.push(json!({"name": "floor", "primitives": [{"attributes": {"POSITION": p, "NORMAL": n, "TEXCOORD_0": u}, "indices": i, "material": 0, "mode": 4}]}));
    nodes.push(json!({"name": "floor", "mesh": 0}));

    let (sp, sn, si) = sphere(1.0, 64, 32);
    let (p, n, i) = (
        blob.floats(&sp, true),
        blob.floats(&sn, false),
        blob.indices(&si),
    );
    meshes.push(json!({"name": "mirror sphere", "primitives": [{"attributes": {"POSITION": p, "NORMAL": n}, "indices": i, "material": 1, "mode": 4}]}));
    meshes.push(json!({"name": "glass sphere", "primitives": [{"attributes": {"POSITION": p, "NORMAL": n}, "indices": i, "material": 2, "mode": 4}]}));
    // Whitted's arrangement: the mirror sphere behind, the glass sphere floating in front of it.
    nodes.push(json!({"name": "mirror sphere", "mesh": 1, "translation": [-0.7, 1.0, -1.6]}));
    nodes.push(json!({"name": "glass sphere", "mesh": 2, "translation": [0.55, 1.05, 0.3], "scale": [0.6, 0.6, 0.6]}));

    // 4.6 m back, 1.7 m up, pitched down 12 degrees.
    let half_pitch = -12f32.to_radians() * 0.5;
    nodes.push(
        json!({"name": "Camera", "camera": 0, "translation": [0.0, 1.7, 4.6],
        "rotation": [half_pitch.sin(), 0.0, 0.0, half_pitch.cos()]}),
    );
    nodes.push(json!({"name": "key light", "translation": [2.5, 5.0, 3.0], "extensions": {"KHR_lights_punctual": {"light": 0}}}));
    nodes.push(json!({"name": "fill light", "translation": [-4.0, 3.0, 1.0], "extensions": {"KHR_lights_punctual": {"light": 1}}}));

    let png = checker_png([200, 40, 30], [235, 200, 40]);
    let image_view = blob.view(&png, None);
    let mut animations = Vec::new();
    if animated {
        let times = blob.scalars(&[0.0, 1.0, 2.0, 3.0, 4.0]);
        let path = blob.floats(
            &[
                [0.55, 1.05, 0.3],
                [-1.2, 1.3, 0.6],
                [-0.3, 0.8, 1.4],
                [1.3, 1.2, 0.9],
                [0.55, 1.05, 0.3],
            ],
            false,
        );
        animations.push(json!({"name": "glide", "samplers": [{"input": times, "output": path, "interpolation": "LINEAR"}],
            "channels": [{"sampler": 0, "target": {"node": 2, "path": "translation"}}]}));
    }
    let data = base64::engine::general_purpose::STANDARD.encode(&blob.bytes);
    let mut scene = json!({
        "asset": {"version": "2.0", "generator": "stereotrace examples/make_scenes.rs"},
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_transmission", "KHR_materials_ior"],
        "scene": 0,
        "scenes": [{"name": "whitted", "nodes": (0..nodes.len()).collect::<Vec<_>>()}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": [
            {"name": "checker", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0, "roughnessFactor": 0.9}},
            {"name": "mirror", "pbrMetallicRoughness": {"baseColorFactor": [0.95, 0.95, 0.95, 1.0], "metallicFactor": 1.0, "roughnessFactor": 0.0}},
            {"name": "glass", "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.0},
             "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0}, "KHR_materials_ior": {"ior": 1.5}}}
        ],
        "textures": [{"sampler": 0, "source": 0}],
        "samplers": [{"magFilter": 9728, "minFilter": 9728, "wrapS": 10497, "wrapT": 10497}],
        "images": [{"bufferView": image_view, "mimeType": "image/png"}],
        "cameras": [{"name": "Camera", "type": "perspective", "perspective": {"yfov": 0.75, "aspectRatio": 16.0 / 9.0, "znear": 0.05}}],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"name": "key", "type": "point", "color": [1.0, 0.97, 0.9], "intensity": 45.0},
            {"name": "fill", "type": "point", "color": [0.8, 0.85, 1.0], "intensity": 12.0}
        ]}},
        "accessors": blob.accessors,
        "bufferViews": blob.views,
        "buffers": [{"byteLength": blob.bytes.len(), "uri": format!("data:application/octet-stream;base64,{data}")}]
    });
    if animated {
        scene["animations"] = json!(animations);
    }
    scene
}

/// The Whitted scene with its mirror and glass spheres replaced by rough, opaque ones (no
/// mirror or refraction rays: every pixel is emission and direct light).
fn whitted_diffuse() -> Value {
    let mut scene = whitted(false);
    scene["materials"][1] = json!({"name": "clay", "pbrMetallicRoughness": {"baseColorFactor": [0.85, 0.35, 0.25, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.7}});
    scene["materials"][2] = json!({"name": "plastic", "pbrMetallicRoughness": {"baseColorFactor": [0.3, 0.5, 0.9, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.5}});
    scene["extensionsUsed"] = json!(["KHR_lights_punctual"]);
    for (node, name) in [(1, "clay sphere"), (2, "plastic sphere")] {
        scene["nodes"][node]["name"] = json!(name);
    }
    scene
}

fn main() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    std::fs::create_dir_all(&dir).expect("scenes/ can be created");
    for (name, scene) in [
        ("whitted.gltf", whitted(false)),
        ("whitted_animated.gltf", whitted(true)),
        ("whitted_diffuse.gltf", whitted_diffuse()),
    ] {
        let path = dir.join(name);
        let text = serde_json::to_string_pretty(&scene).expect("scene serializes");
        std::fs::write(&path, text + "\n").expect("scene file can be written");
        println!("wrote {}", path.display());
    }
}
