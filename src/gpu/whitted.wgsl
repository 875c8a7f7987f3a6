// The Whitted integrator of WHITTED.md section 4 on the GPU, after `render/integrator.rs`, with
// the parts and kd-tree walks of `parts.wgsl` and `walk.wgsl` (which the host puts before this
// file): one invocation per
// camera ray; emission, direct light from every punctual light through shadow rays, and the
// Fresnel-weighted mirror and refraction rays to `max_depth`, with the material inputs of
// WHITTED-materials.md (textures on every slot, normal maps, MASK cut-outs that no ray sees,
// BLEND surfaces over what lies behind). WGSL has no recursion, so the rays still to trace wait
// on a per-invocation stack with the weight their radiance gets.

struct Ray {
    origin: vec3<f32>,
    t_max: f32,
    dir: vec3<f32>,
    pad: f32,
}

struct Frame {
    first: u32,
    count: u32,
    // Rows of the part table.
    parts: u32,
    pad1: u32,
    background: vec3<f32>,
    max_depth: u32,
    // 0: Cook-Torrance (the glTF BRDF), 1: Phong.
    shading: u32,
    lights: u32,
    // Entries of `pending` per invocation.
    stride: u32,
    pad0: u32,
}

// A vertex: position, shading normal (zero: shade flat), two texture coordinate sets, colour
// with alpha, tangent with the bitangent's sign (zero: not normal-mapped).
struct Vertex {
    p: vec3<f32>,
    u0: f32,
    n: vec3<f32>,
    v0: f32,
    color: vec4<f32>,
    u1: f32,
    v1: f32,
    pad0: f32,
    pad1: f32,
    tangent: vec4<f32>,
}

// A texture slot: index into `textures` (or -1), its texture coordinate set, and the rows of its
// KHR_texture_transform (the identity without one).
struct Slot {
    u: vec3<f32>,
    texture: i32,
    v: vec3<f32>,
    tex_coord: u32,
}

struct Material {
    base_color: vec4<f32>,
    emissive: vec3<f32>,
    metallic: f32,
    roughness: f32,
    transmission: f32,
    ior: f32,
    // 0 opaque, 1 mask, 2 blend.
    alpha_mode: u32,
    alpha_cutoff: f32,
    normal_scale: f32,
    pad0: f32,
    pad1: f32,
    base_color_slot: Slot,
    metallic_roughness_slot: Slot,
    normal_slot: Slot,
    emissive_slot: Slot,
}

struct Light {
    position: vec3<f32>,
    // 0: directional, 1: point, 2: spot.
    kind: u32,
    direction: vec3<f32>,
    // 0: unlimited.
    range: f32,
    power: vec3<f32>,
    cos_outer: f32,
    cos_inner: f32,
    pad0: f32,
    pad1: f32,
    pad2: f32,
}

struct Texture {
    offset: u32,
    width: u32,
    height: u32,
    // Bits 0-1: wrap s, 2-3: wrap t (0 repeat, 1 mirrored repeat, 2 clamp); bit 4: nearest.
    flags: u32,
}

@group(0) @binding(3) var<storage, read> camera_rays: array<Ray>;
@group(0) @binding(4) var<storage, read_write> radiance: array<vec4<f32>>;
@group(0) @binding(5) var<uniform> frame: Frame;
@group(0) @binding(6) var<storage, read> vertices: array<Vertex>;
// Per triangle: its three vertex indices and its material.
@group(0) @binding(7) var<storage, read> triangles: array<vec4<u32>>;
@group(0) @binding(8) var<storage, read> materials: array<Material>;
@group(0) @binding(9) var<storage, read> lights: array<Light>;
@group(0) @binding(10) var<storage, read> textures: array<Texture>;
@group(0) @binding(11) var<storage, read> texels: array<vec4<f32>>;
// The rays each invocation still has to trace, `frame.stride` entries from `gid.x * stride`.
// In storage rather than a private array: a private array indexed at run time made Mesa's
// lavapipe spend minutes compiling the shader.
@group(0) @binding(12) var<storage, read_write> pending: array<Pending>;
// Per workgroup of camera rays: the secondary (mirror and refraction) and shadow rays traced,
// as the CPU's `RayCounts` counts them (summed on the host).
@group(0) @binding(16) var<storage, read_write> ray_counts: array<atomic<u32>>;

// Where the vertices, the triangles or the texels are larger than the adapter binds in one
// buffer, their second parts (else placeholders never read).
@group(0) @binding(20) var<storage, read> vertices_rest: array<Vertex>;
@group(0) @binding(21) var<storage, read> triangles_rest: array<vec4<u32>>;
@group(0) @binding(22) var<storage, read> texels_rest: array<vec4<f32>>;

fn vertex_at(i: u32) -> Vertex {
    let n = arrayLength(&vertices);
    if i < n {
        return vertices[i];
    }
    return vertices_rest[i - n];
}

fn face_at(i: u32) -> vec4<u32> {
    let n = arrayLength(&triangles);
    if i < n {
        return triangles[i];
    }
    return triangles_rest[i - n];
}

fn texel_at(i: u32) -> vec4<f32> {
    let n = arrayLength(&texels);
    if i < n {
        return texels[i];
    }
    return texels_rest[i - n];
}

var<private> shadow_rays: u32;
var<private> secondary: u32;

const PI: f32 = 3.14159265358979;
// Shadow rays stop this fraction short of the light (integrator.rs `SHADOW_EPSILON`).
const SHADOW_EPSILON: f32 = 1e-4;
// No limit: the largest f32 (WGSL has no infinity literal).
const FAR: f32 = 3.4028235e38;
// integrator.rs `FACING_MIN`: the least dot(n, v) of a normal-mapped shading normal.
const FACING_MIN: f32 = 0.01;
// integrator.rs `MAX_CROSSINGS`: cut-outs and BLEND surfaces one ray passes at most.
const MAX_CROSSINGS: u32 = 256u;
// The material inputs some material of the scene uses (`GpuFeatures`): the host compiles a
// kernel for each set a scene needs, so that a scene pays for no input it lacks. Opaque, untextured
// scenes run the kernel they ran before these inputs existed (a loop around the walk, even one
// that never turns, or texture lookups never taken, cost lavapipe a fifth of its speed).
// MASK or BLEND materials: hits test their coverage and shadow rays walk on.
const TRANSPARENT: bool = __TRANSPARENT__;
const NORMAL_MAPS: bool = __NORMAL_MAPS__;
const METALLIC_ROUGHNESS_TEXTURES: bool = __METALLIC_ROUGHNESS_TEXTURES__;
const EMISSIVE_TEXTURES: bool = __EMISSIVE_TEXTURES__;

// `offset_origin` of integrator.rs (Wächter and Binder, Ray Tracing Gems ch. 6): a few ulps of
// the point's own coordinates along `n`, a fixed step near the origin.
fn offset_origin(p: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    var out = p;
    for (var i = 0u; i < 3u; i++) {
        let of_i = i32(256.0 * n[i]);
        let bits = bitcast<i32>(p[i]);
        let moved = bitcast<f32>(bits + select(of_i, -of_i, p[i] < 0.0));
        out[i] = select(moved, p[i] + (1.0 / 65536.0) * n[i], abs(p[i]) < 1.0 / 32.0);
    }
    return out;
}

fn wrap_index(i: i32, n: i32, mode: u32) -> i32 {
    if mode == 2u {
        return clamp(i, 0, n - 1);
    }
    if mode == 1u {
        let period = ((i % (2 * n)) + 2 * n) % (2 * n);
        return select(2 * n - 1 - period, period, period < n);
    }
    return ((i % n) + n) % n;
}

fn texel(t: Texture, x: i32, y: i32) -> vec4<f32> {
    let xi = wrap_index(x, i32(t.width), t.flags & 3u);
    let yi = wrap_index(y, i32(t.height), (t.flags >> 2u) & 3u);
    return texel_at(t.offset + u32(yi) * t.width + u32(xi));
}

// `Texture::sample`: bilinear (or nearest) with the sampler's wrap modes, (0,0) top-left.
fn sample_texture(t: Texture, uv: vec2<f32>) -> vec4<f32> {
    let x = uv.x * f32(t.width) - 0.5;
    let y = uv.y * f32(t.height) - 0.5;
    if (t.flags & 16u) != 0u {
        return texel(t, i32(floor(x + 0.5)), i32(floor(y + 0.5)));
    }
    let x0 = floor(x);
    let y0 = floor(y);
    let fx = x - x0;
    let fy = y - y0;
    let xi = i32(x0);
    let yi = i32(y0);
    let top = mix(texel(t, xi, yi), texel(t, xi + 1, yi), fx);
    let bottom = mix(texel(t, xi, yi + 1), texel(t, xi + 1, yi + 1), fx);
    return mix(top, bottom, fy);
}

// A hit's triangle: its vertices, barycentrics (b0, b1, b2) and material.
struct Corner {
    a: Vertex,
    b: Vertex,
    c: Vertex,
    w: vec3<f32>,
    material: u32,
}

fn corner_of(hit: HitOut) -> Corner {
    let tri = face_at(hit.prim);
    let w = vec3<f32>(1.0 - hit.b1 - hit.b2, hit.b1, hit.b2);
    return Corner(vertex_at(tri.x), vertex_at(tri.y), vertex_at(tri.z), w, tri.w);
}

// `TextureRef::uv`: the slot's texture coordinate set at the hit, through its transform.
fn slot_uv(s: Slot, k: Corner) -> vec2<f32> {
    var uv = vec2<f32>(k.a.u0, k.a.v0) * k.w.x + vec2<f32>(k.b.u0, k.b.v0) * k.w.y + vec2<f32>(k.c.u0, k.c.v0) * k.w.z;
    if s.tex_coord == 1u {
        uv = vec2<f32>(k.a.u1, k.a.v1) * k.w.x + vec2<f32>(k.b.u1, k.b.v1) * k.w.y + vec2<f32>(k.c.u1, k.c.v1) * k.w.z;
    }
    let p = vec3<f32>(uv, 1.0);
    return vec2<f32>(dot(s.u, p), dot(s.v, p));
}

// A slot's texel at the hit; 1 in every channel without a texture.
fn slot_texel(s: Slot, k: Corner) -> vec4<f32> {
    if s.texture < 0 {
        return vec4<f32>(1.0);
    }
    return sample_texture(textures[s.texture], slot_uv(s, k));
}

// `Integrator::base_color`: base colour (RGB) and coverage (A), factor x texture x COLOR_0.
fn base_color(k: Corner) -> vec4<f32> {
    let m = &materials[k.material];
    let color = k.a.color * k.w.x + k.b.color * k.w.y + k.c.color * k.w.z;
    return (*m).base_color * color * slot_texel((*m).base_color_slot, k);
}

fn barycentric_point(k: Corner) -> vec3<f32> {
    return k.a.p * k.w.x + k.b.p * k.w.y + k.c.p * k.w.z;
}

// The far side of a surface crossed along `d`: `offset_origin` along the geometric normal.
fn beyond(k: Corner, d: vec3<f32>) -> vec3<f32> {
    let ng = normalize_or_zero(cross(k.b.p - k.a.p, k.c.p - k.a.p));
    return offset_origin(barycentric_point(k), select(-ng, ng, dot(ng, d) >= 0.0));
}

// `Integrator::pass_cut_outs`: the closest hit that exists, passing MASK hits whose coverage is
// below the cutoff; `t` from the first origin.
fn trace_visible(o: vec3<f32>, d: vec3<f32>, t_max: f32) -> HitOut {
    if !TRANSPARENT {
        return trace(o, d, t_max, false, frame.parts);
    }
    var origin = o;
    var travelled = 0.0;
    for (var i = 0u; i < MAX_CROSSINGS; i++) {
        var hit = trace(origin, d, t_max - travelled, false, frame.parts);
        if hit.prim == NO_PRIM {
            hit.t += travelled;
            return hit;
        }
        let k = corner_of(hit);
        let m = &materials[k.material];
        if (*m).alpha_mode != 1u || base_color(k).w >= (*m).alpha_cutoff {
            hit.t += travelled;
            return hit;
        }
        origin = beyond(k, d);
        travelled += hit.t;
        secondary += 1u;
    }
    var none: HitOut;
    none.prim = NO_PRIM;
    return none;
}

// `Integrator::visibility`: the fraction of a shadow ray that reaches the light. Opaque scenes
// ask for any hit; otherwise cut-outs are passed and each BLEND surface lets 1 - a through.
fn visibility(o: vec3<f32>, d: vec3<f32>, t_max: f32, light: Light) -> f32 {
    if !TRANSPARENT {
        shadow_rays += 1u;
        return select(1.0, 0.0, trace(o, d, t_max, true, frame.parts).prim != NO_PRIM);
    }
    var origin = o;
    var dir = d;
    var seen = 1.0;
    for (var i = 0u; i < MAX_CROSSINGS; i++) {
        shadow_rays += 1u;
        let hit = trace(origin, dir, t_max, false, frame.parts);
        if hit.prim == NO_PRIM {
            return seen;
        }
        let k = corner_of(hit);
        let m = &materials[k.material];
        if (*m).alpha_mode == 0u {
            return 0.0;
        }
        let a = base_color(k).w;
        if (*m).alpha_mode == 1u {
            if a >= (*m).alpha_cutoff {
                return 0.0;
            }
        } else {
            seen *= 1.0 - a;
            if seen <= 0.0 {
                return 0.0;
            }
        }
        origin = beyond(k, dir);
        if light.kind != 0u {
            dir = light.position - origin;
        }
    }
    return 0.0;
}

fn pow5(x: f32) -> f32 {
    let x2 = x * x;
    return x2 * x2 * x;
}

fn schlick(f0: vec3<f32>, cos: f32) -> vec3<f32> {
    let w = pow5(1.0 - clamp(cos, 0.0, 1.0));
    return f0 + (vec3<f32>(1.0) - f0) * w;
}

// shading.rs `gltf_brdf`: the glTF 2.0 metallic-roughness BRDF.
fn gltf_brdf(base: vec3<f32>, metallic: f32, roughness: f32, n: vec3<f32>, l: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    let h = normalize(l + v);
    let n_l = dot(n, l);
    let n_v = dot(n, v);
    let n_h = dot(n, h);
    let v_h = dot(v, h);
    var spec = 0.0;
    if roughness > 0.0 && n_h > 0.0 {
        let a = roughness * roughness;
        let a2 = a * a;
        let d_term = n_h * n_h * (a2 - 1.0) + 1.0;
        let d = a2 / (PI * d_term * d_term);
        let vis = 0.5 / (n_l * sqrt(n_v * n_v * (1.0 - a2) + a2) + n_v * sqrt(n_l * n_l * (1.0 - a2) + a2));
        let s = d * vis;
        // Not finite (NaN fails the comparison too): no highlight, as on the CPU.
        spec = select(0.0, s, abs(s) <= 3.4028235e38);
    }
    let fw = pow5(1.0 - abs(v_h));
    let f_dielectric = 0.04 + 0.96 * fw;
    let f_metal = base + (vec3<f32>(1.0) - base) * fw;
    let dielectric = (1.0 - f_dielectric) * base / PI + vec3<f32>(f_dielectric * spec);
    let metal = f_metal * spec;
    return (1.0 - metallic) * dielectric + metallic * metal;
}

// shading.rs `phong_brdf`: normalised Blinn-Phong with the exponent from the roughness.
fn phong_brdf(base: vec3<f32>, metallic: f32, roughness: f32, n: vec3<f32>, l: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    let diffuse = (1.0 - metallic) * base / PI;
    if roughness <= 0.0 {
        return diffuse;
    }
    let a = max(roughness * roughness, 1e-3);
    let e = max(2.0 / (a * a) - 2.0, 0.0);
    let h = normalize(l + v);
    let n_h = max(dot(n, h), 0.0);
    let ks = mix(vec3<f32>(0.04), base, metallic);
    return diffuse + ks * ((e + 8.0) / (8.0 * PI) * pow(n_h, e));
}

fn brdf(base: vec3<f32>, metallic: f32, roughness: f32, n: vec3<f32>, l: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    if frame.shading == 1u {
        return phong_brdf(base, metallic, roughness, n, l, v);
    }
    return gltf_brdf(base, metallic, roughness, n, l, v);
}

fn normalize_or_zero(v: vec3<f32>) -> vec3<f32> {
    let len2 = dot(v, v);
    if len2 > 0.0 && len2 <= 3.4028235e38 {
        return v / sqrt(len2);
    }
    return vec3<f32>(0.0);
}

// Direct light at a lit surface point from every light, each behind its shadow ray.
fn direct_light(p: vec3<f32>, n: vec3<f32>, ng: vec3<f32>, v: vec3<f32>, base: vec3<f32>, metallic: f32, roughness: f32) -> vec3<f32> {
    var sum = vec3<f32>(0.0);
    let origin = offset_origin(p, ng);
    for (var i = 0u; i < frame.lights; i++) {
        let light = lights[i];
        var l: vec3<f32>;
        var irradiance: vec3<f32>;
        var shadow_dir: vec3<f32>;
        var t_max: f32;
        if light.kind == 0u {
            l = -light.direction;
            irradiance = light.power;
            shadow_dir = l;
            t_max = FAR;
        } else {
            let to = light.position - p;
            let d2 = dot(to, to);
            let d = sqrt(d2);
            l = to / d;
            var cone = 1.0;
            if light.kind == 2u {
                let scale = 1.0 / max(light.cos_inner - light.cos_outer, 0.001);
                let offset = -light.cos_outer * scale;
                let a = clamp(dot(light.direction, -l) * scale + offset, 0.0, 1.0);
                cone = a * a;
            }
            var range = 1.0;
            if light.range > 0.0 {
                let r = d / light.range;
                range = clamp(1.0 - r * r * r * r, 0.0, 1.0);
            }
            irradiance = light.power * (cone * range / d2);
            shadow_dir = light.position - origin;
            t_max = 1.0 - SHADOW_EPSILON;
        }
        let n_l = dot(n, l);
        if n_l <= 0.0 || dot(ng, l) <= 0.0 || all(irradiance == vec3<f32>(0.0)) {
            continue;
        }
        let seen = visibility(origin, shadow_dir, t_max, light);
        if seen == 0.0 {
            continue;
        }
        let term = brdf(base, metallic, roughness, n, l, v) * n_l * irradiance;
        sum += select(seen * term, term, seen == 1.0);
    }
    return sum;
}

struct Pending {
    origin: vec3<f32>,
    t_max: f32,
    dir: vec3<f32>,
    depth: u32,
    weight: vec3<f32>,
}

@compute @workgroup_size(64)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(workgroup_id) group: vec3<u32>,
) {
    if gid.x >= frame.count {
        return;
    }
    let index = frame.first + gid.x;
    let camera = camera_rays[index];
    // Rays waiting: at most one per level below the camera ray, and the one being traced.
    let first_slot = gid.x * frame.stride;
    var size = 1u;
    pending[first_slot] = Pending(camera.origin, camera.t_max, camera.dir, 1u, vec3<f32>(1.0));
    var total = vec3<f32>(0.0);
    while size > 0u {
        size -= 1u;
        let ray = pending[first_slot + size];
        secondary += select(0u, 1u, ray.depth > 1u);
        let hit = trace_visible(ray.origin, ray.dir, ray.t_max);
        if hit.prim == NO_PRIM {
            total += ray.weight * frame.background;
            continue;
        }
        // The hit's surface (`shading_point`, `surface`): the barycentric point, geometric and
        // interpolated normals turned to the viewer, and the material's values there.
        let k = corner_of(hit);
        let p = barycentric_point(k);
        let ng0 = normalize_or_zero(cross(k.b.p - k.a.p, k.c.p - k.a.p));
        let interp = k.a.n * k.w.x + k.b.n * k.w.y + k.c.n * k.w.z;
        var ns = ng0;
        if dot(interp, interp) > 1e-12 {
            ns = normalize(interp);
        }
        let front = dot(ng0, -ray.dir) > 0.0;
        let side = select(-1.0, 1.0, front);
        let ng = ng0 * side;
        let v = -ray.dir;
        let m = &materials[k.material];
        let base_alpha = base_color(k);
        let base = base_alpha.xyz;
        var roughness = (*m).roughness;
        var metallic = (*m).metallic;
        if METALLIC_ROUGHNESS_TEXTURES {
            let mr = slot_texel((*m).metallic_roughness_slot, k);
            roughness *= mr.y;
            metallic *= mr.z;
        }
        var emissive = (*m).emissive;
        if EMISSIVE_TEXTURES {
            emissive *= slot_texel((*m).emissive_slot, k).xyz;
        }
        var n = ns * side;
        // `map_normal`: the normal map's normal in the interpolated tangent frame, turned to
        // the viewer and clamped to face it.
        let mapped = NORMAL_MAPS && (*m).normal_slot.texture >= 0;
        if mapped {
            let interp_t = k.a.tangent.xyz * k.w.x + k.b.tangent.xyz * k.w.y + k.c.tangent.xyz * k.w.z;
            let t = normalize_or_zero(interp_t - ns * dot(ns, interp_t));
            var np = ns;
            if any(t != vec3<f32>(0.0)) {
                let bitangent = cross(ns, t) * k.a.tangent.w;
                let c = slot_texel((*m).normal_slot, k);
                let s = (*m).normal_scale;
                let local = vec3<f32>((2.0 * c.x - 1.0) * s, (2.0 * c.y - 1.0) * s, 2.0 * c.z - 1.0);
                let q = normalize_or_zero(local.x * t + local.y * bitangent + local.z * ns);
                np = select(ns, q, any(q != vec3<f32>(0.0)));
            }
            n = np * side;
            let facing = dot(n, v);
            if facing < FACING_MIN {
                n = normalize(n + (FACING_MIN - facing) * v);
            }
        }
        let glass = (*m).transmission >= 0.5;
        let blend = TRANSPARENT && (*m).alpha_mode == 2u;
        let alpha = select(1.0, base_alpha.w, blend);
        var here = emissive;
        if !glass && dot(n, v) > 0.0 {
            here += direct_light(p, n, ng, v, base, metallic, roughness);
        }
        if blend {
            here *= alpha;
        }
        total += ray.weight * here;
        if ray.depth >= frame.max_depth {
            continue;
        }
        // What lies behind a BLEND surface, as a ray of the next depth (`bounces`).
        if blend {
            pending[first_slot + size] = Pending(beyond(k, ray.dir), FAR, ray.dir, ray.depth + 1u, ray.weight * (1.0 - alpha));
            size += 1u;
        }
        // The mirror ray and, for glass, the refraction ray (`specular_bounces`); a normal-mapped
        // hit drops a mirror ray below its geometric surface and a refracted ray above it.
        let cos_i = clamp(dot(n, v), 0.0, 1.0);
        let reflect_dir = normalize(ray.dir + 2.0 * cos_i * n);
        var reflect_weight = vec3<f32>(0.0);
        if glass {
            let eta = select((*m).ior, 1.0 / (*m).ior, front);
            let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
            var f = 1.0;
            if sin2_t < 1.0 {
                let cos_t = sqrt(1.0 - sin2_t);
                let rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
                let rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
                f = 0.5 * (rs * rs + rp * rp);
                let dir = normalize(eta * ray.dir + (eta * cos_i - cos_t) * n);
                if !(mapped && dot(dir, ng) >= 0.0) {
                    let o = offset_origin(p, select(-ng, ng, dot(ng, dir) >= 0.0));
                    pending[first_slot + size] = Pending(o, FAR, dir, ray.depth + 1u, ray.weight * (1.0 - f) * base);
                    size += 1u;
                }
            }
            reflect_weight = vec3<f32>(f);
        } else if roughness == 0.0 {
            reflect_weight = (1.0 - metallic) * schlick(vec3<f32>(0.04), cos_i) + metallic * schlick(base, cos_i);
        } else {
            continue;
        }
        if mapped && dot(reflect_dir, ng) <= 0.0 {
            continue;
        }
        let o = offset_origin(p, select(-ng, ng, dot(ng, reflect_dir) >= 0.0));
        pending[first_slot + size] = Pending(o, FAR, reflect_dir, ray.depth + 1u, ray.weight * alpha * reflect_weight);
        size += 1u;
    }
    radiance[index] = vec4<f32>(total, 1.0);
    let slot = 2u * (frame.first / 64u + group.x);
    atomicAdd(&ray_counts[slot], secondary);
    atomicAdd(&ray_counts[slot + 1u], shadow_rays);
}
