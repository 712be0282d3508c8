// lamina's correction transport_fit on the GPU (src/models/corrections/transport_fit.rs), for every model: after the
// model's f, f ← s f + a with (s, a) bilinear over the zenith nodes x = √(1 − cos θ) of wi and wo, and in the
// sampling mixture a cosine lobe for the added light. A stack without the correction has `on` 0. Composed after the
// model's shader, before the kernels (queries.wgsl, render.wgsl, env.wgsl), which call `eval_fitted` and
// `fitted_proposals` instead of the model's own.

const FIT_NODES: u32 = 65u;  // adding_doubling::NODES
// Whether some stack of the dispatch has the correction (gpu::Specialization): without, its code is compiled out.
override FITTED: bool;

// A stack's correction: whether it has one, where its (s, a) per (node i, node o, channel) start in `fit_values`, and
// where its added albedo per view node starts.
struct Fit {
    on: u32,
    base: u32,
    added_base: u32,
    pad: u32,
}

@group(0) @binding(14) var<storage, read> fit_stacks: array<Fit>;
@group(0) @binding(15) var<storage, read> fit_values: array<f32>;
// The current thread's stack's (set beside `params`).
var<private> fit: Fit;

// TransportFit::eval_columns: the model's f, then s f + a per channel (rows below the horizon keep the model's f).
fn eval_fitted(wi: vec3<f32>, wo: vec3<f32>, base: u32) {
    eval_pair(wi, wo, base);
    if !FITTED || fit.on == 0u || wi.z <= 0.0 || wo.z <= 0.0 {
        return;
    }
    let ni = table_node(sqrt(max(1.0 - wi.z, 0.0)), FIT_NODES);
    let no = table_node(sqrt(max(1.0 - wo.z, 0.0)), FIT_NODES);
    let ch = params.channels;
    let i = u32(ni.i);
    let o = u32(no.i);
    let w = array<f32, 4>((1.0 - ni.f) * (1.0 - no.f), ni.f * (1.0 - no.f), (1.0 - ni.f) * no.f, ni.f * no.f);
    let corner = array<u32, 4>(i * FIT_NODES + o, (i + 1u) * FIT_NODES + o, i * FIT_NODES + o + 1u, (i + 1u) * FIT_NODES + o + 1u);
    for (var c = 0u; c < ch; c++) {
        var s = 0.0;
        var a = 0.0;
        for (var k = 0u; k < 4u; k++) {
            let at = fit.base + 2u * (corner[k] * ch + c);
            s += w[k] * fit_values[at];
            a += w[k] * fit_values[at + 1u];
        }
        out[base + c] = s * out[base + c] + a;
    }
}

// TransportFit::proposals: the model's mixture, then the added light's cosine lobe (its albedo at wo's node over the
// mixture's 1 − DEFENSIVE).
fn fitted_proposals(wo: vec3<f32>) {
    proposals(wo);
    if !FITTED || fit.on == 0u {
        return;
    }
    let node = table_node(sqrt(max(1.0 - wo.z, 0.0)), FIT_NODES);
    let at = fit.added_base + u32(node.i);
    let added = (1.0 - node.f) * fit_values[at] + node.f * fit_values[at + 1u];
    add_term(lobe_count, COSINE, added / (1.0 - DEFENSIVE), cosine_lobe());
}
