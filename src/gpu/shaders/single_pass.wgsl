// The walk shared by the single-pass models on the GPU (Walk in src/models/single_pass.rs), here for one channel at a
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
