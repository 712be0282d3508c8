// The walk shared by the single-pass models on the GPU (Walk in src/models/common/single_pass.rs), here for one channel at a
// time: at each interface its specular lobe weighted by the attenuation above, then the model's passage into the slab
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

// Walk::eval_group for channel ch: f(wi, wo) of the stack; 0 below the horizon.
fn walk(wi_in: vec3<f32>, wo_in: vec3<f32>, ch: u32) -> f32 {
    if wi_in.z <= 0.0 || wo_in.z <= 0.0 {
        return 0.0;
    }
    var wi = wi_in;
    var wo = wo_in;
    var weight = 1.0;
    var f = 0.0;
    for (var l = 0u; l < params.layers; l++) {
        let layer = sp_layer(l);
        if layer.kind != DIELECTRIC && layer.kind != CONDUCTOR {
            f += weight * value(layer, ch, ALBEDO) * value(layer, ch, GAIN) * oren_nayar_shape(layer.sigma, wi, wo);
            break;
        }
        let geo = lobe(layer, wi, wo);
        f += weight * geo.x * interface_fresnel(layer, geo.y, ch);
        if layer.kind == CONDUCTOR {
            // The inter-reflections with the coat above (conductor_interreflection; 0 without).
            f += weight * interreflected(layer, ch, wi.z, wo.z) * FRAC_1_PI;
            break;
        }
        let p = passage(layer, wi, wo, ch);
        if !p.through {
            break;
        }
        var through = p.t_light;
        if params.eta2 != 0u {
            let eta = value(layer, ch, ETA);
            through /= eta * eta;
        }
        let a = beer_lambert(value(layer, ch, SIGMA_T), layer.thickness, p.wi, p.wo);
        f += weight * through * p.t_view_slab * (1.0 - a) * value(layer, ch, ALBEDO) * FRAC_1_PI;
        weight *= through * p.t_view * a;
        if weight == 0.0 {
            break;
        }
        wi = p.wi;
        wo = p.wo;
    }
    return f;
}

// f(wi, wo) of every channel into out[base..]: the single-pass models' one evaluation, shared by the eval and render kernels.
fn eval_pair(wi: vec3<f32>, wo: vec3<f32>, base: u32) {
    for (var ch = 0u; ch < params.channels; ch++) {
        out[base + ch] = walk(wi, wo, ch);
    }
}

// The mean relative IOR of a layer over the channels (Walk::terms refracts at it).
fn mean_eta(layer: Layer) -> f32 {
    var eta = 0.0;
    for (var c = 0u; c < params.channels; c++) {
        eta += value(layer, c, ETA);
    }
    return eta / f32(params.channels);
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
                let sin_t = sqrt(max(1.0 - cos * cos, 0.0)) / mean_eta(layer);
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
        let sin_t = sqrt(max(1.0 - cos * cos, 0.0)) / mean_eta(layer);
        if sin_t >= 1.0 {
            break;
        }
        cos = sqrt(1.0 - sin_t * sin_t);
        weight *= (1.0 - f) * (1.0 - f) * exp(-2.0 * value(layer, ch, SIGMA_T) * layer.thickness / max(cos, 1e-9));
    }
    return mirror;
}
