// A frame's parts (`gpu/accel.rs`) walked in the CPU's order (`accel/instances.rs`), after the
// kd-tree walk of `walk.wgsl` (which the host puts before this file): a world part's kd-tree as
// it is; an instance's once the ray meets its world box, the ray carried into object space with
// its direction not renormalized, so distances compare across parts; a refitted (bounded)
// kd-tree by its children's boxes, nearer child first, as `RefitTree::walk_boxes`.

const PART_INSTANCE: u32 = 1u;
const PART_BOXES: u32 = 2u;

struct Part {
    world_to_object: mat4x4<f32>,
    world_min: vec3<f32>,
    kind: u32,
    world_max: vec3<f32>,
    node_base: u32,
    tree_min: vec3<f32>,
    ref_base: u32,
    tree_max: vec3<f32>,
    box_base: u32,
    // A hit's global triangle index is its triangle entry - tri_base + prim_offset.
    tri_base: u32,
    prim_offset: u32,
    pad: vec2<u32>,
}

// Per node of a refitted tree: its below and above children's boxes (min, max each, 12 floats),
// in two parts as the other arrays.
@group(0) @binding(17) var<storage, read> boxes: array<f32>;
@group(0) @binding(18) var<storage, read> boxes_rest: array<f32>;
@group(0) @binding(19) var<storage, read> parts: array<Part>;

fn box_at(i: u32) -> f32 {
    let n = arrayLength(&boxes);
    if i < n {
        return boxes[i];
    }
    return boxes_rest[i - n];
}

// The ray's interval inside a box (`Aabb::clip`); a miss comes back with x > y.
fn clip_box(lo: vec3<f32>, hi: vec3<f32>, o: vec3<f32>, d: vec3<f32>, inv_d: vec3<f32>, t_max: f32) -> vec2<f32> {
    var t0 = 0.0;
    var t1 = t_max;
    for (var axis = 0u; axis < 3u; axis++) {
        if d[axis] == 0.0 {
            if o[axis] < lo[axis] || o[axis] > hi[axis] {
                return vec2<f32>(1.0, 0.0);
            }
            continue;
        }
        let a = (lo[axis] - o[axis]) * inv_d[axis];
        let b = (hi[axis] - o[axis]) * inv_d[axis];
        t0 = max(t0, min(a, b));
        t1 = min(t1, max(a, b));
        if t0 > t1 {
            return vec2<f32>(1.0, 0.0);
        }
    }
    return vec2<f32>(t0, t1);
}

// A refitted tree's closest hit (or, with `any`, the first found) below `t_max`. Children may
// overlap: both are visited when the ray meets both, the farther one waiting on the stack with
// where the ray enters it, and skipped once the best hit is nearer than that. At most one child
// waits per level, so the stack is as deep as the tree.
fn walk_boxes(o: vec3<f32>, d: vec3<f32>, t_max: f32, part: u32, any: bool) -> HitOut {
    let p = parts[part];
    var out = HitOut(t_max, NO_PRIM, 0.0, 0.0);
    let inv_d = vec3<f32>(1.0) / d;
    let root = clip_box(p.tree_min, p.tree_max, o, d, inv_d, t_max);
    if root.x > root.y {
        return out;
    }
    let sh = shear_of(d);
    // Waiting children: node, and where the ray enters it (as bits).
    var stack: array<vec2<u32>, FULL_STACK>;
    var size = 0u;
    var node = p.node_base;
    var near = root.x;
    loop {
        if near <= out.t {
            let n = node_at(node);
            if (n.y & 3u) == 3u {
                let first = n.x + p.ref_base;
                if test_leaf(first, first + (n.y >> 2u), o, sh, &out, any) {
                    return out;
                }
            } else {
                tally.x += 1u;
                let k = 12u * (p.box_base + node - p.node_base);
                let below_lo = vec3<f32>(box_at(k), box_at(k + 1u), box_at(k + 2u));
                let below_hi = vec3<f32>(box_at(k + 3u), box_at(k + 4u), box_at(k + 5u));
                let above_lo = vec3<f32>(box_at(k + 6u), box_at(k + 7u), box_at(k + 8u));
                let above_hi = vec3<f32>(box_at(k + 9u), box_at(k + 10u), box_at(k + 11u));
                let below = clip_box(below_lo, below_hi, o, d, inv_d, out.t);
                let above = clip_box(above_lo, above_hi, o, d, inv_d, out.t);
                let below_node = node + 1u;
                let above_node = node + (n.y >> 2u);
                let in_below = below.x <= below.y;
                let in_above = above.x <= above.y;
                if in_below && in_above {
                    // The nearer first; the below child on a tie, as the CPU pops it.
                    if above.x < below.x {
                        stack[size] = vec2<u32>(below_node, bitcast<u32>(below.x));
                        node = above_node;
                        near = above.x;
                    } else {
                        stack[size] = vec2<u32>(above_node, bitcast<u32>(above.x));
                        node = below_node;
                        near = below.x;
                    }
                    size += 1u;
                    continue;
                }
                if in_below {
                    node = below_node;
                    near = below.x;
                    continue;
                }
                if in_above {
                    node = above_node;
                    near = above.x;
                    continue;
                }
            }
        }
        if size == 0u {
            break;
        }
        size -= 1u;
        node = stack[size].x;
        near = bitcast<f32>(stack[size].y);
    }
    return out;
}

// The closest hit among the first `count` parts (or, with `any`, the first found) below
// `t_max`, its `prim` the global triangle index; each part is walked below the best hit so far.
fn trace(o: vec3<f32>, d: vec3<f32>, t_max: f32, any: bool, count: u32) -> HitOut {
    var best = HitOut(t_max, NO_PRIM, 0.0, 0.0);
    for (var i = 0u; i < count; i++) {
        // Only the fields this part's walk needs, not the whole row.
        let kind = parts[i].kind;
        var lo = o;
        var ld = d;
        if (kind & PART_INSTANCE) != 0u {
            let world = clip_box(parts[i].world_min, parts[i].world_max, o, d, vec3<f32>(1.0) / d, best.t);
            if world.x > world.y {
                continue;
            }
            let m = parts[i].world_to_object;
            lo = (m * vec4<f32>(o, 1.0)).xyz;
            ld = (m * vec4<f32>(d, 0.0)).xyz;
        }
        var h: HitOut;
        if (kind & PART_BOXES) != 0u {
            h = walk_boxes(lo, ld, best.t, i, any);
        } else {
            h = walk(lo, ld, best.t, parts[i].tree_min, parts[i].tree_max, any, parts[i].node_base, parts[i].ref_base);
        }
        if h.prim != NO_PRIM {
            best = h;
            best.prim = h.prim - parts[i].tri_base + parts[i].prim_offset;
            if any {
                break;
            }
        }
    }
    return best;
}
