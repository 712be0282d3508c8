// The GPU renderer's scene (src/render/mod.rs): the camera contract, the sphere or the plane, and the directional
// and point lights. Composed before the kernels that render it: render.wgsl (the models) and oat.wgsl.

struct RenderParams {
    width: u32,
    height: u32,
    shape: u32,   // 0 sphere, 1 plane
    camera: u32,  // 0 orthographic, 1 perspective
    lights: u32,
    stacks: u32,  // images rendered by the dispatch, one per stack (the models' kernels)
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
    uv: vec2<f32>,
}

// The flat index of a thread of a dispatch of (x, y) workgroups of 64 (gpu::workgroups: y > 1 past 65535 in x).
fn thread_index(gid: vec3<u32>, groups: vec3<u32>) -> u32 {
    return gid.y * groups.x * 64u + gid.x;
}

// The radiance of pixel px into the image (of the images of a batch, px counting on through them).
fn store(px: u32, rgb: vec3<f32>) {
    image[3u * px] = rgb.x;
    image[3u * px + 1u] = rgb.y;
    image[3u * px + 2u] = rgb.z;
}

// Scene::ray: the camera ray (origin, unit direction) through the centre of pixel px.
fn camera_ray(px: u32) -> array<vec3<f32>, 2> {
    let i = px % rp.width;
    let j = px / rp.width;
    let x = (f32(i) + 0.5) / f32(rp.width) * 2.0 - 1.0;
    let y = 1.0 - (f32(j) + 0.5) / f32(rp.height) * 2.0;
    if rp.camera == 1u {
        return array<vec3<f32>, 2>(rp.origin.xyz, normalize(rp.forward.xyz + x * rp.right.xyz + y * rp.up.xyz));
    }
    return array<vec3<f32>, 2>(vec3<f32>(x, y, 10.0), vec3<f32>(0.0, 0.0, -1.0));
}

// render::incident: light k's direction (towards it) and irradiance at p.
fn incident(k: u32, p: vec3<f32>) -> array<vec3<f32>, 2> {
    let a = light_rows[2u * k];
    let e = light_rows[2u * k + 1u];
    if a.x == 1.0 {
        let v = a.yzw - p;
        return array<vec3<f32>, 2>(normalize(v), e.xyz / max(dot(v, v), 1e-12));
    }
    return array<vec3<f32>, 2>(a.yzw, e.xyz);
}

// Scene::intersect: the unit sphere (t = normalize(ŷ × n), uv = (½ + atan2(x, z)/2π, acos(y)/π)) or the square
// [−1, 1]² of z = 0 (t = x̂, uv = ((x + 1)/2, (1 − y)/2)).
fn intersect(o: vec3<f32>, d: vec3<f32>) -> Hit {
    var h = Hit(false, vec3<f32>(0.0), vec3<f32>(0.0, 0.0, 1.0), vec3<f32>(1.0, 0.0, 0.0), vec2<f32>(0.0));
    if rp.shape == 0u {
        // |o + s d|² = 1: disc = 1 − |q|², q the ray's point nearest the centre (stable in float32).
        let b = dot(o, d);
        let q = o - b * d;
        let disc = 1.0 - dot(q, q);
        if disc < 0.0 {
            return h;
        }
        // The hit o + s d = q ∓ √disc d: from q, not from o, whose distance would cancel in float32.
        var root = -sqrt(disc);
        if -b + root <= 1e-6 {
            root = sqrt(disc);
        }
        if -b + root <= 1e-6 {
            return h;
        }
        h.found = true;
        h.n = normalize(q + root * d);
        h.p = h.n;
        let t = cross(vec3<f32>(0.0, 1.0, 0.0), h.n);
        if dot(t, t) > 0.0 {
            h.t = normalize(t);
        }
        h.uv = vec2<f32>(0.5 + atan2(h.n.x, h.n.z) / (2.0 * PI), acos(clamp(h.n.y, -1.0, 1.0)) / PI);
        return h;
    }
    if abs(d.z) < 1e-12 {
        return h;
    }
    let s = -o.z / d.z;
    let p = o + s * d;
    h.found = s > 1e-6 && abs(p.x) <= 1.0 && abs(p.y) <= 1.0;
    h.p = p;
    h.uv = vec2<f32>(0.5 * (p.x + 1.0), 0.5 * (1.0 - p.y));
    return h;
}

