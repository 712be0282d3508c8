// model="albedo_scaling" on the GPU (src/models/albedo_scaling.rs): each interface's single-scattering lobe, and
// what lies beneath it scaled by 1 − E(μ) (lamina's FGD table) and the slab's Beer–Lambert transmittance, the layers
// below evaluated at the same outside directions. Composed after optics.wgsl and layers.wgsl.

struct Params {
    n: u32,
    channels: u32,
    layers: u32,
    g2: u32,
    reciprocal: u32,
    fresnel: u32,          // always exact
    fresnel_samples: u32,  // always 0: no Fresnel tables
    pad0: u32,
    fgd_dims: vec4<u32>,   // nodes of μ, α, η, √(κ / κmax)
    eta_min: f32,
    eta_max: f32,
    kappa_max: f32,
    layers_base: u32,  // where the stack's layers start in `layers`
}

// Every stack's parameters (one for per-element queries; one per stack in a batched render, gpu::batched) and, in
// `params`, the current thread's.
@group(0) @binding(0) var<storage, read> stack_params: array<Params>;
var<private> params: Params;
// [μ][α][η][κ]
@group(0) @binding(2) var<storage, read> fgd: array<f32>;
@group(0) @binding(3) var<storage, read> pairs: array<f32>;
@group(0) @binding(4) var<storage, read_write> out: array<f32>;

// Fgd::lookup: quadrilinear in (μ, α, log η, √(κ / κmax)).
fn fgd_lookup(mu: f32, alpha: f32, eta: f32, kappa: f32) -> f32 {
    let x = vec4<f32>(mu, alpha, log(eta / params.eta_min) / log(params.eta_max / params.eta_min), sqrt(max(kappa / params.kappa_max, 0.0)));
    let g = grid_point(x, params.fgd_dims, 4u);
    var v = 0.0;
    for (var k = 0u; k < 16u; k++) {
        v += corner_weight(g, k) * fgd[corner_index(g, k)];
    }
    return v;
}

// albedo: E(μ), the directional albedo of the interface's lobe (the Fresnel reflectance itself when smooth).
fn albedo(layer: Layer, mu: f32, ch: u32) -> f32 {
    if layer.mf.smooth_ != 0u {
        return interface_fresnel(layer, mu, ch);
    }
    return fgd_lookup(mu, sqrt(layer.mf.alpha_x * layer.mf.alpha_y), value(layer, ch, ETA), value(layer, ch, KAPPA));
}

// unreflected: 1 − E(μ), a smooth interface's without cancellation at grazing incidence.
fn unreflected(layer: Layer, mu: f32, ch: u32) -> f32 {
    if layer.mf.smooth_ != 0u {
        return interface_transmittance(layer, mu, ch);
    }
    return 1.0 - albedo(layer, mu, ch);
}

// Prepared::scale: 1 − E per direction and the slab's Beer–Lambert transmittance along the refracted directions.
fn scale(layer: Layer, wi: vec3<f32>, wo: vec3<f32>, ch: u32) -> f32 {
    let view = unreflected(layer, wo.z, ch);
    var light = 1.0;
    if params.reciprocal != 0u {
        light = unreflected(layer, wi.z, ch);
    }
    let eta = value(layer, ch, ETA);
    let down_i = refracted_up(wi, sqrt(wi.x * wi.x + wi.y * wi.y) / eta);
    let down_o = refracted_up(wo, sqrt(wo.x * wo.x + wo.y * wo.y) / eta);
    return max(light * view, 0.0) * beer_lambert(value(layer, ch, SIGMA_T), layer.thickness, down_i, down_o);
}

// Prepared::eval for channel ch; 0 below the horizon.
fn eval_channel(wi: vec3<f32>, wo: vec3<f32>, ch: u32) -> f32 {
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return 0.0;
    }
    var weight = 1.0;
    var f = 0.0;
    for (var l = 0u; l < params.layers; l++) {
        let layer = sp_layer(l);
        if layer.kind != DIELECTRIC && layer.kind != CONDUCTOR {
            return f + weight * value(layer, ch, ALBEDO) * oren_nayar_shape(layer.sigma, wi, wo);
        }
        let geo = reflection_geometry(layer.mf, params.g2, wi, wo);
        f += weight * geo.x * interface_fresnel(layer, geo.y, ch);
        if layer.kind == CONDUCTOR {
            break;
        }
        weight *= scale(layer, wi, wo, ch);
    }
    return f;
}

// Prepared::terms, the sampling part: each rough lobe by its albedo times the scales above, the diffuse base by its
// albedo, mean over channels, with the defensive cosine share.
fn proposals(wo: vec3<f32>) {
    clear_mixture();
    let share = 1.0 / f32(params.channels);
    for (var ch = 0u; ch < params.channels; ch++) {
        var weight = 1.0;
        var slot = 0u;
        for (var l = 0u; l < params.layers; l++) {
            let layer = sp_layer(l);
            if layer.kind != DIELECTRIC && layer.kind != CONDUCTOR {
                add_term(slot, COSINE, share * weight * value(layer, ch, ALBEDO), cosine_lobe());
                break;
            }
            if layer.mf.smooth_ == 0u {
                add_term(slot, REFLECTION, share * weight * albedo(layer, wo.z, ch), layer.mf);
                slot += 1u;
            }
            if layer.kind == CONDUCTOR {
                break;
            }
            weight *= scale(layer, wo, wo, ch);
        }
    }
    add_defensive_share();
}

// Prepared::specular: the Dirac reflection at wo of channel ch, from smooth interfaces seen through smooth ones.
fn specular(wo: vec3<f32>, ch: u32) -> f32 {
    if wo.z <= 0.0 {
        return 0.0;
    }
    var mirror = 0.0;
    var weight = 1.0;
    for (var l = 0u; l < params.layers; l++) {
        let layer = sp_layer(l);
        if (layer.kind != DIELECTRIC && layer.kind != CONDUCTOR) || layer.mf.smooth_ == 0u {
            break;
        }
        mirror += weight * interface_fresnel(layer, wo.z, ch);
        if layer.kind == CONDUCTOR {
            break;
        }
        weight *= scale(layer, wo, wo, ch);
    }
    return mirror;
}

// f(wi, wo) of every channel into out[base..]: the model's one evaluation, shared by the eval and render kernels.
fn eval_pair(wi: vec3<f32>, wo: vec3<f32>, base: u32) {
    for (var ch = 0u; ch < params.channels; ch++) {
        out[base + ch] = eval_channel(wi, wo, ch);
    }
}
