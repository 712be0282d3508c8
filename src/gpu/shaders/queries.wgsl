// The per-element kernels of every model (gpu::Query): eval, sample and pdf over n elements, each a row of two
// vectors in `pairs` ((wi, wo), or (wo, u) for sample). Composed after the model, which declares `params` (n,
// channels) of its one stack in `stack_params`, `pairs`, `out`, `eval_pair` and `proposals`, and fit.wgsl, which wraps
// the last two in lamina's correction transport_fit where the stack has it; the per-element inputs (inputs.wgsl) are
// element i's.

// Vector `which` (0 or 1) of element i.
fn load(i: u32, which: u32) -> vec3<f32> {
    let k = 6u * i + 3u * which;
    return vec3<f32>(pairs[k], pairs[k + 1u], pairs[k + 2u]);
}

// Model::eval: f(wi, wo) of every channel per element.
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    params = stack_params[0];
    fit = fit_stacks[0];
    let i = gid.x;
    if i < params.n {
        load_element_inputs(i);
        eval_fitted(load(i, 0u), load(i, 1u), i * params.channels);
    }
}

// Stack.sample on the GPU (mixture::sample with the model's f): per element (wo, u) the row (wi, weight = f cos θi /
// pdf per channel, pdf); wi = +z, weight 0 and pdf 0 where nothing is sampled.
@compute @workgroup_size(64)
fn sample_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    params = stack_params[0];
    fit = fit_stacks[0];
    let i = gid.x;
    if i >= params.n {
        return;
    }
    let wo = load(i, 0u);
    let base = i * (params.channels + 4u);
    load_element_inputs(i);
    var s = vec4<f32>(0.0, 0.0, 1.0, 0.0);
    if wo.z > 0.0 {
        fitted_proposals(wo);
        s = sample_mixture(wo, load(i, 1u));
    }
    if s.w > 0.0 {
        eval_fitted(s.xyz, wo, base + 3u);
    }
    for (var ch = 0u; ch < params.channels; ch++) {
        out[base + 3u + ch] = select(0.0, out[base + 3u + ch] * weight_factor(s.xyz, s.w), s.w > 0.0);
    }
    out[base] = s.x;
    out[base + 1u] = s.y;
    out[base + 2u] = s.z;
    out[base + 3u + params.channels] = s.w;
}

// Stack.pdf on the GPU (mixture::pdf): the mixture's density of wi for wo per element; 0 for wo below the horizon.
@compute @workgroup_size(64)
fn pdf_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    params = stack_params[0];
    fit = fit_stacks[0];
    let i = gid.x;
    if i >= params.n {
        return;
    }
    let wi = load(i, 0u);
    let wo = load(i, 1u);
    var p = 0.0;
    if wo.z > 0.0 {
        fitted_proposals(wo);
        p = mixture_pdf(wi, wo);
    }
    out[i] = p;
}
