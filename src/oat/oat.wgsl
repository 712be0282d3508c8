// Oat 2006's gooey layers on the GPU, mirroring src/oat/mod.rs function by function: the texture-space light
// map (one thread per texel of the sphere's or the plane's uv chart) and the composite (one thread per pixel).
// Composed after optics.wgsl and scene.wgsl. Textures live in one float array, described by (offset, width,
// height, comps) rows; the light map is one of them, written by `light_map` before `shade` reads it.

struct OatParams {
    variant: u32,   // 0 full, 1 normal_filtered, 2 vertex_normal
    shadowing: u32,
    border: u32,    // 0 clamp, 1 wrap
    inner: u32,     // the number of inner layers
    texel: vec2<f32>,
    pad: vec2<f32>,
}

@group(0) @binding(0) var<uniform> op: OatParams;
@group(0) @binding(1) var<storage, read> textures: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read_write> texels: array<f32>;

const OUTER_ALBEDO: u32 = 0u;
const OUTER_OPACITY: u32 = 1u;
const OUTER_NORMAL: u32 = 2u;
const LIGHT_MAP: u32 = 3u;
// Inner layer k: albedo 4 + 3k, opacity 5 + 3k (0 values per texel for the deepest), depth 6 + 3k.

// oat::POISSON_DISC (Oat 2006, Listing 2).
const POISSON_DISC = array<vec2<f32>, 12>(
    vec2<f32>(-0.326212, -0.40581),
    vec2<f32>(-0.840144, -0.07358),
    vec2<f32>(-0.695914, 0.457137),
    vec2<f32>(-0.203345, 0.620716),
    vec2<f32>(0.96234, -0.194983),
    vec2<f32>(0.473434, -0.480026),
    vec2<f32>(0.519456, 0.767022),
    vec2<f32>(0.185461, -0.893124),
    vec2<f32>(0.507431, 0.064425),
    vec2<f32>(0.89642, 0.412458),
    vec2<f32>(-0.32194, -0.932615),
    vec2<f32>(-0.791559, -0.59771),
);

// Texture::texel: the values of texel (i, j), 0 past the texture's channels.
fn texel(id: u32, i: u32, j: u32) -> vec3<f32> {
    let d = textures[id];
    let k = d.x + (j * d.y + i) * d.w;
    var v = vec3<f32>(0.0);
    for (var c = 0u; c < min(d.w, 3u); c++) {
        v[c] = texels[k + c];
    }
    return v;
}

// Texture::bilinear's index: the two texels around x (n of them) and the weight of the second, by the border rule.
fn bilinear_index(x: f32, n: u32) -> vec3<f32> {
    let f = x * f32(n) - 0.5;
    let i = floor(f);
    var a = vec2<f32>(i, i + 1.0);
    if op.border == 0u {
        a = clamp(a, vec2<f32>(0.0), vec2<f32>(f32(n - 1u)));
    } else {
        a = a - f32(n) * floor(a / f32(n));
    }
    return vec3<f32>(a, f - i);
}

// Texture::bilinear: interpolation between the four nearest texel centres.
fn bilinear(id: u32, uv: vec2<f32>) -> vec3<f32> {
    let d = textures[id];
    let x = bilinear_index(uv.x, d.y);
    let y = bilinear_index(uv.y, d.z);
    let i = vec2<u32>(min(vec2<u32>(x.xy), vec2<u32>(d.y - 1u)));
    let j = vec2<u32>(min(vec2<u32>(y.xy), vec2<u32>(d.z - 1u)));
    let top = mix(texel(id, i.x, j.x), texel(id, i.y, j.x), x.z);
    let bottom = mix(texel(id, i.x, j.y), texel(id, i.y, j.y), x.z);
    return mix(top, bottom, y.z);
}

// oat::parallax (Oat 2006, Listing 1): (uv_inner, s) for view v and normal n over a layer `thickness` texels deep.
fn parallax(uv: vec2<f32>, v: vec3<f32>, n: vec3<f32>, thickness: f32) -> vec3<f32> {
    let r = 2.0 * dot(v, n) * n - v;
    let t = vec3<f32>(r.x, r.y, -r.z);
    let s = thickness / max(abs(t.z), 1e-6);
    return vec3<f32>(uv + op.texel * s * t.xy, s);
}

// oat::disc_taps: tap k of the growable Poisson disc (0 the centre).
fn disc_tap(uv: vec2<f32>, radius: f32, k: u32) -> vec2<f32> {
    if k == 0u {
        return uv;
    }
    return uv + op.texel * POISSON_DISC[k - 1u] * radius;
}

// oat::poisson_filter (Oat 2006, Listing 2): the mean of the disc's 13 bilinear taps.
fn poisson_filter(id: u32, uv: vec2<f32>, radius: f32) -> vec3<f32> {
    var sum = vec3<f32>(0.0);
    for (var k = 0u; k < 13u; k++) {
        sum += bilinear(id, disc_tap(uv, radius, k));
    }
    return sum / 13.0;
}

// oat::diffuse: Lambert's radiance for a white surface of normal n at p, Σ E max(0, n·l) / π.
fn diffuse(p: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    var sum = vec3<f32>(0.0);
    for (var k = 0u; k < rp.lights; k++) {
        let light = incident(k, p);
        sum += light[1] * max(dot(n, light[0]), 0.0) * FRAC_1_PI;
    }
    return sum;
}

// oat::chart_point: the sphere's or the plane's point at uv.
fn chart_point(uv: vec2<f32>) -> Hit {
    if rp.shape == 0u {
        let phi = (uv.x - 0.5) * 2.0 * PI;
        let theta = uv.y * PI;
        let n = vec3<f32>(sin(theta) * sin(phi), cos(theta), sin(theta) * cos(phi));
        var t = cross(vec3<f32>(0.0, 1.0, 0.0), n);
        t = select(vec3<f32>(1.0, 0.0, 0.0), normalize(t), dot(t, t) > 0.0);
        return Hit(true, n, n, t, uv);
    }
    let p = vec3<f32>(2.0 * uv.x - 1.0, 1.0 - 2.0 * uv.y, 0.0);
    return Hit(true, p, vec3<f32>(0.0, 0.0, 1.0), vec3<f32>(1.0, 0.0, 0.0), uv);
}

// oat::frame: tangent space (t, t × n, n) to the world.
fn to_world(h: Hit, v: vec3<f32>) -> vec3<f32> {
    return v.x * h.t + v.y * cross(h.t, h.n) + v.z * h.n;
}

// oat::frame: the world to tangent space.
fn to_tangent(h: Hit, w: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(w, h.t), dot(w, cross(h.t, h.n)), dot(w, h.n));
}

fn unit_or_z(v: vec3<f32>) -> vec3<f32> {
    return select(vec3<f32>(0.0, 0.0, 1.0), normalize(v), dot(v, v) > 0.0);
}

// oat::normal_at: the outer normal map's normal at uv.
fn normal_at(uv: vec2<f32>) -> vec3<f32> {
    return unit_or_z(bilinear(OUTER_NORMAL, uv));
}

// oat::light_map: each texel of the chart lit through the normal map's normal at its world position. The sphere's
// and the plane's charts cover every texel, so no dilation is needed.
@compute @workgroup_size(64)
fn light_map(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let d = textures[LIGHT_MAP];
    let k = thread_index(gid, groups);
    if k >= d.y * d.z {
        return;
    }
    let uv = vec2<f32>((f32(k % d.y) + 0.5) / f32(d.y), (f32(k / d.y) + 0.5) / f32(d.z));
    let hit = chart_point(uv);
    let n = to_world(hit, unit_or_z(texel(OUTER_NORMAL, k % d.y, k / d.y)));
    let rgb = diffuse(hit.p, n);
    for (var c = 0u; c < 3u; c++) {
        texels[d.x + 3u * k + c] = rgb[c];
    }
}

fn transparency(at: vec2<f32>) -> f32 {
    if op.shadowing == 1u {
        return 1.0 - bilinear(OUTER_OPACITY, at).x;
    }
    return 1.0;
}

// oat::shade: the composite from the deepest layer up, towards the viewer wo (world).
fn shade(hit: Hit, wo: vec3<f32>) -> vec3<f32> {
    let uv = hit.uv;
    let v = to_tangent(hit, wo);
    let n = normal_at(uv);
    var outer_light = diffuse(hit.p, to_world(hit, n));
    if op.variant == 0u {
        outer_light = bilinear(LIGHT_MAP, uv);
    }
    let cos_v = clamp(dot(n, v), 0.0, 1.0);
    var below = vec3<f32>(0.0);
    for (var k = i32(op.inner) - 1; k >= 0; k--) {
        let layer = 4u + 3u * u32(k);
        let depth = bilinear(layer + 2u, uv).x;
        let shifted = parallax(uv, v, n, depth);
        let uv_k = shifted.xy;
        var light = vec3<f32>(0.0);
        if op.variant == 2u {
            light = diffuse(hit.p, hit.n) * transparency(uv_k);
        } else {
            for (var j = 0u; j < 13u; j++) {
                let tap = disc_tap(uv_k, depth, j);
                if op.variant == 0u {
                    light += bilinear(LIGHT_MAP, tap) * transparency(tap);
                } else {
                    light += diffuse(hit.p, to_world(hit, normal_at(tap))) * transparency(tap);
                }
            }
            light /= 13.0;
        }
        var base = poisson_filter(layer, uv_k, shifted.z);
        if op.variant == 2u {
            base = bilinear(layer, uv_k);
        }
        let colour = base * light;
        if textures[layer + 1u].w > 0u && u32(k) + 1u < op.inner {
            let w = (1.0 - bilinear(layer + 1u, uv_k).x) * cos_v;
            below = mix(colour, below, w);
        } else {
            below = colour;
        }
    }
    let outer = bilinear(OUTER_ALBEDO, uv) * outer_light;
    return mix(outer, below, (1.0 - bilinear(OUTER_OPACITY, uv).x) * cos_v);
}

@compute @workgroup_size(64)
fn render_oat(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let px = thread_index(gid, groups);
    if px >= rp.width * rp.height {
        return;
    }
    let ray = camera_ray(px);
    let hit = intersect(ray[0], ray[1]);
    var rgb = vec3<f32>(0.0);
    if hit.found && dot(-ray[1], hit.n) > 0.0 {
        rgb = shade(hit, -ray[1]);
    }
    store(px, rgb);
}

// Meshes (mesh.wgsl): the light map's dilation state (rgb, covered) in and out.
@group(2) @binding(3) var<storage, read> state_in: array<vec4<f32>>;
@group(2) @binding(4) var<storage, read_write> state_out: array<vec4<f32>>;

// oat::light_map for a mesh: each texel the uv pass covered, lit through the normal map's normal.
@compute @workgroup_size(64)
fn light_map_mesh(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let d = textures[LIGHT_MAP];
    let k = thread_index(gid, groups);
    if k >= d.y * d.z {
        return;
    }
    let hit = visible(textureLoad(visibility_target, vec2<u32>(k % d.y, k / d.y), 0));
    var out = vec4<f32>(0.0);
    if hit.found {
        out = vec4<f32>(diffuse(hit.p, to_world(hit, unit_or_z(texel(OUTER_NORMAL, k % d.y, k / d.y)))), 1.0);
    }
    state_out[k] = out;
}

// oat::light_map's dilation pass: an empty texel next to covered ones takes their mean.
@compute @workgroup_size(64)
fn dilate(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let d = textures[LIGHT_MAP];
    let k = thread_index(gid, groups);
    if k >= d.y * d.z {
        return;
    }
    var out = state_in[k];
    if out.w == 0.0 {
        let i = i32(k % d.y);
        let j = i32(k / d.y);
        var sum = vec4<f32>(0.0);
        for (var dj = -1; dj <= 1; dj++) {
            for (var di = -1; di <= 1; di++) {
                let a = i + di;
                let b = j + dj;
                if (di != 0 || dj != 0) && a >= 0 && b >= 0 && a < i32(d.y) && b < i32(d.z) {
                    let s = state_in[u32(b) * d.y + u32(a)];
                    if s.w > 0.0 {
                        sum += vec4<f32>(s.xyz, 1.0);
                    }
                }
            }
        }
        if sum.w > 0.0 {
            out = vec4<f32>(sum.xyz / sum.w, 1.0);
        }
    }
    state_out[k] = out;
}

// The dilated light map into its texture.
@compute @workgroup_size(64)
fn store_light_map(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let d = textures[LIGHT_MAP];
    let k = thread_index(gid, groups);
    if k >= d.y * d.z {
        return;
    }
    for (var c = 0u; c < 3u; c++) {
        texels[d.x + 3u * k + c] = state_in[k][c];
    }
}

// render_rows for a mesh: the surface the camera pass found at the pixel (camera_surface).
@compute @workgroup_size(64)
fn render_oat_mesh(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let px = thread_index(gid, groups);
    if px >= rp.width * rp.height {
        return;
    }
    let ray = camera_ray(px);
    let d = ray[1];
    let hit = camera_surface(px, ray[0], d);
    var rgb = vec3<f32>(0.0);
    if hit.found && dot(-d, hit.n) > 0.0 {
        rgb = shade(hit, -d);
    }
    store(px, rgb);
}
