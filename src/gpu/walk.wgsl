// kd-tree traversal on the GPU: one invocation per ray, the CPU's tree bit for bit (accel/tree.rs:
// 8-byte nodes in depth-first order, the below child right after its parent), the CPU's
// watertight triangle test (accel/triangle.rs). Three walks, chosen by `STACK_CAP` when the host
// builds the pipeline (it writes the constant into this source, since WGSL sizes a private array
// only by a constant expression):
// - a full per-ray stack (`STACK_CAP` >= the depth cap): the CPU walk, step for step;
// - a short stack (Horn et al., "Interactive k-D Tree GPU Raytracing", I3D 2007): a ring of
//   `STACK_CAP` entries that forgets its oldest entry when full, and a restart from the root
//   over what is left of the ray when it runs dry;
// - kd-restart (Foley and Sugerman, "KD-Tree Acceleration Structures for a GPU Raytracer",
//   Graphics Hardware 2005): `STACK_CAP` = 0, every leaf exit restarts from the root.
// Restarts follow a restart trail (below), so all three find the CPU's hits.

const STACK_CAP: u32 = __STACK_CAP__u;
// A ring this long never forgets: it is the CPU walk's stack, one entry per level of the depth cap.
const FULL_STACK: u32 = __FULL_STACK__u;
// At least one entry, so the array is valid WGSL when `STACK_CAP` is 0 (kd-restart never uses it).
const STACK_LEN: u32 = max(STACK_CAP, 1u);

// `prim` = 0xffffffff: no hit (or, for any hit, not occluded).
struct HitOut {
    t: f32,
    prim: u32,
    b1: f32,
    b2: f32,
}

struct Entry {
    node: u32,
    t_min: f32,
    t_far: f32,
}

@group(0) @binding(0) var<storage, read> nodes: array<vec2<u32>>;
@group(0) @binding(1) var<storage, read> prim_refs: array<u32>;
@group(0) @binding(2) var<storage, read> tris: array<f32>;
// Where an array is larger than the adapter binds in one buffer, its second part (else a
// placeholder never read): an index past the first part's length continues here.
@group(0) @binding(13) var<storage, read> nodes_rest: array<vec2<u32>>;
@group(0) @binding(14) var<storage, read> prim_refs_rest: array<u32>;
@group(0) @binding(15) var<storage, read> tris_rest: array<f32>;

fn node_at(i: u32) -> vec2<u32> {
    let n = arrayLength(&nodes);
    if i < n {
        return nodes[i];
    }
    return nodes_rest[i - n];
}

fn prim_at(i: u32) -> u32 {
    let n = arrayLength(&prim_refs);
    if i < n {
        return prim_refs[i];
    }
    return prim_refs_rest[i - n];
}

fn tri_at(i: u32) -> f32 {
    let n = arrayLength(&tris);
    if i < n {
        return tris[i];
    }
    return tris_rest[i - n];
}

const NO_PRIM: u32 = 0xffffffffu;

// The shear of the watertight test (Woop, Benthin and Wald 2013), as `RayPre::new` builds it.
struct Shear {
    k: vec3<u32>,
    s: vec3<f32>,
}

fn shear_of(d: vec3<f32>) -> Shear {
    let a = abs(d);
    var kz = 2u;
    if a.x >= a.y && a.x >= a.z {
        kz = 0u;
    } else if a.y >= a.z {
        kz = 1u;
    }
    var kx = (kz + 1u) % 3u;
    var ky = (kz + 2u) % 3u;
    if d[kz] < 0.0 {
        let t = kx;
        kx = ky;
        ky = t;
    }
    var sh: Shear;
    sh.k = vec3<u32>(kx, ky, kz);
    sh.s = vec3<f32>(d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]);
    return sh;
}

fn vertex(i: u32) -> vec3<f32> {
    return vec3<f32>(tri_at(3u * i), tri_at(3u * i + 1u), tri_at(3u * i + 2u));
}

// The vertex relative to the origin, sheared so the ray runs along +z.
fn sheared(v: vec3<f32>, o: vec3<f32>, sh: Shear) -> vec3<f32> {
    let r = v - o;
    let z = r[sh.k.z];
    return vec3<f32>(r[sh.k.x] - sh.s.x * z, r[sh.k.y] - sh.s.y * z, sh.s.z * z);
}

// `a d - b c` to within about an ulp (Kahan's algorithm with fused multiply-adds), where the
// CPU recomputes an edge function that came out exactly zero in f64 (WGSL has no f64).
fn det2(a: f32, d: f32, b: f32, c: f32) -> f32 {
    let bc = b * c;
    let err = fma(-b, c, bc);
    return fma(a, d, -bc) + err;
}

// (t, b1, b2) of a hit with 0 < t < t_max, or t < 0 for none.
fn intersect(prim: u32, o: vec3<f32>, sh: Shear, t_max: f32) -> vec3<f32> {
    let a = sheared(vertex(3u * prim), o, sh);
    let b = sheared(vertex(3u * prim + 1u), o, sh);
    let c = sheared(vertex(3u * prim + 2u), o, sh);
    var u = c.x * b.y - c.y * b.x;
    var v = a.x * c.y - a.y * c.x;
    var w = b.x * a.y - b.y * a.x;
    if u == 0.0 || v == 0.0 || w == 0.0 {
        u = det2(c.x, b.y, c.y, b.x);
        v = det2(a.x, c.y, a.y, c.x);
        w = det2(b.x, a.y, b.y, a.x);
    }
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return vec3<f32>(-1.0, 0.0, 0.0);
    }
    let det = u + v + w;
    if det == 0.0 {
        return vec3<f32>(-1.0, 0.0, 0.0);
    }
    let t_scaled = u * a.z + v * b.z + w * c.z;
    let inv_det = 1.0 / det;
    let t = t_scaled * inv_det;
    if !(t > 0.0 && t < t_max) {
        return vec3<f32>(-1.0, 0.0, 0.0);
    }
    return vec3<f32>(t, v * inv_det, w * inv_det);
}

// The restart trail (Laine, "Restart Trail for Stackless BVH Traversal", HPG 2010), here for the
// kd-tree: bit L (of 64, in two words) is set when the walk's node at depth L has no second child
// left to visit. With it a restart descends to exactly the node the CPU's stack would pop, so
// the short stack and kd-restart visit the CPU walk's nodes in its order, zero-length cells
// (a ray crossing two planes at one point, or lying in one) included.
const NONE: u32 = 0xffffffffu;

fn has_bit(trail: vec2<u32>, level: u32) -> bool {
    if level < 32u {
        return (trail.x & (1u << level)) != 0u;
    }
    return (trail.y & (1u << (level - 32u))) != 0u;
}

fn with_bit(trail: vec2<u32>, level: u32) -> vec2<u32> {
    if level < 32u {
        return vec2<u32>(trail.x | (1u << level), trail.y);
    }
    return vec2<u32>(trail.x, trail.y | (1u << (level - 32u)));
}

// Bits 0..n-1 of a word, for n in 0..=32.
fn low_bits(n: u32) -> u32 {
    return select((1u << n) - 1u, 0xffffffffu, n >= 32u);
}

// The deepest level above `depth` whose bit is clear, or NONE.
fn deepest_pending(trail: vec2<u32>, depth: u32) -> u32 {
    let open = ~trail & vec2<u32>(low_bits(depth), low_bits(max(depth, 32u) - 32u));
    if open.y != 0u {
        return 32u + firstLeadingBit(open.y);
    }
    if open.x != 0u {
        return firstLeadingBit(open.x);
    }
    return NONE;
}

// Marks `level` done and forgets every deeper level: the walk goes on at that level's second child.
fn advance(trail: vec2<u32>, level: u32) -> vec2<u32> {
    let kept = trail & vec2<u32>(low_bits(level + 1u), low_bits(max(level + 1u, 32u) - 32u));
    return with_bit(kept, level);
}

// Inner nodes, leaves and triangle tests of the walks this invocation ran.
var<private> tally: vec3<u32>;

// Tests the references `first..end` of a leaf against the ray, keeping in `hit` any hit nearer
// than `hit.t`; with `any`, true at the first hit found.
fn test_leaf(first: u32, end: u32, o: vec3<f32>, sh: Shear, hit: ptr<function, HitOut>, any: bool) -> bool {
    tally.y += 1u;
    for (var i = first; i < end; i++) {
        tally.z += 1u;
        let p = prim_at(i);
        let h = intersect(p, o, sh, (*hit).t);
        if h.x > 0.0 {
            *hit = HitOut(h.x, p, h.y, h.z);
            if any {
                return true;
            }
        }
    }
    return false;
}

// The closest hit of the ray `o + t d` with 0 < t < t_max (or, with `any`, the first hit found)
// in the tree over the box `box_min`..`box_max` whose root is node `root` and whose leaves'
// references start at `ref_base`; `prim` (an entry of the triangle array) = NO_PRIM for none.
fn walk(o: vec3<f32>, d: vec3<f32>, t_max: f32, box_min: vec3<f32>, box_max: vec3<f32>, any: bool, root: u32, ref_base: u32) -> HitOut {
    var out = HitOut(t_max, NO_PRIM, 0.0, 0.0);
    let inv_d = vec3<f32>(1.0) / d;
    // The ray's interval inside the scene box (`Aabb::clip`): slabs per axis, a zero component
    // inside its slab leaves the interval as it is.
    var t_enter = 0.0;
    var t_exit = t_max;
    for (var axis = 0u; axis < 3u; axis++) {
        let lo = box_min[axis];
        let hi = box_max[axis];
        if d[axis] == 0.0 {
            if o[axis] < lo || o[axis] > hi {
                t_exit = -1.0;
            }
        } else {
            let near = (lo - o[axis]) * inv_d[axis];
            let far = (hi - o[axis]) * inv_d[axis];
            t_enter = max(t_enter, min(near, far));
            t_exit = min(t_exit, max(near, far));
        }
    }
    if !(t_enter <= t_exit) {
        return out;
    }
    let sh = shear_of(d);
    var stack: array<Entry, STACK_LEN>;
    // The ring's newest entry is at `top - 1` (modulo its length); `size` entries are held.
    var top = 0u;
    var size = 0u;
    var node = root;
    var depth = 0u;
    var trail = vec2<u32>(0u, 0u);
    var t_min = t_enter;
    var t_far = t_exit;
    loop {
        if out.t < t_min {
            break;
        }
        let n = node_at(node);
        if (n.y & 3u) == 3u {
            let first = n.x + ref_base;
            if test_leaf(first, first + (n.y >> 2u), o, sh, &out, any) {
                break;
            }
            // The deepest level whose second child is still to visit; none left ends the walk.
            let level = deepest_pending(trail, depth);
            if level == NONE {
                break;
            }
            trail = advance(trail, level);
            depth = level + 1u;
            if size > 0u {
                // The newest entry is that level's second child (the ring forgets the oldest,
                // shallowest entries first).
                top = (top + STACK_LEN - 1u) % STACK_LEN;
                size -= 1u;
                let e = stack[top];
                node = e.node;
                t_min = e.t_min;
                t_far = e.t_far;
            } else {
                // Restart: the trail steers the walk back down to that child.
                node = root;
                depth = 0u;
                t_min = t_enter;
                t_far = t_exit;
            }
            continue;
        }
        tally.x += 1u;
        let axis = n.y & 3u;
        let split = bitcast<f32>(n.x);
        let below = node + 1u;
        let above = node + (n.y >> 2u);
        let oa = o[axis];
        let da = d[axis];
        var first = above;
        var second = below;
        if oa < split || (oa == split && da <= 0.0) {
            first = below;
            second = above;
        }
        // The CPU walk's cases: one child, or both (the second from `t_second` on).
        var both = false;
        var t_second = t_min;
        var t_first_far = t_far;
        if da == 0.0 {
            // The ray lies in the split plane: triangles in it may sit on either side.
            both = oa == split;
            node = first;
        } else {
            let t_plane = (split - oa) * inv_d[axis];
            if t_plane > t_far || t_plane <= 0.0 {
                node = first;
            } else if t_plane < t_min {
                node = second;
            } else {
                both = true;
                t_second = t_plane;
                t_first_far = t_plane;
            }
        }
        if both {
            if has_bit(trail, depth) {
                // Back after a restart: the first child is done.
                node = second;
                t_min = t_second;
            } else {
                if STACK_CAP > 0u {
                    stack[top] = Entry(second, t_second, t_far);
                    top = (top + 1u) % STACK_LEN;
                    size = min(size + 1u, STACK_CAP);
                }
                node = first;
                t_far = t_first_far;
            }
        } else {
            // Nothing waits at this level.
            trail = with_bit(trail, depth);
        }
        depth += 1u;
    }
    return out;
}
