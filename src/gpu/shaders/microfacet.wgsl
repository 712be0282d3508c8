// model="microfacet" on the GPU (src/models/microfacet.rs): a rough conductor, Lambert / Oren–Nayar, or a smooth
// coat over Lambert, f(wi, wo) for n direction pairs and every channel. Composed after optics.wgsl.

struct Params {
    kind: u32,      // 0 conductor, 1 diffuse, 2 smooth coat over Lambert
    g2: u32,        // Microfacet::g2 form
    fresnel: u32,   // FresnelForm
    channels: u32,
    n: u32,         // pairs in this dispatch
    sigma: f32,     // Oren–Nayar σ (kind 1)
    pad0: u32,
    pad1: u32,
    mf: Microfacet,
    base: u32,      // where the stack's rows start in `channel`
    pad2: u32,
}

// Every stack's parameters (one for per-element queries; one per stack in a batched render, gpu::batched) and, in
// `params`, the current thread's.
@group(0) @binding(0) var<storage, read> stack_params: array<Params>;
var<private> params: Params;
// Per channel: (eta, k, albedo, f_int): the Prepared variant's values (unused ones 0).
@group(0) @binding(1) var<storage, read> channel: array<f32>;
// Per pair: wi then wo (xyz each, unit).
@group(0) @binding(2) var<storage, read> pairs: array<f32>;
@group(0) @binding(3) var<storage, read_write> out: array<f32>;

// Channel ch's row of `channel`.
fn channel_row(ch: u32) -> vec4<f32> {
    let k = params.base + 4u * ch;
    return vec4<f32>(channel[k], channel[k + 1u], channel[k + 2u], channel[k + 3u]);
}

// microfacet::smooth_coat_lambert: smooth dielectric coat over Lambert, all internal bounces (Weidlich–Wilkie 2007).
fn smooth_coat_lambert(albedo: f32, eta: f32, f_int: f32, cos_i: f32, cos_o: f32) -> f32 {
    let t = fresnel_dielectric_transmittance(cos_i, eta) * fresnel_dielectric_transmittance(cos_o, eta);
    return albedo * t * FRAC_1_PI / (eta * eta * (1.0 - albedo * f_int));
}

// Prepared::proposals: the conductor's lobe (none when smooth), or the cosine.
fn proposals(wo: vec3<f32>) {
    clear_mixture();
    if params.kind == 0u {
        if params.mf.smooth_ == 0u {
            add_term(0u, REFLECTION, 1.0, params.mf);
        }
    } else {
        add_term(0u, COSINE, 1.0, cosine_lobe());
    }
}

// Prepared::specular: the Dirac reflection of a smooth conductor or of the smooth coat, channel ch.
fn specular(wo: vec3<f32>, ch: u32) -> f32 {
    if wo.z <= 0.0 {
        return 0.0;
    }
    let p = channel_row(ch);
    if params.kind == 0u && params.mf.smooth_ != 0u {
        return fresnel_form_conductor(params.fresnel, wo.z, p.x, p.y);
    }
    if params.kind == 2u {
        return fresnel_dielectric(wo.z, p.x);
    }
    return 0.0;
}

// f(wi, wo) of every channel into out[base..]: the model's one evaluation, shared by the eval and render kernels.
fn eval_pair(wi: vec3<f32>, wo: vec3<f32>, base: u32) {
    let above = wi.z > 0.0 && wo.z > 0.0;
    let geo = reflection_geometry(params.mf, params.g2, wi, wo);
    let shape = oren_nayar_shape(params.sigma, wi, wo);
    for (var c = 0u; c < params.channels; c++) {
        let p = channel_row(c);
        var f = 0.0;
        if above {
            switch params.kind {
                case 0u: { f = geo.x * fresnel_form_conductor(params.fresnel, geo.y, p.x, p.y); }
                case 1u: { f = p.z * shape; }
                default: { f = smooth_coat_lambert(p.z, p.x, p.w, wi.z, wo.z); }
            }
        }
        out[base + c] = f;
    }
}
