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
    group: u32,            // channels a pass walks at once (single_pass.wgsl)
    // The patina form (Patina; patina 0: none): from layers_base, where its walk's layers (the stack unclamped), the
    // bare surface's (the base alone) and the tint per channel (tints values) start in `layers`; the smoothstep's
    // extent and transition, the bare top roughness and Elek's roughness clamp.
    patina: u32,
    patina_at: u32,
    bare_at: u32,
    tint_at: u32,
    tints: u32,
    extent: f32,
    transition: f32,
    bare_alpha_x: f32,
    bare_alpha_y: f32,
    clamp: u32,
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

// Prepared::eval_block: the walk, its base tilted by a car-paint flake (`flake_normal`, `distance`), or the patina's
// blend where a `mask` covers the surface.
fn eval_pair(wi: vec3<f32>, wo: vec3<f32>, base: u32) {
    walk_state = WalkState();
    if input_given(0u) {
        // normalize(flake + max(distance, 1) ẑ); a base tilted below the horizon reflects nothing.
        let d = select(1.0, max(input(1u).x, 1.0), input_given(1u));
        let m = normalize(input(0u) + vec3<f32>(0.0, 0.0, d));
        walk_state.normal = select(vec3<f32>(0.0, 0.0, -1.0), m, m.z > 0.0);
    }
    if input_given(2u) && params.patina != 0u {
        eval_patina(wi, wo, base, input(2u).x);
    } else {
        eval_walk(wi, wo, base);
    }
}

// weidlich_wilkie::smoothstep: GLSL's, 0 below a, 1 above b (a step where b ≤ a).
fn smoothstep_ww(a: f32, b: f32, x: f32) -> f32 {
    if b <= a {
        return select(1.0, 0.0, x < a);
    }
    let t = clamp((x - a) / (b - a), 0.0, 1.0);
    return t * t * (3.0 - 2.0 * t);
}

// Patina::eval: (1 − w) f_bare + w f_patina, w = 1 − smoothstep(extent − transition, extent + transition, mask), the
// patina's roughness and IOR interpolated from the bare surface's with w and the base tinted by 1 + w (tint − 1).
fn eval_patina(wi: vec3<f32>, wo: vec3<f32>, base: u32, mask: f32) {
    let w = 1.0 - smoothstep_ww(params.extent - params.transition, params.extent + params.transition, mask);
    let stack = params;
    var bare = stack;
    bare.layers_base = stack.layers_base + stack.bare_at;
    bare.layers = 1u;
    var patina = stack;
    patina.layers_base = stack.layers_base + stack.patina_at;
    patina.layers = 2u;
    params = patina;
    let top = sp_layer(0u).mf;
    let b = sp_layer(1u).mf;
    var own = vec2<f32>(0.0);
    if top.smooth_ == 0u {
        own = vec2<f32>(top.alpha_x, top.alpha_y);
    }
    let bare_alpha = vec2<f32>(stack.bare_alpha_x, stack.bare_alpha_y);
    let alpha = bare_alpha + w * (own - bare_alpha);
    var covered = walk_state;
    covered.patina = 1u;
    covered.w = w;
    covered.top_mf = mf_with_alpha(top, alpha.x, alpha.y);
    covered.base_mf = b;
    if stack.clamp != 0u && b.smooth_ == 0u {
        covered.base_mf = mf_with_alpha(b, max(b.alpha_x, alpha.x), max(b.alpha_y, alpha.y));
    }
    covered.tint_at = stack.layers_base + stack.tint_at;
    covered.tints = stack.tints;
    let uncovered = walk_state;
    for (var c0 = 0u; c0 < stack.channels; c0 += stack.group) {
        let lanes = min(stack.group, stack.channels - c0);
        var f = vec4<f32>(0.0);
        if w < 1.0 {
            params = bare;
            walk_state = uncovered;
            f = (1.0 - w) * walk(wi, wo, c0, lanes);
        }
        if w > 0.0 {
            params = patina;
            walk_state = covered;
            f += w * walk(wi, wo, c0, lanes);
        }
        for (var k = 0u; k < lanes; k++) {
            out[base + c0 + k] = f[k];
        }
    }
    params = stack;
}
