//! `model="weidlich_wilkie"`: Weidlich & Wilkie 2007, "Arbitrarily layered micro-facet surfaces", in the recursive
//! form of Elek 2010 — f⁽ⁱ⁾(L, V) = f_i(L, V) + T₁₂ · f⁽ⁱ⁺¹⁾(L′, V′) · a_i · t_i, with L′, V′ refracted by Snell's law
//! at the macro-surface, a_i = exp(−σ d (1/cos θL′ + 1/cos θV′)), t_i = (1 − G_i) + T₂₁ G_i, T₁₂ = 1 − F(cos θL) and
//! T₂₁ = 1 − F(cos θV). Each f_i is a Torrance–Sparrow lobe (by default Beckmann D and the V-cavity G); the base is
//! a conductor lobe or Lambert / Oren–Nayar. Unrolled by models/single_pass.rs.
//!
//! Options: the Fresnel form (exact or Lazányi–Szirmay-Kalos), Elek's m₂ ≥ m₁ roughness clamp, and Elek's
//! precomputed variant (tables/elek.rs: 128-sample Fresnel tables and the 512 × 512 Beckmann table).
//! Car paint: a per-sample base normal normalize(flake + max(distance, 1) ẑ) (Elek's distance-based smoothing).
//! Copper patina: `eval_patina`.

use super::single_pass::{self, refracted_up, Base, Interface, Passage, SpLayer, Transport, Walk};
use super::Options;
use crate::bsdf;
use crate::optics::microfacet::Distribution;
use crate::stack::{value_error, Layer, Result, Stack};
use crate::tables::elek::beckmann_table;
use glam::DVec3;

pub struct Prepared {
    walk: Walk,
    precomputed: bool,
}

pub fn prepare(stack: &Stack, opts: &Options) -> Result<Prepared> {
    let mut walk = Walk::new(stack, opts.distribution, opts);
    let precomputed = opts.elek_precomputed;
    if precomputed {
        for layer in &mut walk.layers {
            if let SpLayer::Dielectric { iface, .. } | SpLayer::Conductor(iface) = layer {
                iface.precompute(opts.fresnel);
            }
        }
        beckmann_table();
    }
    Ok(Prepared { walk, precomputed })
}

impl Transport for Prepared {
    /// Torrance–Sparrow lobe D G / (4 cos θi cos θo); the precomputed variant takes D from Elek's table (isotropic
    /// Beckmann interfaces; others keep the analytic D).
    fn lobe(&self, iface: &Interface, wi: DVec3, wo: DVec3) -> Option<(f64, f64)> {
        let (geo, cos_h) = bsdf::reflection_geometry(&iface.mf, self.walk.g2, wi, wo)?;
        let mf = &iface.mf;
        if !self.precomputed || geo == 0.0 || mf.dist != Distribution::Beckmann || mf.alpha_x != mf.alpha_y {
            return Some((geo, cos_h));
        }
        let h = (wi + wo).normalize();
        Some((geo * beckmann_table().lookup(h.z, mf.alpha_x) / mf.d(h), cos_h))
    }

    /// Snell's law at the macro-surface; T₁₂ = 1 − F(cos θL) into the layer, t = (1 − G) + T₂₁ G out of it.
    fn passage(&self, iface: &Interface, wi: DVec3, wo: DVec3, c: usize) -> Option<Passage> {
        let eta = iface.eta[c];
        let (sin_i, sin_o) = (wi.x.hypot(wi.y) / eta, wo.x.hypot(wo.y) / eta);
        if sin_i >= 1.0 || sin_o >= 1.0 {
            return None; // total internal reflection at the macro-surface
        }
        let t12 = 1.0 - iface.fresnel(self.walk.fresnel, wi.z, c);
        let t21 = 1.0 - iface.fresnel(self.walk.fresnel, wo.z, c);
        let g = if iface.mf.is_smooth() { 1.0 } else { iface.mf.g2(self.walk.g2, wi, wo, (wi + wo).normalize()) };
        Some(Passage {
            t_light: t12,
            t_view: (1.0 - g) + t21 * g,
            t_view_slab: t21,
            wi: refracted_up(wi, sin_i),
            wo: refracted_up(wo, sin_o),
        })
    }
}

impl Prepared {
    pub fn eval(&self, wi: DVec3, wo: DVec3, out: &mut [f64]) {
        self.walk.eval(self, &self.walk.layers, wi, wo, &[single_pass::PLAIN_BASE], out);
    }

    /// Car paint: the base evaluated about a flake normal `flake` smoothed by the viewing `distance`.
    pub fn eval_flake(&self, wi: DVec3, wo: DVec3, flake: DVec3, distance: f64, out: &mut [f64]) {
        let n = (flake + distance.max(1.0) * DVec3::Z).normalize();
        self.walk.eval(self, &self.walk.layers, wi, wo, &[Base { normal: Some(n), tint: 1.0 }], out);
    }
}

/// The copper-patina material (Elek 2010): a bare stack and a patina stack whose top layer is the patina.
pub struct Patina {
    pub bare: Prepared,
    pub patina: Prepared,
    /// Elek's m₂ ≥ m₁ against the interpolated patina roughness.
    pub clamp: bool,
    /// The bare top roughness: where the patina layer's roughness starts.
    pub bare_alpha: (f64, f64),
    /// Tarnish tone multiplying the base under the patina, per channel.
    pub tint: Vec<f64>,
    pub extent: f64,
    pub transition: f64,
}

/// GLSL smoothstep: 0 below `a`, 1 above `b`, 3t² − 2t³ between.
pub fn smoothstep(a: f64, b: f64, x: f64) -> f64 {
    if b <= a {
        return if x < a { 0.0 } else { 1.0 };
    }
    let t = ((x - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

impl Patina {
    pub fn new(
        bare: &Stack,
        patina: &Stack,
        tint: Vec<f64>,
        extent: f64,
        transition: f64,
        opts: &Options,
    ) -> Result<Self> {
        if !matches!(patina.layers[..], [Layer::Dielectric { .. }, _]) {
            return value_error("patina: the patina stack must be the patina (a Dielectric layer) over an opaque base");
        }
        if bare.channels != patina.channels {
            return value_error(format!(
                "patina: the bare stack has {} channels but the patina stack has {}",
                bare.channels, patina.channels
            ));
        }
        if opts.elek_precomputed {
            return value_error("precomputed: the patina's IOR changes per element, so it has no precomputed tables");
        }
        if tint.len() != patina.channels {
            return value_error(format!("tint has {} channels but the stack has {}", tint.len(), patina.channels));
        }
        let bare_alpha = match bare.layers.first() {
            Some(Layer::Dielectric { alpha, .. } | Layer::Conductor { alpha, .. }) => *alpha,
            _ => (0.0, 0.0),
        };
        Ok(Patina {
            bare: prepare(bare, opts)?,
            // The roughness clamp is applied per element, against the patina's interpolated roughness.
            patina: prepare(patina, &Options { clamp_roughness: false, ..*opts })?,
            clamp: opts.clamp_roughness,
            bare_alpha,
            tint,
            extent,
            transition,
        })
    }

    /// extentFactor = 1 − smoothstep(extent − transition, extent + transition, mask): 1 where the patina covers.
    pub fn coverage(&self, mask: f64) -> f64 {
        1.0 - smoothstep(self.extent - self.transition, self.extent + self.transition, mask)
    }

    /// f = (1 − w) f_bare + w f_patina, where the patina layer's roughness and IOR go from the bare surface's (the
    /// outside medium's IOR: no layer) to the patina's with w, and the base is tinted by lerp(1, tint, w).
    pub fn eval(&self, wi: DVec3, wo: DVec3, mask: f64, out: &mut [f64]) {
        let w = self.coverage(mask);
        let mut bare = vec![0.0; out.len()];
        if w < 1.0 {
            self.bare.eval(wi, wo, &mut bare);
        }
        out.fill(0.0);
        if w > 0.0 {
            let [SpLayer::Dielectric { iface, thickness, sigma_t, albedo }, base] = &self.patina.walk.layers[..] else {
                unreachable!("checked in Patina::new")
            };
            let lerp = |a: f64, b: f64| a + w * (b - a);
            // The patina's relative IOR over the outside goes from 1 (no layer) to its own; the base's relative
            // IOR follows the medium above it.
            let eta_top: Vec<f64> = iface.eta.iter().map(|e| lerp(1.0, *e)).collect();
            let rescale = |v: &[f64]| -> Vec<f64> {
                v.iter().zip(&iface.eta).zip(&eta_top).map(|((x, e), t)| x * e / t).collect()
            };
            let target = if iface.mf.is_smooth() { (0.0, 0.0) } else { (iface.mf.alpha_x, iface.mf.alpha_y) };
            let alpha = (lerp(self.bare_alpha.0, target.0), lerp(self.bare_alpha.1, target.1));
            let top = SpLayer::Dielectric {
                iface: single_pass::Interface {
                    mf: iface.mf.with_alpha(alpha.0, alpha.1),
                    eta: eta_top.clone(),
                    kappa: iface.kappa.clone(),
                    conductor: false,
                    table: Vec::new(),
                },
                thickness: *thickness,
                sigma_t: sigma_t.clone(),
                albedo: albedo.clone(),
            };
            let base = match base {
                SpLayer::Conductor(b) => SpLayer::Conductor(single_pass::Interface {
                    mf: if self.clamp && !b.mf.is_smooth() {
                        b.mf.with_alpha(b.mf.alpha_x.max(alpha.0), b.mf.alpha_y.max(alpha.1))
                    } else {
                        b.mf
                    },
                    eta: rescale(&b.eta),
                    kappa: rescale(&b.kappa),
                    conductor: true,
                    table: Vec::new(),
                }),
                SpLayer::Diffuse { albedo, sigma } => SpLayer::Diffuse { albedo: albedo.clone(), sigma: *sigma },
                SpLayer::Dielectric { .. } => unreachable!("checked in Patina::new"),
            };
            let tint: Vec<Base> = self.tint.iter().map(|t| Base { normal: None, tint: lerp(1.0, *t) }).collect();
            self.patina.walk.eval(&self.patina, &[top, base], wi, wo, &tint, out);
        }
        for (o, b) in out.iter_mut().zip(&bare) {
            *o = (1.0 - w) * b + w * *o;
        }
    }
}
