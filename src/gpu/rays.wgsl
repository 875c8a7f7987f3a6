// Batches of rays through the parts of `parts.wgsl` (which the host puts, after `walk.wgsl`,
// before this file): one invocation per ray, its hit written out, and in a counting pass its
// work.

// Set by the host per pipeline: any hit (shadow rays) or closest hit, and whether to count the
// walk's work (an untimed pass, as the CPU's counted walk is).
override ANY_HIT: bool = false;
override COUNT: bool = false;

struct Ray {
    origin: vec3<f32>,
    t_max: f32,
    dir: vec3<f32>,
    pad: f32,
}

struct Params {
    first: u32,
    count: u32,
    // Rows of the part table.
    parts: u32,
    pad: u32,
}

@group(0) @binding(3) var<storage, read> rays: array<Ray>;
@group(0) @binding(4) var<storage, read_write> hits: array<HitOut>;
@group(0) @binding(5) var<uniform> params: Params;
// Per workgroup of rays: inner nodes visited, leaves visited, triangle tests (summed on the host;
// one workgroup's counts stay far inside a u32).
@group(0) @binding(6) var<storage, read_write> work: array<atomic<u32>>;

@compute @workgroup_size(64)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(workgroup_id) group: vec3<u32>,
) {
    if gid.x >= params.count {
        return;
    }
    let index = params.first + gid.x;
    let ray = rays[index];
    hits[index] = trace(ray.origin, ray.dir, ray.t_max, ANY_HIT, params.parts);
    if COUNT {
        let slot = 3u * (params.first / 64u + group.x);
        atomicAdd(&work[slot], tally.x);
        atomicAdd(&work[slot + 1u], tally.y);
        atomicAdd(&work[slot + 2u], tally.z);
    }
}
