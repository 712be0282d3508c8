// The walk shared by the single-pass models on the GPU (Walk in src/models/common/single_pass.rs), for up to four
// channels at once (vector lanes) where they share the IOR: at each interface its specular lobe weighted by the attenuation above, then the model's passage into the slab
// below with its Beer–Lambert attenuation and scattered light, down to the opaque base. Composed after layers.wgsl
// and before the model's shader, which declares `params` (also layers, g2 and eta2) and the model's `lobe` and
// `passage` (single_pass::Transport).

// single_pass::Passage: transmissions of the light and view directions, the view's for the slab's scattering, and
// the directions refracted into the slab (pointing up); `through` false when nothing gets through.
struct Passage {
    t_light: f32,
    t_view: f32,
    t_view_slab: f32,
    wi: vec3<f32>,
    wo: vec3<f32>,
    through: bool,
}

// The walk's per-element state, which the model sets before a walk (zero: none): Walk::eval_block's `normal` (the
// base's tilted normal; z = 0: not tilted) and `tint` (the base's tint per channel, `tints` values from `tint_at` in
// `layers`, one for all when 1, taken as 1 + w (tint − 1)), and weidlich_wilkie's patina (Patina::eval): the top
// layer covers the base with coverage w, at the roughness `top_mf`, over a base of roughness `base_mf`.
struct WalkState {
    normal: vec3<f32>,
    tint_at: u32,
    tints: u32,
    patina: u32,
    w: f32,
    top_mf: Microfacet,
    base_mf: Microfacet,
}

var<private> walk_state: WalkState;

// Layer l as the walk sees it: under a patina the top and the base take their interpolated form.
fn walk_layer(l: u32) -> Layer {
    var layer = sp_layer(l);
    if walk_state.patina != 0u && l < 2u {
        layer.w = walk_state.w;
        if l == 0u {
            layer.role = PATINA_TOP;
            layer.mf = walk_state.top_mf;
        } else {
            layer.role = PATINA_BASE;
            layer.mf = walk_state.base_mf;
            layer.top_at = sp_layer(0u).at;
        }
    }
    return layer;
}

// The base's tint for the 4 lanes from channel c0 (1 without).
fn tint_lanes(c0: u32) -> vec4<f32> {
    var t = vec4<f32>(1.0);
    if walk_state.tints == 0u {
        return t;
    }
    for (var k = 0u; k < 4u; k++) {
        let raw = layers[walk_state.tint_at + min(c0 + k, walk_state.tints - 1u)];
        t[k] = 1.0 + walk_state.w * (raw - 1.0);
    }
    return t;
}

// Up to 4 channels c0 .. c0 + lanes of a per-channel value of a layer, in vector lanes (0 beyond).
fn lanes_of(layer: Layer, c0: u32, lanes: u32, which: u32) -> vec4<f32> {
    var v = vec4<f32>(0.0);
    for (var k = 0u; k < lanes; k++) {
        v[k] = value(layer, c0 + k, which);
    }
    return v;
}

// interface_fresnel of channels c0 .. c0 + lanes, in vector lanes.
fn fresnel_lanes(layer: Layer, cos_i: f32, c0: u32, lanes: u32) -> vec4<f32> {
    var v = vec4<f32>(0.0);
    for (var k = 0u; k < lanes; k++) {
        v[k] = interface_fresnel(layer, cos_i, c0 + k);
    }
    return v;
}

// interreflected of channels c0 .. c0 + lanes, in vector lanes.
fn interreflected_lanes(layer: Layer, c0: u32, lanes: u32, mu_i: f32, mu_o: f32) -> vec4<f32> {
    var v = vec4<f32>(0.0);
    for (var k = 0u; k < lanes; k++) {
        v[k] = interreflected(layer, c0 + k, mu_i, mu_o);
    }
    return v;
}

// Walk::eval_group for the `lanes` ≤ params.group channels from c0, in vector lanes: f(wi, wo) of the stack; 0 below
// the horizon. Where every dielectric shares its IOR over the channels (params.group 4) the lobes' geometry and the
// passages are channel c0's for all the lanes; a dispersive stack walks one channel per pass (params.group 1).
fn walk(wi_in: vec3<f32>, wo_in: vec3<f32>, c0: u32, lanes: u32) -> vec4<f32> {
    if wi_in.z <= 0.0 || wo_in.z <= 0.0 {
        return vec4<f32>(0.0);
    }
    var wi = wi_in;
    var wo = wo_in;
    var weight = vec4<f32>(1.0);
    var f = vec4<f32>(0.0);
    for (var l = 0u; l < params.layers; l++) {
        let layer = walk_layer(l);
        if layer.kind != DIELECTRIC {
            // The opaque base, in the frame of its tilted normal if any (nothing below that normal's horizon),
            // tinted.
            let n = walk_state.normal;
            if n.z != 0.0 {
                let tb = orthonormal_basis(n);
                wi = vec3<f32>(dot(wi, tb[0]), dot(wi, tb[1]), dot(wi, n));
                wo = vec3<f32>(dot(wo, tb[0]), dot(wo, tb[1]), dot(wo, n));
                if wi.z <= 0.0 || wo.z <= 0.0 {
                    break;
                }
            }
            weight *= tint_lanes(c0);
            if layer.kind == CONDUCTOR {
                let geo = lobe(layer, wi, wo);
                f += weight * geo.x * fresnel_lanes(layer, geo.y, c0, lanes);
                // The inter-reflections with the coat above (conductor_interreflection; 0 without).
                f += weight * interreflected_lanes(layer, c0, lanes, wi.z, wo.z) * FRAC_1_PI;
            } else {
                let albedo = lanes_of(layer, c0, lanes, ALBEDO) * lanes_of(layer, c0, lanes, GAIN);
                f += weight * albedo * oren_nayar_shape(layer.sigma, wi, wo);
            }
            break;
        }
        let geo = lobe(layer, wi, wo);
        f += weight * geo.x * fresnel_lanes(layer, geo.y, c0, lanes);
        let p = passage(layer, wi, wo, c0);
        if !p.through {
            break;
        }
        var through = p.t_light;
        if params.eta2 != 0u {
            let eta = value(layer, c0, ETA);
            through /= eta * eta;
        }
        let sigma_t = lanes_of(layer, c0, lanes, SIGMA_T);
        let d = layer.thickness;
        let a = vec4<f32>(
            beer_lambert(sigma_t.x, d, p.wi, p.wo),
            beer_lambert(sigma_t.y, d, p.wi, p.wo),
            beer_lambert(sigma_t.z, d, p.wi, p.wo),
            beer_lambert(sigma_t.w, d, p.wi, p.wo),
        );
        f += weight * through * p.t_view_slab * (1.0 - a) * lanes_of(layer, c0, lanes, ALBEDO) * FRAC_1_PI;
        weight *= through * p.t_view * a;
        if all(weight == vec4<f32>(0.0)) {
            break;
        }
        wi = p.wi;
        wo = p.wo;
    }
    return f;
}

// f(wi, wo) of every channel into out[base..], params.group channels per pass, in the walk's current state: the
// single-pass models' evaluation.
fn eval_walk(wi: vec3<f32>, wo: vec3<f32>, base: u32) {
    for (var c0 = 0u; c0 < params.channels; c0 += params.group) {
        let lanes = min(params.group, params.channels - c0);
        let f = walk(wi, wo, c0, lanes);
        for (var k = 0u; k < lanes; k++) {
            out[base + c0 + k] = f[k];
        }
    }
}

// Walk::terms, the sampling part: each rough interface's lobe and the diffuse terms with their energies estimated
// at wo (Fresnel at the macro-surface cosine, Snell at the mean IOR, Beer–Lambert both ways), mean over channels.
fn proposals(wo: vec3<f32>) {
    clear_mixture();
    let share = 1.0 / f32(params.channels);
    for (var ch = 0u; ch < params.channels; ch++) {
        var weight = 1.0;
        var cos = wo.z;
        var slot = 0u;
        for (var l = 0u; l < params.layers; l++) {
            let layer = sp_layer(l);
            if layer.kind == DIELECTRIC {
                let f = interface_fresnel(layer, cos, ch);
                if layer.mf.smooth_ == 0u {
                    add_term(slot, REFLECTION, share * weight * f, layer.mf);
                    slot += 1u;
                }
                let sin_t = sqrt(max(1.0 - cos * cos, 0.0)) / layer.mean_eta;
                if sin_t >= 1.0 {
                    break;
                }
                cos = sqrt(1.0 - sin_t * sin_t);
                let k = exp(-2.0 * value(layer, ch, SIGMA_T) * layer.thickness / max(cos, 1e-9));
                let t = weight * (1.0 - f) * (1.0 - f);
                add_term(slot, COSINE, share * t * (1.0 - k) * value(layer, ch, ALBEDO), cosine_lobe());
                slot += 1u;
                weight = t * k;
            } else if layer.kind == CONDUCTOR {
                if layer.mf.smooth_ == 0u {
                    add_term(slot, REFLECTION, share * weight * interface_fresnel(layer, cos, ch), layer.mf);
                    slot += 1u;
                }
                add_term(slot, COSINE, share * weight * interreflected(layer, ch, cos, cos), cosine_lobe());
            } else {
                add_term(slot, COSINE, share * weight * value(layer, ch, ALBEDO) * value(layer, ch, GAIN), cosine_lobe());
            }
        }
    }
    add_defensive_share();
}

// Walk::specular: the Dirac reflection at wo of channel ch, from smooth interfaces seen through smooth ones.
fn specular(wo: vec3<f32>, ch: u32) -> f32 {
    if wo.z <= 0.0 {
        return 0.0;
    }
    var mirror = 0.0;
    var weight = 1.0;
    var cos = wo.z;
    for (var l = 0u; l < params.layers; l++) {
        let layer = sp_layer(l);
        if layer.kind != DIELECTRIC && layer.kind != CONDUCTOR {
            break;
        }
        let f = interface_fresnel(layer, cos, ch);
        if layer.mf.smooth_ == 0u {
            break;  // nothing below a rough interface is seen as a Dirac lobe
        }
        mirror += weight * f;
        if layer.kind == CONDUCTOR {
            break;
        }
        let sin_t = sqrt(max(1.0 - cos * cos, 0.0)) / layer.mean_eta;
        if sin_t >= 1.0 {
            break;
        }
        cos = sqrt(1.0 - sin_t * sin_t);
        weight *= (1.0 - f) * (1.0 - f) * exp(-2.0 * value(layer, ch, SIGMA_T) * layer.thickness / max(cos, 1e-9));
    }
    return mirror;
}
