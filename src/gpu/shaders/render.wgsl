// The renderer's deterministic path on the GPU (src/render/mod.rs): one thread per pixel of the camera contract,
// the sphere or the plane, and Σ f(l, v) max(0, n·l) E over directional and point lights, f from the model's
// eval_pair. Composed after optics.wgsl and a model's shader (whose `out` serves as each pixel's scratch).

struct RenderParams {
    width: u32,
    height: u32,
    shape: u32,   // 0 sphere, 1 plane
    camera: u32,  // 0 orthographic, 1 perspective
    lights: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
    // Perspective: the pinhole, and the forward, right and up vectors (right and up scaled by tan(fov/2)·aspect
    // and tan(fov/2)).
    origin: vec4<f32>,
    forward: vec4<f32>,
    right: vec4<f32>,
    up: vec4<f32>,
}

@group(1) @binding(0) var<uniform> rp: RenderParams;
// Two rows per light: (kind 0 directional / 1 point, x, y, z), (r, g, b, 0): direction towards the light and
// irradiance, or position and intensity.
@group(1) @binding(1) var<storage, read> light_rows: array<vec4<f32>>;
@group(1) @binding(2) var<storage, read_write> image: array<f32>;

struct Hit {
    found: bool,
    p: vec3<f32>,
    n: vec3<f32>,
    t: vec3<f32>,
}

// Scene::intersect: the unit sphere (t = normalize(ŷ × n)) or the square [−1, 1]² of z = 0 (t = x̂).
fn intersect(o: vec3<f32>, d: vec3<f32>) -> Hit {
    var h = Hit(false, vec3<f32>(0.0), vec3<f32>(0.0, 0.0, 1.0), vec3<f32>(1.0, 0.0, 0.0));
    if rp.shape == 0u {
        // |o + s d|² = 1: disc = 1 − |q|², q the ray's point nearest the centre (stable in float32).
        let b = dot(o, d);
        let q = o - b * d;
        let disc = 1.0 - dot(q, q);
        if disc < 0.0 {
            return h;
        }
        var s = -b - sqrt(disc);
        if s <= 1e-6 {
            s = -b + sqrt(disc);
        }
        if s <= 1e-6 {
            return h;
        }
        h.found = true;
        h.n = normalize(o + s * d);
        h.p = h.n;
        let t = cross(vec3<f32>(0.0, 1.0, 0.0), h.n);
        if dot(t, t) > 0.0 {
            h.t = normalize(t);
        }
        return h;
    }
    if abs(d.z) < 1e-12 {
        return h;
    }
    let s = -o.z / d.z;
    let p = o + s * d;
    h.found = s > 1e-6 && abs(p.x) <= 1.0 && abs(p.y) <= 1.0;
    h.p = p;
    return h;
}

@compute @workgroup_size(64)
fn render(@builtin(global_invocation_id) gid: vec3<u32>) {
    let px = gid.x;
    if px >= rp.width * rp.height {
        return;
    }
    let i = px % rp.width;
    let j = px / rp.width;
    // Scene::ray: the centre of pixel (i, j).
    let x = (f32(i) + 0.5) / f32(rp.width) * 2.0 - 1.0;
    let y = 1.0 - (f32(j) + 0.5) / f32(rp.height) * 2.0;
    var o = vec3<f32>(x, y, 10.0);
    var d = vec3<f32>(0.0, 0.0, -1.0);
    if rp.camera == 1u {
        o = rp.origin.xyz;
        d = normalize(rp.forward.xyz + x * rp.right.xyz + y * rp.up.xyz);
    }
    let hit = intersect(o, d);
    var rgb = vec3<f32>(0.0);
    if hit.found {
        let b = cross(hit.n, hit.t);
        let wo = vec3<f32>(dot(-d, hit.t), dot(-d, b), dot(-d, hit.n));
        let base = px * params.channels;
        for (var k = 0u; k < rp.lights; k++) {
            let a = light_rows[2u * k];
            let e = light_rows[2u * k + 1u];
            var l = a.yzw;
            var irradiance = e.xyz;
            if a.x == 1.0 {
                let v = a.yzw - hit.p;
                let r2 = max(dot(v, v), 1e-12);
                l = normalize(v);
                irradiance = e.xyz / r2;
            }
            let wi = vec3<f32>(dot(l, hit.t), dot(l, b), dot(l, hit.n));
            if wi.z > 0.0 && wo.z > 0.0 {
                eval_pair(wi, wo, base);
                rgb += vec3<f32>(out[base], out[base + 1u], out[base + 2u]) * wi.z * irradiance;
            }
        }
    }
    image[3u * px] = rgb.x;
    image[3u * px + 1u] = rgb.y;
    image[3u * px + 2u] = rgb.z;
}
