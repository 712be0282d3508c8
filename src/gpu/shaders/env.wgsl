// The renderer's environment lighting on the GPU (src/render/env.rs and render::shade): an equirectangular radiance
// map importance-sampled by its piecewise-constant 2D distribution, combined with the model's BSDF sampling
// (sample.wgsl and the model's `proposals`) by multiple importance sampling, `spp` samples per pixel, plus the Dirac
// reflection of smooth interfaces towards the mirror direction and the directional and point lights. Statistically,
// not sample by sample, the CPU renderer's estimator: the random streams differ. Composed after render.wgsl.

struct EnvParams {
    width: u32,
    height: u32,
    spp: u32,
    seed: u32,
    rotation: f32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(3) @binding(0) var<uniform> ep: EnvParams;
// Row-major RGB radiance, 3 values per texel (already scaled).
@group(3) @binding(1) var<storage, read> env_rgb: array<f32>;
// The 1D distributions (Pdf1), each as n values of the function, its n + 1 CDF values and its integral: first the
// marginal over the rows (n = height), then each row's (n = width).
@group(3) @binding(2) var<storage, read> dists: array<f32>;

const TAU: f32 = 6.28318530717959;

// A PCG hash (Jarzynski & Olano 2020): the pixel's random stream.
fn pcg(v: u32) -> u32 {
    let state = v * 747796405u + 2891336453u;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

// A uniform number in [0, 1) from the stream `state`, which it advances.
fn next_uniform(state: ptr<function, u32>) -> f32 {
    *state = pcg(*state);
    return f32(*state >> 8u) * 5.9604645e-8;
}

fn row_offset(j: u32) -> u32 {
    return 2u * ep.height + 2u + j * (2u * ep.width + 2u);
}

// Pdf1::density of bin i of the distribution at `at` with n bins.
fn pdf1_density(at: u32, n: u32, i: u32) -> f32 {
    let integral = dists[at + 2u * n + 1u];
    if integral > 0.0 {
        return dists[at + i] / integral;
    }
    return 1.0;
}

// Pdf1::sample: a continuous sample in [0, 1) and its density.
fn pdf1_sample(at: u32, n: u32, u: f32) -> vec2<f32> {
    let cdf = at + n;
    var lo = 0u;
    var hi = n + 1u;
    while lo < hi {
        let mid = (lo + hi) / 2u;
        if dists[cdf + mid] <= u {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    let i = clamp(lo, 1u, n) - 1u;
    let width = dists[cdf + i + 1u] - dists[cdf + i];
    var du = 0.5;
    if width > 0.0 {
        du = (u - dists[cdf + i]) / width;
    }
    return vec2<f32>((f32(i) + clamp(du, 0.0, 1.0)) / f32(n), pdf1_density(at, n, i));
}

// Environment::uv: map coordinates of the world direction d.
fn env_uv(d: vec3<f32>) -> vec2<f32> {
    let phi = atan2(d.x, -d.z) + ep.rotation;
    return vec2<f32>(fract(phi / TAU + 0.5), acos(clamp(d.y, -1.0, 1.0)) / PI);
}

// Environment::direction: the world direction of map coordinates (u, v).
fn env_direction(u: f32, v: f32) -> vec3<f32> {
    let phi = TAU * (u - 0.5) - ep.rotation;
    let theta = PI * v;
    return vec3<f32>(sin(theta) * sin(phi), cos(theta), -sin(theta) * cos(phi));
}

// Environment::texel
fn env_texel(uv: vec2<f32>) -> vec2<u32> {
    return vec2<u32>(min(u32(uv.x * f32(ep.width)), ep.width - 1u), min(u32(uv.y * f32(ep.height)), ep.height - 1u));
}

// Environment::radiance: the radiance arriving from d (nearest texel).
fn env_radiance(d: vec3<f32>) -> vec3<f32> {
    let t = env_texel(env_uv(d));
    let k = 3u * (t.y * ep.width + t.x);
    return vec3<f32>(env_rgb[k], env_rgb[k + 1u], env_rgb[k + 2u]);
}

// Environment::sample: a world direction with density ∝ luminance, and its pdf per unit solid angle (w).
fn env_sample(u1: f32, u2: f32) -> vec4<f32> {
    let v = pdf1_sample(0u, ep.height, u1);
    let j = env_texel(vec2<f32>(0.0, v.x)).y;
    let u = pdf1_sample(row_offset(j), ep.width, u2);
    let sin_theta = sin(PI * v.x);
    var pdf = 0.0;
    if sin_theta > 0.0 {
        pdf = u.y * v.y / (2.0 * PI * PI * sin_theta);
    }
    return vec4<f32>(env_direction(u.x, v.x), pdf);
}

// Environment::pdf: the density of env_sample at the world direction d.
fn env_pdf(d: vec3<f32>) -> f32 {
    let uv = env_uv(d);
    let t = env_texel(uv);
    let sin_theta = sin(PI * uv.y);
    if sin_theta <= 0.0 {
        return 0.0;
    }
    return pdf1_density(0u, ep.height, t.y) * pdf1_density(row_offset(t.y), ep.width, t.x) / (2.0 * PI * PI * sin_theta);
}

// sampling::power_heuristic: β = 2 (Veach 1997 eq. 9.13).
fn power_heuristic(pdf: f32, other: f32) -> f32 {
    if pdf <= 0.0 {
        return 0.0;
    }
    return pdf * pdf / (pdf * pdf + other * other);
}

// render::shade with an environment: the lights, the Dirac reflection of the mirror direction, and spp samples of
// the environment and of the BSDF combined by MIS, at a hit seen along d. Every direction is evaluated at one call of
// eval_pair (scratch at `base`), so that the model's code is compiled into the kernel once.
fn shade_env(hit: Hit, d: vec3<f32>, base: u32, px: u32) -> vec3<f32> {
    load_texture_inputs(hit.uv);
    var rgb = vec3<f32>(0.0);
    let b = cross(hit.n, hit.t);
    let wo = vec3<f32>(dot(-d, hit.t), dot(-d, b), dot(-d, hit.n));
    if wo.z <= 0.0 {
        return rgb;
    }
    let mirror = env_radiance(-wo.x * hit.t - wo.y * b + wo.z * hit.n);
    for (var ch = 0u; ch < 3u; ch++) {
        rgb[ch] += specular(wo, ch) * mirror[ch];
    }
    fitted_proposals(wo);
    var state = pcg(ep.seed ^ pcg(px));
    let spp = max(ep.spp, 1u);
    // Directions 0 .. lights are the lights; then per sample the environment's, then the BSDF's.
    for (var k = 0u; k < rp.lights + 2u * spp; k++) {
        var wi = vec3<f32>(0.0, 0.0, 1.0);
        var scale = vec3<f32>(0.0);
        if k < rp.lights {
            let light = incident(k, hit.p);
            wi = vec3<f32>(dot(light[0], hit.t), dot(light[0], b), dot(light[0], hit.n));
            scale = light[1] * max(wi.z, 0.0);
        } else if (k - rp.lights) % 2u == 0u {
            let light = env_sample(next_uniform(&state), next_uniform(&state));
            wi = vec3<f32>(dot(light.xyz, hit.t), dot(light.xyz, b), dot(light.xyz, hit.n));
            if wi.z > 0.0 && light.w > 0.0 {
                let w = power_heuristic(light.w, mixture_pdf(wi, wo));
                scale = env_radiance(light.xyz) * (wi.z * w / (light.w * f32(spp)));
            }
        } else {
            let u = vec3<f32>(next_uniform(&state), next_uniform(&state), next_uniform(&state));
            let sampled = sample_mixture(wo, u);
            wi = sampled.xyz;
            if sampled.w > 0.0 {
                let dir = wi.x * hit.t + wi.y * b + wi.z * hit.n;
                let w = power_heuristic(sampled.w, env_pdf(dir));
                scale = env_radiance(dir) * (weight_factor(wi, sampled.w) * w / f32(spp));
            }
        }
        if wi.z > 0.0 && any(scale != vec3<f32>(0.0)) {
            eval_fitted(wi, wo, base);
            rgb += vec3<f32>(out[base], out[base + 1u], out[base + 2u]) * scale;
        }
    }
    return rgb;
}

// The sphere or the plane under an environment (seen where the camera ray misses).
@compute @workgroup_size(64)
fn render_env(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let t = thread_index(gid, groups);
    let px = begin(t);
    if px == rp.width * rp.height {
        return;
    }
    let ray = camera_ray(px);
    let hit = intersect(ray[0], ray[1]);
    var rgb = env_radiance(ray[1]);
    if hit.found {
        rgb = shade_env(hit, ray[1], t * params.channels, px);
    }
    store(t, rgb);
}

// A mesh under an environment.
@compute @workgroup_size(64)
fn render_mesh_env(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let t = thread_index(gid, groups);
    let px = begin(t);
    if px == rp.width * rp.height {
        return;
    }
    let ray = camera_ray(px);
    let d = ray[1];
    let hit = camera_surface(px, ray[0], d);
    var rgb = env_radiance(d);
    if hit.found {
        rgb = shade_env(hit, d, t * params.channels, px);
    }
    store(t, rgb);
}
