// model="belcour" on the GPU (src/models/belcour): the tabulated adding-doubling interpolated per pair, one GGX lobe
// per interface and the diffuse base, as the CPU's block evaluator (table.rs) does. Composed after optics.wgsl.

struct Params {
    n: u32,
    channels: u32,
    lobes: u32,
    nodes: u32,
    azimuths: u32,
    width: u32,
    g2: u32,
    symmetric: u32,
    has_diffuse: u32,
    diffuse_eta: f32,
    pad0: u32,
    pad1: u32,
    // Where the stack's values start in record, t_down, t_up and diffuse.
    record_base: u32,
    t_down_base: u32,
    t_up_base: u32,
    diffuse_base: u32,
}

// Every stack's parameters (one for per-element queries; one per stack in a batched render, gpu::batched) and, in
// `params`, the current thread's.
@group(0) @binding(0) var<storage, read> stack_params: array<Params>;
var<private> params: Params;
// [node][azimuth][lobe][width]: roughness (1 value, or the roughness matrix xx, xy, yy), then energy per channel.
@group(0) @binding(1) var<storage, read> record: array<f32>;
// [node][azimuth][channel]: energy transmitted down to the base and up from it.
@group(0) @binding(2) var<storage, read> t_down: array<f32>;
@group(0) @binding(3) var<storage, read> t_up: array<f32>;
// Per channel: (albedo, R̄↑) of the diffuse base.
@group(0) @binding(4) var<storage, read> diffuse: array<f32>;
@group(0) @binding(5) var<storage, read> pairs: array<f32>;
@group(0) @binding(6) var<storage, read_write> out: array<f32>;

const FRAC_PI_2: f32 = 1.5707963267949;
const FRAC_PI_4: f32 = 0.785398163397448;

// table::pseudo_angle: a monotonic stand-in for the azimuth modulo π (Rajan et al. 2006), in [0, π).
fn pseudo_angle(x_in: f32, y_in: f32) -> f32 {
    var x = x_in;
    var y = y_in;
    if y < 0.0 {
        x = -x;
        y = -y;
    }
    let big = max(abs(x), y);
    if big == 0.0 {
        return 0.0;
    }
    let t = min(abs(x), y) / big;
    var a = t * (FRAC_PI_4 + 0.273 * (1.0 - t));
    if y > abs(x) {
        a = FRAC_PI_2 - a;
    }
    var p = a;
    if x < 0.0 {
        p = PI - a;
    }
    if p >= PI {
        return 0.0;
    }
    return p;
}

struct Corners {
    index: vec4<i32>,
    weight: vec4<f32>,
}

// Prepared::corners: bilinear corners in √cos θ and the azimuth's pseudo-angle (isotropic tables: two corners).
fn corners(cos_theta: f32, x: f32, y: f32) -> Corners {
    let az = i32(params.azimuths);
    var v = 0.0;
    if az > 1 {
        v = pseudo_angle(x, y) * (FRAC_1_PI * f32(az));
    }
    let node = table_node(sqrt(clamp(cos_theta, 0.0, 1.0)), params.nodes);
    let k = node.i;
    let fk = node.f;
    let a = min(i32(v), az - 1);
    let fa = v - f32(a);
    var b = a + 1;
    if b == az {
        b = 0;
    }
    return Corners(
        vec4<i32>(k * az + a, (k + 1) * az + a, k * az + b, (k + 1) * az + b),
        vec4<f32>((1.0 - fk) * (1.0 - fa), fk * (1.0 - fa), (1.0 - fk) * fa, fk * fa),
    );
}

// Cov::eigen_frame: (λ1, λ2, cos, sin) of a symmetric 2x2 matrix, the eigenvector of λ1 ≥ λ2 as (cos, sin).
fn eigen_frame(xx: f32, xy: f32, yy: f32) -> vec4<f32> {
    let mean = 0.5 * (xx + yy);
    let half = 0.5 * (xx - yy);
    let r = sqrt(half * half + xy * xy);
    var x = xy;
    var y = r - half;
    if half >= 0.0 {
        x = half + r;
        y = xy;
    }
    if x < 0.0 {
        x = -x;
        y = -y;
    }
    let len = sqrt(x * x + y * y);
    if r > 0.0 {
        return vec4<f32>(mean + r, mean - r, x / len, y / len);
    }
    return vec4<f32>(mean, mean, 1.0, 0.0);
}

// Microfacet::with_frame: GGX of roughness (αx, αy) along the frame (cos, sin); (0, 0) is a Dirac interface.
fn ggx(ax: f32, ay: f32, cos_phi: f32, sin_phi: f32) -> Microfacet {
    return mf_with_alpha(Microfacet(0u, 0u, 0.0, 0.0, cos_phi, sin_phi), ax, ay);
}

// symmetric_cosine: |wo·h| (Belcour 2018 §6), wo·n where wi + wo is too short to normalise.
fn symmetric_cosine(wi: vec3<f32>, wo: vec3<f32>) -> f32 {
    let s = wi + wo;
    if dot(s, s) == 0.0 {
        return wo.z;
    }
    return abs(dot(wo, normalize(s)));
}

// The value at `offset` of a record (lobe j's values at offset j·width + i), interpolated at the corners.
fn interpolate(c: Corners, offset: u32) -> f32 {
    let w = params.lobes * params.width;
    var v = 0.0;
    for (var q = 0; q < 4; q++) {
        v += c.weight[q] * record[params.record_base + u32(c.index[q]) * w + offset];
    }
    return v;
}

// Channel ch's (albedo, R̄↑) of the diffuse base.
fn diffuse_row(ch: u32) -> vec2<f32> {
    let k = params.diffuse_base + 2u * ch;
    return vec2<f32>(diffuse[k], diffuse[k + 1u]);
}

// T↓ or T↑ of channel ch at the corners.
fn transmitted(c: Corners, down: bool, ch: u32) -> f32 {
    var v = 0.0;
    for (var q = 0; q < 4; q++) {
        let k = u32(c.index[q]) * params.channels + ch;
        v += c.weight[q] * select(t_up[params.t_up_base + k], t_down[params.t_down_base + k], down);
    }
    return v;
}

// Lobe j of the table interpolated at the corners: its GGX microfacet and where its energies start in the record.
struct TableLobe {
    mf: Microfacet,
    energy: u32,
}

fn table_lobe(c: Corners, j: u32) -> TableLobe {
    let at = j * params.width;
    if params.azimuths > 1u {
        let e = eigen_frame(interpolate(c, at), interpolate(c, at + 1u), interpolate(c, at + 2u));
        return TableLobe(ggx(e.x, e.y, e.z, e.w), at + 3u);
    }
    let a = interpolate(c, at);
    return TableLobe(ggx(a, a, 1.0, 0.0), at + 1u);
}

// Prepared::proposals: the table's lobes at wo, each by its mean energy (none when smooth), and the diffuse base by
// ρ T↑² / (1 − ρ R̄↑).
fn proposals(wo: vec3<f32>) {
    clear_mixture();
    let c = corners(wo.z, wo.x, wo.y);
    for (var j = 0u; j < params.lobes; j++) {
        let lobe = table_lobe(c, j);
        if lobe.mf.smooth_ == 0u {
            var energy = 0.0;
            for (var ch = 0u; ch < params.channels; ch++) {
                energy += interpolate(c, lobe.energy + ch);
            }
            add_term(lobe_count, REFLECTION, energy / f32(params.channels), lobe.mf);
        }
    }
    if params.has_diffuse != 0u {
        var energy = 0.0;
        for (var ch = 0u; ch < params.channels; ch++) {
            let d = diffuse_row(ch);
            let t = transmitted(c, false, ch);
            energy += d.x * t * t / (1.0 - d.x * d.y);
        }
        add_term(lobe_count, COSINE, energy / f32(params.channels), cosine_lobe());
    }
    keep_terms_with_energy();
}

// Prepared::specular: the energies of the smooth lobes at wo, channel ch.
fn specular(wo: vec3<f32>, ch: u32) -> f32 {
    if wo.z <= 0.0 {
        return 0.0;
    }
    let c = corners(wo.z, wo.x, wo.y);
    var mirror = 0.0;
    for (var j = 0u; j < params.lobes; j++) {
        let lobe = table_lobe(c, j);
        if lobe.mf.smooth_ != 0u {
            mirror += interpolate(c, lobe.energy + ch);
        }
    }
    return mirror;
}

// f(wi, wo) of every channel into out[base..]: the model's one evaluation, shared by the eval and render kernels.
fn eval_pair(wi: vec3<f32>, wo: vec3<f32>, base: u32) {
    for (var ch = 0u; ch < params.channels; ch++) {
        out[base + ch] = 0.0;
    }
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return;
    }
    var cos_theta = wo.z;
    if params.symmetric != 0u {
        cos_theta = symmetric_cosine(wi, wo);
    }
    let c = corners(cos_theta, wo.x, wo.y);
    for (var j = 0u; j < params.lobes; j++) {
        let lobe = table_lobe(c, j);
        let shape = reflection_geometry(lobe.mf, params.g2, wi, wo).x;
        for (var ch = 0u; ch < params.channels; ch++) {
            out[base + ch] += interpolate(c, lobe.energy + ch) * shape;
        }
    }
    if params.has_diffuse != 0u {
        // Prepared::add_diffuse: ρ/π · T↓(θi) T↑(θo) / ((1 − ρ R̄↑) η²).
        let down = corners(wi.z, wi.x, wi.y);
        var up = c;
        if params.symmetric != 0u {
            up = corners(wo.z, wo.x, wo.y);
        }
        let eta2 = params.diffuse_eta * params.diffuse_eta;
        for (var ch = 0u; ch < params.channels; ch++) {
            let d = diffuse_row(ch);
            out[base + ch] += d.x * FRAC_1_PI * transmitted(down, true, ch) * transmitted(up, false, ch) / ((1.0 - d.x * d.y) * eta2);
        }
    }
}
