// model="weidlich_wilkie" on the GPU (src/models/weidlich_wilkie.rs): the single-pass walk (single_pass.wgsl) with a
// Torrance–Sparrow lobe per interface (D optionally from Elek's Beckmann table) and Weidlich–Wilkie's passage:
// Snell's law at the macro-surface, T₁₂ = 1 − F(cos θL) in, t = (1 − G) + T₂₁ G out. Composed after optics.wgsl,
// layers.wgsl and single_pass.wgsl.

struct Params {
    n: u32,
    channels: u32,
    layers: u32,
    g2: u32,
    fresnel: u32,
    eta2: u32,
    fresnel_samples: u32,  // Elek's Fresnel tables in the layers (0: none)
    precomputed: u32,      // Elek's Beckmann table
    d_size: u32,
    layers_base: u32,  // where the stack's layers start in `layers`
    pad1: u32,
    pad2: u32,
}

// Every stack's parameters (one for per-element queries; one per stack in a batched render, gpu::batched) and, in
// `params`, the current thread's.
@group(0) @binding(0) var<storage, read> stack_params: array<Params>;
var<private> params: Params;
// Elek's Beckmann table [m][u], u = cos⁸θh.
@group(0) @binding(2) var<storage, read> beckmann: array<f32>;
@group(0) @binding(3) var<storage, read> pairs: array<f32>;
@group(0) @binding(4) var<storage, read_write> out: array<f32>;

// BeckmannTable::lookup: D(cos θh, m) bilinear in (m, cos⁸θh).
fn beckmann_lookup(cos_h: f32, m: f32) -> f32 {
    let a = table_node(m, params.d_size);
    let b = table_node(pow(max(cos_h, 0.0), 8.0), params.d_size);
    let k = u32(a.i) * params.d_size + u32(b.i);
    return (1.0 - a.f) * ((1.0 - b.f) * beckmann[k] + b.f * beckmann[k + 1u])
        + a.f * ((1.0 - b.f) * beckmann[k + params.d_size] + b.f * beckmann[k + params.d_size + 1u]);
}

// Prepared::lobe: Torrance–Sparrow D G / (4 cos θi cos θo) and wi·h; precomputed, D from Elek's table for isotropic
// Beckmann interfaces.
fn lobe(layer: Layer, wi: vec3<f32>, wo: vec3<f32>) -> vec2<f32> {
    let geo = reflection_geometry(layer.mf, params.g2, wi, wo);
    let mf = layer.mf;
    if params.precomputed == 0u || geo.x == 0.0 || mf.dist != 1u || mf.alpha_x != mf.alpha_y {
        return geo;
    }
    let h = normalize(wi + wo);
    return vec2<f32>(geo.x * beckmann_lookup(h.z, mf.alpha_x) / mf_d(mf, h), geo.y);
}

// Prepared::passage: Snell's law at the macro-surface (nothing through under total internal reflection);
// T₁₂ = 1 − F(cos θL) into the layer, t = (1 − G) + T₂₁ G out of it.
fn passage(layer: Layer, wi: vec3<f32>, wo: vec3<f32>, ch: u32) -> Passage {
    let eta = value(layer, ch, ETA);
    let sin_i = sqrt(wi.x * wi.x + wi.y * wi.y) / eta;
    let sin_o = sqrt(wo.x * wo.x + wo.y * wo.y) / eta;
    if sin_i >= 1.0 || sin_o >= 1.0 {
        return Passage(0.0, 0.0, 0.0, wi, wo, false);
    }
    let t12 = interface_transmittance(layer, wi.z, ch);
    let t21 = interface_transmittance(layer, wo.z, ch);
    var g = 1.0;
    if layer.mf.smooth_ == 0u {
        g = mf_g2(layer.mf, params.g2, wi, wo, normalize(wi + wo));
    }
    return Passage(t12, (1.0 - g) + t21 * g, t21, refracted_up(wi, sin_i), refracted_up(wo, sin_o), true);
}
