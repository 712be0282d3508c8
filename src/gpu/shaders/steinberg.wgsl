// model="steinberg" on the GPU (src/models/steinberg.rs): the single-pass walk (single_pass.wgsl) with a
// Cook–Torrance GGX lobe per interface and Steinberg's passage, t(wi) t(wo) and the mean refracted directions from
// lamina's tables (src/tables/steinberg.rs), tabulated or fitted. Composed after optics.wgsl, layers.wgsl and
// single_pass.wgsl.

struct Params {
    n: u32,
    channels: u32,
    layers: u32,
    g2: u32,
    fresnel: u32,
    eta2: u32,
    fitted: u32,
    n_mu: u32,
    n_alpha: u32,
    n_eta: u32,
    eta_min: f32,
    eta_max: f32,
    fresnel_samples: u32,  // 0: no Fresnel tables
    layers_base: u32,      // where the stack's layers start in `layers`
    microfacet_transmission: u32,
    group: u32,            // channels a pass walks at once (single_pass.wgsl)
}

// Every stack's parameters (one for per-element queries; one per stack in a batched render, gpu::batched) and, in
// `params`, the current thread's.
@group(0) @binding(0) var<storage, read> stack_params: array<Params>;
var<private> params: Params;
// [μ][α][η][t, s / sin θ, p, T]
@group(0) @binding(2) var<storage, read> table: array<f32>;
// [α][η][a, b, c, d, m, a₁, a₂, b₁, b₂]
@group(0) @binding(3) var<storage, read> fits: array<f32>;
@group(0) @binding(4) var<storage, read> pairs: array<f32>;
@group(0) @binding(5) var<storage, read_write> out: array<f32>;

const STRIDE: u32 = 4u;
const FIT: u32 = 9u;

// tables::steinberg::eta_coord: η's coordinate on the table's logarithmic axis.
fn eta_coord(eta: f32) -> f32 {
    return log(eta / params.eta_min) / log(params.eta_max / params.eta_min);
}

// Steinberg::tabulated: (t, s) trilinear in (μ, α, log η), s through s / sin θ.
fn tabulated(mu: f32, alpha: f32, eta: f32) -> vec2<f32> {
    let dims = vec4<u32>(params.n_mu, params.n_alpha, params.n_eta, 1u);
    let g = grid_point(vec4<f32>(mu, alpha, eta_coord(eta), 0.0), dims, 3u);
    var ts = vec2<f32>(0.0);
    for (var k = 0u; k < 8u; k++) {
        let i = corner_index(g, k) * STRIDE;
        ts += corner_weight(g, k) * vec2<f32>(table[i], table[i + 1u]);
    }
    return vec2<f32>(ts.x, min(ts.y * sqrt(max(1.0 - mu * mu, 0.0)), 1.0));
}

// Steinberg::transmitted: T trilinear in (μ, α, log η), clamped to [0, 1].
fn transmitted(mu: f32, alpha: f32, eta: f32) -> f32 {
    let dims = vec4<u32>(params.n_mu, params.n_alpha, params.n_eta, 1u);
    let g = grid_point(vec4<f32>(mu, alpha, eta_coord(eta), 0.0), dims, 3u);
    var t = 0.0;
    for (var k = 0u; k < 8u; k++) {
        t += corner_weight(g, k) * table[corner_index(g, k) * STRIDE + 3u];
    }
    return clamp(t, 0.0, 1.0);
}

// tables::steinberg::t_model: m((erf(aμ − b) + 1) + cμ) + d, and s_model: a₁e^{a₂μ} + b₁e^{b₂μ}, of fit record k.
fn fitted_node(k: u32, mu: f32) -> vec2<f32> {
    let p = k * FIT;
    let t = fits[p + 4u] * ((erf(fits[p] * mu - fits[p + 1u]) + 1.0) + fits[p + 2u] * mu) + fits[p + 3u];
    let s = fits[p + 5u] * exp(fits[p + 6u] * mu) + fits[p + 7u] * exp(fits[p + 8u] * mu);
    return vec2<f32>(t, s);
}

// Steinberg::fitted: (t, s) of the fitted closed forms, bilinear in (α, log η), clamped to [0, 1].
fn fitted(mu: f32, alpha: f32, eta: f32) -> vec2<f32> {
    let j = table_node(alpha, params.n_alpha);
    let e = table_node(eta_coord(eta), params.n_eta);
    let k = u32(j.i) * params.n_eta + u32(e.i);
    let ts = (1.0 - j.f) * ((1.0 - e.f) * fitted_node(k, mu) + e.f * fitted_node(k + 1u, mu))
        + j.f * ((1.0 - e.f) * fitted_node(k + params.n_eta, mu) + e.f * fitted_node(k + params.n_eta + 1u, mu));
    return clamp(ts, vec2<f32>(0.0), vec2<f32>(1.0));
}

// Prepared::lobe: the Cook–Torrance GGX lobe's D G2 / (4 cos θi cos θo) and wi·h.
fn lobe(layer: Layer, wi: vec3<f32>, wo: vec3<f32>) -> vec2<f32> {
    return reflection_geometry(layer.mf, params.g2, wi, wo);
}

// Prepared::passage's lookup: (t, s) of direction w at its projected roughness, T for t with microfacet_transmission.
fn transmission(mf: Microfacet, w: vec3<f32>, eta: f32) -> vec2<f32> {
    var alpha = 0.0;
    if mf.smooth_ == 0u {
        alpha = mf_projected_alpha(mf, w);
    }
    var ts: vec2<f32>;
    if params.fitted != 0u {
        ts = fitted(w.z, alpha, eta);
    } else {
        ts = tabulated(w.z, alpha, eta);
    }
    if params.microfacet_transmission != 0u {
        ts.x = transmitted(w.z, alpha, eta);
    }
    return ts;
}

// Prepared::passage: t(wo) t(wi) and the mean refracted directions.
fn passage(layer: Layer, wi: vec3<f32>, wo: vec3<f32>, ch: u32) -> Passage {
    let eta = value(layer, ch, ETA);
    let i = transmission(layer.mf, wi, eta);
    let o = transmission(layer.mf, wo, eta);
    return Passage(i.x, o.x, o.x, refracted_up(wi, i.y), refracted_up(wo, o.y), true);
}

// f(wi, wo) of every channel into out[base..]: the walk.
fn eval_pair(wi: vec3<f32>, wo: vec3<f32>, base: u32) {
    eval_walk(wi, wo, base);
}
