//! `model="steinberg"`: Steinberg 2016, "Light Transport in a Multi-Layered Microfacet Model" — one pass through
//! the stack (models/single_pass.rs) with a Cook–Torrance GGX lobe per interface; a dielectric interface transmits
//! t(wo) t(wi), the mean Fresnel transmissions over the visible microfacets, and bends both directions to the mean
//! refracted directions, both from lamina's tables (tables/steinberg.rs, tabulated or fitted form).
//!
//! Anisotropic layers (lamina's analytic approximation; the article names a 3D LUT or an analytic form): each
//! direction looks the tables up with the projected roughness α(φ) of its azimuth in the layer's tangent frame —
//! the roughness that the Smith masking of that direction sees — and stays in its plane of incidence. The lobes
//! themselves use the full anisotropic D and G2.

use super::single_pass::{refracted_up, Interface, Passage, SpLayer, Transport, Walk, PLAIN_BASE};
use super::Options;
use crate::bsdf;
use crate::optics::microfacet::Distribution;
use crate::stack::{value_error, Result, Stack};
use crate::tables::steinberg::{self as lut, steinberg};
use glam::DVec3;

pub struct Prepared {
    walk: Walk,
    fitted: bool,
}

pub fn prepare(stack: &Stack, opts: &Options) -> Result<Prepared> {
    if opts.distribution != Distribution::Ggx {
        return value_error("distribution: model 'steinberg' is defined for 'ggx' only (its tables are GGX)");
    }
    let walk = Walk::new(stack, Distribution::Ggx, opts);
    for (i, layer) in walk.layers.iter().enumerate() {
        if let SpLayer::Dielectric { iface, .. } = layer {
            if let Some(eta) = iface.eta.iter().find(|e| !(lut::ETA_MIN..=lut::ETA_MAX).contains(*e)) {
                return value_error(format!(
                    "layer {i}: model 'steinberg' tabulates relative IORs (this layer's over the one above) in \
                     [{}, {}], got {eta}",
                    lut::ETA_MIN,
                    lut::ETA_MAX
                ));
            }
        }
    }
    steinberg(); // generate or load the tables outside the parallel evaluation
    Ok(Prepared { walk, fitted: opts.steinberg_fitted })
}

impl Transport for Prepared {
    /// Cook–Torrance GGX lobe (Cook & Torrance 1982 with the GGX D and Smith G2 of Walter et al. 2007).
    fn lobe(&self, iface: &Interface, wi: DVec3, wo: DVec3) -> Option<(f64, f64)> {
        bsdf::reflection_geometry(&iface.mf, self.walk.g2, wi, wo)
    }

    /// t(wo) t(wi) and the mean refracted directions from the tables, at each direction's projected roughness.
    fn passage(&self, iface: &Interface, wi: DVec3, wo: DVec3, c: usize) -> Option<Passage> {
        let table = steinberg();
        let lookup = |w: DVec3| {
            let alpha = if iface.mf.is_smooth() { 0.0 } else { iface.mf.projected_alpha(w) };
            if self.fitted {
                table.fitted(w.z, alpha, iface.eta[c])
            } else {
                table.tabulated(w.z, alpha, iface.eta[c])
            }
        };
        let ((t_i, s_i), (t_o, s_o)) = (lookup(wi), lookup(wo));
        Some(Passage {
            t_light: t_i,
            t_view: t_o,
            t_view_slab: t_o,
            wi: refracted_up(wi, s_i),
            wo: refracted_up(wo, s_o),
        })
    }
}

impl Prepared {
    pub fn eval(&self, wi: DVec3, wo: DVec3, out: &mut [f64]) {
        self.walk.eval(self, &self.walk.layers, wi, wo, &[PLAIN_BASE], out);
    }
}
