// The single-pass layers on the GPU (src/models/common/single_pass.rs): the stack's interfaces, slabs and base, their
// Fresnel terms and the slabs' refraction and Beer–Lambert attenuation, shared by the single-pass walk
// (single_pass.wgsl) and albedo scaling. Composed after optics.wgsl and before the model's shader, which declares
// `params` (channels, fresnel, fresnel_samples, layers_base).

// The layers as gpu::single_pass_layers writes them: per layer a header of HEADER values, then per channel
// PER_CHANNEL values (η, κ, σt, albedo, gain, and a conductor base's inter-reflection albedo at INTERREFLECTION_NODES
// cosines) and Elek's Fresnel table, (F, 1 − F) at each of params.fresnel_samples nodes (none without).
@group(0) @binding(1) var<storage, read> layers: array<f32>;

const HEADER: u32 = 10u;
const INTERREFLECTION_NODES: u32 = 8u;  // single_pass::INTERREFLECTION_NODES
const PER_CHANNEL: u32 = 5u + INTERREFLECTION_NODES;
const DIELECTRIC: u32 = 0u;
const CONDUCTOR: u32 = 1u;

struct Layer {
    kind: u32,
    mf: Microfacet,
    thickness: f32,
    sigma: f32,     // Oren–Nayar σ of a diffuse base
    mean_eta: f32,  // η's mean over the channels (the sampling mixture refracts at it)
    at: u32,        // where its channel values start
    // Under a patina (single_pass.wgsl's walk state): PATINA_TOP or PATINA_BASE, the patina's coverage w and where
    // the top's channel values start; PLAIN and 1 otherwise.
    role: u32,
    w: f32,
    top_at: u32,
}

const PLAIN: u32 = 0u;
const PATINA_TOP: u32 = 1u;
const PATINA_BASE: u32 = 2u;

// SpLayer: layer l of the stack.
fn sp_layer(l: u32) -> Layer {
    let at = params.layers_base + l * (HEADER + channel_stride() * params.channels);
    let mf = Microfacet(u32(layers[at + 1u]), u32(layers[at + 2u]), layers[at + 3u], layers[at + 4u], layers[at + 5u], layers[at + 6u]);
    return Layer(u32(layers[at]), mf, layers[at + 7u], layers[at + 8u], layers[at + 9u], at + HEADER, PLAIN, 1.0, 0u);
}

// Per-channel values of a layer: η, κ, σt, albedo (single-scattering, or the diffuse base's), gain.
const ETA: u32 = 0u;
const KAPPA: u32 = 1u;
const SIGMA_T: u32 = 2u;
const ALBEDO: u32 = 3u;
const GAIN: u32 = 4u;
const INTERREFLECTED: u32 = 5u;

fn channel_stride() -> u32 {
    return PER_CHANNEL + 2u * params.fresnel_samples;
}

// Under a patina of coverage w (weidlich_wilkie::Patina::eval) the top's relative η goes from 1 (no layer) to its own,
// 1 + w (η − 1), and the base's η and κ follow the medium above: × η_top / (1 + w (η_top − 1)).
fn value(layer: Layer, ch: u32, which: u32) -> f32 {
    let v = layers[layer.at + ch * channel_stride() + which];
    if layer.role == PATINA_TOP && which == ETA {
        return 1.0 + layer.w * (v - 1.0);
    }
    if layer.role == PATINA_BASE && (which == ETA || which == KAPPA) {
        let e = layers[layer.top_at + ch * channel_stride() + ETA];
        return v * e / (1.0 + layer.w * (e - 1.0));
    }
    return v;
}

// single_pass::node_lerp of a conductor base's inter-reflection table g (0 without the correction): linear between its
// nodes; under a patina, scaled by its coverage (as Patina::eval scales the table).
fn interreflected_at(layer: Layer, ch: u32, mu: f32) -> f32 {
    let x = clamp(mu, 0.0, 1.0) * f32(INTERREFLECTION_NODES - 1u);
    let j = min(u32(x), INTERREFLECTION_NODES - 2u);
    let at = layer.at + ch * channel_stride() + INTERREFLECTED + j;
    return layer.w * (layers[at] + (x - f32(j)) * (layers[at + 1u] - layers[at]));
}

// single_pass::interreflected: g(μi) g(μo).
fn interreflected(layer: Layer, ch: u32, mu_i: f32, mu_o: f32) -> f32 {
    return interreflected_at(layer, ch, mu_i) * interreflected_at(layer, ch, mu_o);
}

// single_pass::refracted_up: w refracted into a slab and flipped to point up, same azimuth, sine sin_t.
fn refracted_up(w: vec3<f32>, sin_t: f32) -> vec3<f32> {
    let r = sqrt(w.x * w.x + w.y * w.y);
    let cos_t = sqrt(max(1.0 - sin_t * sin_t, 0.0));
    if r == 0.0 {
        return vec3<f32>(0.0, 0.0, cos_t);
    }
    return vec3<f32>(w.x / r * sin_t, w.y / r * sin_t, cos_t);
}

// single_pass::beer_lambert: exp(−σ d (1/cos θi + 1/cos θo)) along both refracted directions.
fn beer_lambert(sigma_t: f32, thickness: f32, wi: vec3<f32>, wo: vec3<f32>) -> f32 {
    if sigma_t * thickness == 0.0 {
        return 1.0;
    }
    return exp(-sigma_t * thickness * (1.0 / max(wi.z, 1e-9) + 1.0 / max(wo.z, 1e-9)));
}

// FresnelTable::lookup (which 0) and transmittance (which 1): linear in cos θ over the table's nodes.
fn fresnel_table(layer: Layer, cos_i: f32, ch: u32, which: u32) -> f32 {
    let node = table_node(cos_i, params.fresnel_samples);
    let at = layer.at + ch * channel_stride() + PER_CHANNEL + 2u * u32(node.i) + which;
    return (1.0 - node.f) * layers[at] + node.f * layers[at + 2u];
}

// Interface::fresnel: the layer's Fresnel reflectance of channel ch in the chosen form, or from its table.
fn interface_fresnel(layer: Layer, cos_i: f32, ch: u32) -> f32 {
    if params.fresnel_samples > 0u {
        return fresnel_table(layer, cos_i, ch, 0u);
    }
    if layer.kind == CONDUCTOR {
        return fresnel_form_conductor(params.fresnel, cos_i, value(layer, ch, ETA), value(layer, ch, KAPPA));
    }
    return fresnel_form_dielectric(params.fresnel, cos_i, value(layer, ch, ETA));
}

// Interface::transmittance: 1 − F into the layer below, without cancellation at grazing incidence (a dielectric's),
// or from its table.
fn interface_transmittance(layer: Layer, cos_i: f32, ch: u32) -> f32 {
    if params.fresnel_samples > 0u {
        return fresnel_table(layer, cos_i, ch, 1u);
    }
    if layer.kind == CONDUCTOR {
        return 1.0 - interface_fresnel(layer, cos_i, ch);
    }
    return fresnel_form_dielectric_transmittance(params.fresnel, cos_i, value(layer, ch, ETA));
}

