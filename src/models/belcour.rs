//! `model="belcour"`: Belcour 2018, "Efficient rendering of layered materials using an atomic decomposition with
//! statistical operators" — per-lobe energy, mean (as a cosine) and variance (in the projected disc, through the
//! roughness map h) carried through the stack by adding-doubling, in the form of the published reference loop;
//! one GGX lobe per interface, all centred on the mirror direction. Isotropic layers only in this version.
//!
//! Statistics are computed for the viewing direction wo (or for |wo·h| with `symmetric`, Belcour §6, which makes
//! the BRDF reciprocal). Slabs are medium steps (Beer–Lambert absorption and forward Henyey–Greenstein scattering,
//! no lobe). A diffuse base contributes ρ/π · T↓(θi) T↑(θo) / ((1 − ρ R̄↑) η²) — lamina's choice, which is exact
//! for a smooth coat (Mitsuba's `plastic`): the energies transmitted down from wi and up to wo (one adding pass
//! each), the inter-reflections with the stack's hemispherical reflectance from below R̄↑ (precomputed by
//! quadrature, 1 under total internal reflection), and the radiance compression η² of the medium above the base.

use super::Options;
use crate::optics::fresnel;
use crate::optics::microfacet::{G2Form, Microfacet};
use crate::stack::{value_error, Layer, Result, Stack};
use crate::tables;
use glam::DVec3;
use std::f64::consts::FRAC_1_PI;

/// Belcour 2018 roughness-to-variance map h(α) = α^1.1 / (1 − α^1.1) (the reference code's fit).
pub fn variance_from_alpha(alpha: f64) -> f64 {
    let a = alpha.clamp(0.0, 0.9999).powf(1.1);
    a / (1.0 - a)
}

/// Inverse of `variance_from_alpha`: α = (v / (1 + v))^(1/1.1).
pub fn alpha_from_variance(v: f64) -> f64 {
    let v = v.max(0.0);
    (v / (1.0 + v)).powf(1.0 / 1.1)
}

/// Variance of Henyey–Greenstein forward scattering in the projected disc, ((1 − g)/g)^0.8 / (1 + g) (Belcour 2018
/// reference code), with g clamped to [0.01, 0.99].
pub fn hg_variance(g: f64) -> f64 {
    let g = g.clamp(0.01, 0.99);
    ((1.0 - g) / g).powf(0.8) / (1.0 + g)
}

/// Where Belcour's paper and reference code disagree, each choice is an option, measured against the reference
/// evaluator in docs/validation.md. Defaults: the reference code.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Variant {
    /// Transmission roughness scale s with the real cosines (paper) instead of cosines frozen to 1 (code).
    pub real_cosines: bool,
    /// J21 (paper) instead of j12 (code) in the transmitted and back-reflected variance terms.
    pub jacobian_j21: bool,
    /// Energies from the exact Fresnel at the mean cosine instead of the FGD table.
    pub fresnel_energy: bool,
}

enum Step {
    /// A rough interface: relative IOR per channel (below / above), κ per channel (conductors), roughness.
    Interface { eta: Vec<f64>, kappa: Vec<f64>, alpha: f64, conductor: bool },
    /// A slab: thickness and coefficients per channel.
    Medium { thickness: f64, sigma_a: Vec<f64>, sigma_s: Vec<f64>, g: f64 },
}

/// A Lambertian base: albedo, relative IOR of the medium above it (against the outside) and R̄↑ per channel.
struct DiffuseBase {
    albedo: Vec<f64>,
    eta: f64,
    r_up: Vec<f64>,
}

/// Everything the adding-doubling produces, tabulated over the cosine it is run for, at nodes uniform in √cos θ
/// (denser at grazing angles, where a smooth top's Fresnel term rises steeply): evaluation interpolates linearly
/// instead of re-running the loop. The interpolation error is measured and asserted in tests/test_belcour.py.
const TABLE_NODES: usize = 512;

struct LobeTable {
    lobes: usize,
    /// [node][lobe][channel]
    energy: Vec<f64>,
    /// [node][lobe]
    alpha: Vec<f64>,
    /// [node][channel]: energy transmitted down to the base (T0i) and up from it (Ti0).
    t_down: Vec<f64>,
    t_up: Vec<f64>,
}

pub struct Prepared {
    steps: Vec<Step>,
    diffuse: Option<DiffuseBase>,
    table: Option<LobeTable>,
    g2: G2Form,
    symmetric: bool,
    variant: Variant,
    channels: usize,
}

pub fn prepare(stack: &Stack, opts: &Options) -> Result<Prepared> {
    let mut steps = Vec::new();
    let mut diffuse = None;
    let mut above = vec![stack.ext_ior; stack.channels];
    for (i, layer) in stack.layers.iter().enumerate() {
        let alpha = match layer {
            Layer::Dielectric { alpha, .. } | Layer::Conductor { alpha, .. } => {
                if alpha.0 != alpha.1 {
                    return value_error(format!(
                        "layer {i}: model 'belcour' is isotropic; anisotropic roughness {alpha:?} needs the \
                         Yamaguchi 2019 extension (not implemented yet)"
                    ));
                }
                alpha.0
            }
            Layer::Diffuse { roughness, .. } if *roughness > 0.0 => {
                return value_error("model 'belcour' takes a Lambertian diffuse base (roughness 0)");
            }
            Layer::Diffuse { .. } => 0.0,
        };
        match layer {
            Layer::Dielectric { ior, thickness, sigma_a, sigma_s, g, .. } => {
                let eta = ior.iter().zip(&above).map(|(n, a)| n / a).collect();
                steps.push(Step::Interface { eta, kappa: vec![0.0; stack.channels], alpha, conductor: false });
                if *thickness > 0.0 && sigma_a.iter().chain(sigma_s).any(|&s| s > 0.0) {
                    steps.push(Step::Medium {
                        thickness: *thickness,
                        sigma_a: sigma_a.clone(),
                        sigma_s: sigma_s.clone(),
                        g: *g,
                    });
                }
                above = ior.clone();
            }
            Layer::Conductor { ior, k, .. } => {
                let eta = ior.iter().zip(&above).map(|(n, a)| n / a).collect();
                let kappa = k.iter().zip(&above).map(|(k, a)| k / a).collect();
                steps.push(Step::Interface { eta, kappa, alpha, conductor: true });
            }
            Layer::Diffuse { albedo, .. } => {
                let eta = above.iter().sum::<f64>() / above.len() as f64 / stack.ext_ior;
                diffuse = Some(DiffuseBase { albedo: albedo.clone(), eta, r_up: vec![] });
            }
        }
    }
    let mut p = Prepared {
        steps,
        diffuse: None,
        table: None,
        g2: opts.g2,
        symmetric: opts.symmetric,
        variant: opts.belcour,
        channels: stack.channels,
    };
    if let Some(mut d) = diffuse {
        d.r_up = p.hemispherical_reflectance_from_below(d.eta);
        p.diffuse = Some(d);
    }
    if opts.belcour_table {
        p.table = Some(p.tabulate());
    }
    Ok(p)
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// Energies and variances of the stack above the current interface (Belcour 2018 §5, reference-code notation).
struct State {
    r0i: Vec<f64>,
    t0i: Vec<f64>,
    ri0: Vec<f64>,
    ti0: Vec<f64>,
    s_r0i: f64,
    s_t0i: f64,
    s_ri0: f64,
    s_ti0: f64,
    j0i: f64,
    ji0: f64,
}

/// The statistics of one step: energies per channel, scalar variances and Jacobians.
struct StepStats {
    r12: Vec<f64>,
    t12: Vec<f64>,
    r21: Vec<f64>,
    t21: Vec<f64>,
    s_r12: f64,
    s_t12: f64,
    s_r21: f64,
    s_t21: f64,
    j12: f64,
    j21: f64,
}

impl State {
    /// Adds one step below the stack (adding-doubling on energies and variances); returns the energy and
    /// roughness of the lobe reflected by this step.
    fn add(&mut self, st: &StepStats, j21_in_variance: bool) -> (Vec<f64>, f64) {
        let c = self.r0i.len();
        let denom: Vec<f64> = (0..c).map(|k| 1.0 - self.ri0[k] * st.r12[k]).collect();
        let ok = mean(&denom) > 0.0;
        let safe = |x: f64, k: usize| if ok { x / denom[k] } else { 0.0 };
        let m_r0i: Vec<f64> = (0..c).map(|k| safe(self.t0i[k] * st.r12[k] * self.ti0[k], k)).collect();
        let m_ri0: Vec<f64> = (0..c).map(|k| safe(st.t21[k] * self.ri0[k] * st.t12[k], k)).collect();
        let m_rr: Vec<f64> = (0..c).map(|k| safe(self.ri0[k] * st.r12[k], k)).collect();
        let e_r0i: Vec<f64> = (0..c).map(|k| self.r0i[k] + m_r0i[k]).collect();
        let e_t0i: Vec<f64> = (0..c).map(|k| safe(self.t0i[k] * st.t12[k], k)).collect();
        let e_ri0: Vec<f64> = (0..c).map(|k| st.r21[k] + m_ri0[k]).collect();
        let e_ti0: Vec<f64> = (0..c).map(|k| safe(st.t21[k] * self.ti0[k], k)).collect();
        let (r0i, er0i, eri0, mr0i, mri0, mrr, r21) =
            (mean(&self.r0i), mean(&e_r0i), mean(&e_ri0), mean(&m_r0i), mean(&m_ri0), mean(&m_rr), mean(&st.r21));
        let below = self.s_t0i + st.s_r12 + mrr * (st.s_r12 + self.s_ri0);
        let lobe_variance = self.s_ti0 + self.j0i * below;
        let s_r0i = if er0i > 0.0 { (r0i * self.s_r0i + mr0i * lobe_variance) / er0i } else { 0.0 };
        let j = if j21_in_variance { st.j21 } else { st.j12 };
        let s_t0i = j * self.s_t0i + st.s_t12 + j * (st.s_r12 + self.s_ri0) * mrr;
        let s_ri0 = if eri0 > 0.0 {
            (r21 * st.s_r21 + mri0 * (st.s_t12 + j * (st.s_t21 + self.s_ri0 + mrr * (st.s_r12 + self.s_ri0)))) / eri0
        } else {
            0.0
        };
        let s_ti0 = self.ji0 * st.s_t21 + self.s_ti0 + self.ji0 * (st.s_r12 + self.s_ri0) * mrr;
        let lobe = if mr0i > 0.0 { (m_r0i, alpha_from_variance(lobe_variance)) } else { (vec![0.0; c], 0.0) };
        (self.r0i, self.t0i, self.ri0, self.ti0) = (e_r0i, e_t0i, e_ri0, e_ti0);
        (self.s_r0i, self.s_t0i, self.s_ri0, self.s_ti0) = (s_r0i, s_t0i, s_ri0, s_ti0);
        self.j0i *= st.j12;
        self.ji0 *= st.j21;
        lobe
    }
}

impl Prepared {
    /// R̄↑ = ∫ R↑(μ) 2μ dμ over cosines μ in the medium above the base. Below the critical cosine μc light is totally
    /// reflected; above it, Snell's law (μ dμ = μo dμo / η², η the total relative IOR) turns the integral into one
    /// over the outside cosine μo, where the integrand is smooth: R̄↑ = μc² + ∫ R↑(μo) 2μo dμo / η².
    ///
    /// Totally reflected light still crosses the slab directly above the base twice: that part is
    /// ∫₀^μc 2μ e^{−2τ/μ} dμ with τ the slab's optical depth (exact for one slab; deeper slabs are ignored there).
    fn hemispherical_reflectance_from_below(&self, eta: f64) -> Vec<f64> {
        let mu_c = if eta > 1.0 { (1.0 - 1.0 / (eta * eta)).sqrt() } else { 0.0 };
        let mu_o_min = (1.0 - eta * eta).max(0.0).sqrt();
        let tau: Vec<f64> = match self.steps.last() {
            Some(Step::Medium { thickness, sigma_a, sigma_s, .. }) => {
                sigma_a.iter().zip(sigma_s).map(|(a, s)| (a + s) * thickness).collect()
            }
            _ => vec![0.0; self.channels],
        };
        let mut r: Vec<f64> = tau
            .iter()
            .map(|t| fresnel::integrate(|mu| 2.0 * mu * (-2.0 * t / mu.max(1e-12)).exp(), 0.0, mu_c, 4))
            .collect();
        let half = 0.5 * (1.0 - mu_o_min);
        for (x, w) in crate::optics::fresnel::gauss_legendre(16) {
            let mu_o = mu_o_min + half * (1.0 + x);
            let (_, state) = self.adding(mu_o);
            for (rk, ri0) in r.iter_mut().zip(&state.ri0) {
                *rk += w * half * 2.0 * mu_o * ri0 / (eta * eta);
            }
        }
        r
    }

    fn tabulate(&self) -> LobeTable {
        let c = self.channels;
        let runs: Vec<_> =
            (0..TABLE_NODES).map(|k| self.adding((k as f64 / (TABLE_NODES - 1) as f64).powi(2))).collect();
        let lobes = runs.iter().map(|(l, _)| l.len()).max().unwrap_or(0);
        let mut t = LobeTable {
            lobes,
            energy: vec![0.0; TABLE_NODES * lobes * c],
            alpha: vec![0.0; TABLE_NODES * lobes],
            t_down: Vec::with_capacity(TABLE_NODES * c),
            t_up: Vec::with_capacity(TABLE_NODES * c),
        };
        for (k, (l, state)) in runs.iter().enumerate() {
            for (j, (e, a)) in l.iter().enumerate() {
                t.energy[(k * lobes + j) * c..(k * lobes + j + 1) * c].copy_from_slice(e);
                t.alpha[k * lobes + j] = *a;
            }
            t.t_down.extend_from_slice(&state.t0i);
            t.t_up.extend_from_slice(&state.ti0);
        }
        t
    }

    /// The lobes (energy per channel, GGX roughness) for a viewing cosine `cos_theta`.
    pub fn lobes(&self, cos_theta: f64) -> Vec<(Vec<f64>, f64)> {
        self.adding(cos_theta).0
    }

    /// Runs the adding-doubling from the top for cosine `cos_theta`: the lobes and the final stack statistics.
    fn adding(&self, cos_theta: f64) -> (Vec<(Vec<f64>, f64)>, State) {
        let c = self.channels;
        let fgd = tables::fgd();
        let mut s = State {
            r0i: vec![0.0; c],
            t0i: vec![1.0; c],
            ri0: vec![0.0; c],
            ti0: vec![1.0; c],
            s_r0i: 0.0,
            s_t0i: 0.0,
            s_ri0: 0.0,
            s_ti0: 0.0,
            j0i: 1.0,
            ji0: 1.0,
        };
        let mut cti = cos_theta.clamp(1e-4, 1.0);
        let mut lobes = Vec::new();
        for step in &self.steps {
            match step {
                Step::Interface { eta, kappa, alpha, conductor } => {
                    let n12 = mean(eta);
                    let stt = (1.0 - cti * cti).max(0.0).sqrt() / n12;
                    let ctt = if stt <= 1.0 { (1.0 - stt * stt).sqrt() } else { -1.0 };
                    let transmissive = ctt > 0.0 && !conductor;
                    let s_r12 = variance_from_alpha(*alpha);
                    // Transmission roughness scale s = |η cos θt − cos θi| / (2η cos θt) (and its reverse), with the
                    // cosines frozen to 1 as in the reference code, or real as in the paper.
                    let (ci, ct) = if self.variant.real_cosines { (cti, ctt) } else { (1.0, 1.0) };
                    let (s_t12, s_t21, j12, j21) = if transmissive {
                        (
                            variance_from_alpha(alpha * 0.5 * (ct * n12 - ci).abs() / (ct * n12)),
                            variance_from_alpha(alpha * 0.5 * (ci / n12 - ct).abs() / (ci / n12)),
                            ctt / cti * n12,
                            cti / ctt / n12,
                        )
                    } else {
                        (0.0, 0.0, 1.0, 1.0)
                    };
                    // FGD at the roughness of the incoming lobe convolved with the interface.
                    let temp_alpha = alpha_from_variance(s.s_t0i + s_r12);
                    let r12: Vec<f64> = (0..c)
                        .map(|k| {
                            if temp_alpha == 0.0 || self.variant.fresnel_energy {
                                fresnel::conductor(cti, eta[k], kappa[k]) // FGD at α = 0 is the Fresnel term itself
                            } else {
                                fgd.lookup(cti, temp_alpha, eta[k], kappa[k])
                            }
                        })
                        .collect();
                    let t12: Vec<f64> = if transmissive { r12.iter().map(|r| 1.0 - r).collect() } else { vec![0.0; c] };
                    let (r21, t21) =
                        if transmissive { (r12.clone(), t12.clone()) } else { (vec![0.0; c], vec![0.0; c]) };
                    let st = StepStats { r12, t12, r21, t21, s_r12, s_t12, s_r21: s_r12, s_t21, j12, j21 };
                    lobes.push(s.add(&st, self.variant.jacobian_j21));
                    if !transmissive {
                        s.t0i.fill(0.0);
                        s.ti0.fill(0.0);
                        return (lobes, s);
                    }
                    cti = ctt;
                }
                Step::Medium { thickness, sigma_a, sigma_s, g } => {
                    let t: Vec<f64> = (0..c)
                        .map(|k| {
                            (1.0 + sigma_s[k] * thickness / cti)
                                * (-(thickness / cti) * (sigma_a[k] + sigma_s[k])).exp()
                        })
                        .collect();
                    let s_t = if mean(sigma_s) > 0.0 { hg_variance(*g) } else { 0.0 };
                    let zero = vec![0.0; c];
                    let st = StepStats {
                        r12: zero.clone(),
                        t12: t.clone(),
                        r21: zero,
                        t21: t,
                        s_r12: 0.0,
                        s_t12: s_t,
                        s_r21: 0.0,
                        s_t21: s_t,
                        j12: 1.0,
                        j21: 1.0,
                    };
                    s.add(&st, self.variant.jacobian_j21);
                }
            }
        }
        (lobes, s)
    }

    pub fn eval(&self, wi: DVec3, wo: DVec3, out: &mut [f64]) {
        out.fill(0.0);
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return;
        }
        let h = (wi + wo).normalize();
        let cos_theta = if self.symmetric { wo.dot(h).abs() } else { wo.z };
        if let Some(t) = &self.table {
            return self.eval_tabulated(t, wi, wo, h, cos_theta, out);
        }
        let (lobes, view) = self.adding(cos_theta);
        for (coeff, alpha) in &lobes {
            self.add_lobe(*alpha, |ch| coeff[ch], wi, wo, h, out);
        }
        if self.diffuse.is_some() {
            // T↓ at θi and T↑ at θo (not at |wo·h|): symmetric under exchange, since T0i = Ti0 in this model.
            let light = self.adding(wi.z).1;
            let view = if self.symmetric { self.adding(wo.z).1 } else { view };
            self.add_diffuse(|ch| light.t0i[ch], |ch| view.ti0[ch], out);
        }
    }

    /// Adds one GGX lobe of roughness `alpha` with per-channel `energy`; a lobe of roughness 0 is a Dirac delta,
    /// not part of f.
    fn add_lobe(&self, alpha: f64, energy: impl Fn(usize) -> f64, wi: DVec3, wo: DVec3, h: DVec3, out: &mut [f64]) {
        if alpha <= 0.0 {
            return;
        }
        let mf = Microfacet::new(crate::optics::microfacet::Distribution::Ggx, alpha, alpha, 0.0);
        let shape = mf.d(h) * mf.g2(self.g2, wi, wo, h) / (4.0 * wi.z * wo.z);
        for (ch, o) in out.iter_mut().enumerate() {
            *o += energy(ch) * shape;
        }
    }

    /// Adds the diffuse base ρ/π · T↓ T↑ / ((1 − ρ R̄↑) η²) from the energies transmitted down and up per channel.
    fn add_diffuse(&self, down: impl Fn(usize) -> f64, up: impl Fn(usize) -> f64, out: &mut [f64]) {
        let Some(d) = &self.diffuse else { return };
        for (ch, o) in out.iter_mut().enumerate() {
            let rho = d.albedo[ch];
            *o += rho * FRAC_1_PI * down(ch) * up(ch) / ((1.0 - rho * d.r_up[ch]) * d.eta * d.eta);
        }
    }

    /// Linear interpolation (in √cos θ) of a cosine in the table: (node, weight of the next node).
    fn node(cos_theta: f64) -> (usize, f64) {
        let x = cos_theta.clamp(0.0, 1.0).sqrt() * (TABLE_NODES - 1) as f64;
        let k = (x as usize).min(TABLE_NODES - 2);
        (k, x - k as f64)
    }

    fn eval_tabulated(&self, t: &LobeTable, wi: DVec3, wo: DVec3, h: DVec3, cos_theta: f64, out: &mut [f64]) {
        let c = self.channels;
        let (k, w) = Self::node(cos_theta);
        let lerp = |v: &[f64], stride: usize, j: usize| v[k * stride + j] * (1.0 - w) + v[(k + 1) * stride + j] * w;
        for j in 0..t.lobes {
            self.add_lobe(lerp(&t.alpha, t.lobes, j), |ch| lerp(&t.energy, t.lobes * c, j * c + ch), wi, wo, h, out);
        }
        if self.diffuse.is_some() {
            let ((ki, wi_w), (ko, wo_w)) = (Self::node(wi.z), Self::node(wo.z));
            let down = |ch| t.t_down[ki * c + ch] * (1.0 - wi_w) + t.t_down[(ki + 1) * c + ch] * wi_w;
            let up = |ch| t.t_up[ko * c + ch] * (1.0 - wo_w) + t.t_up[(ko + 1) * c + ch] * wo_w;
            self.add_diffuse(down, up, out);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn smooth_coat_over_lambert_is_the_closed_form() {
        let stack = Stack::new(
            vec![
                Layer::Dielectric {
                    ior: vec![1.5],
                    alpha: (0.0, 0.0),
                    angle: 0.0,
                    thickness: 0.0,
                    sigma_a: vec![0.0],
                    sigma_s: vec![0.0],
                    g: 0.0,
                },
                Layer::Diffuse { albedo: vec![0.7], roughness: 0.0 },
            ],
            1.0,
        )
        .unwrap();
        let p = prepare(&stack, &Options { belcour_table: false, ..Options::default() }).unwrap();
        let f_int = crate::optics::fresnel::diffuse_reflectance(1.0 / 1.5);
        for (wi, wo) in [(DVec3::new(0.3, 0.1, 0.9), DVec3::new(-0.6, 0.2, 0.5)), (DVec3::new(0.9, 0.0, 0.2), DVec3::Z)]
        {
            let (wi, wo) = (wi.normalize(), wo.normalize());
            let mut out = [0.0];
            p.eval(wi, wo, &mut out);
            let exact = crate::models::microfacet::smooth_coat_lambert(0.7, 1.5, f_int, wi.z, wo.z);
            assert!((out[0] - exact).abs() < 1e-9 * exact, "{} vs {exact}", out[0]);
        }
    }

    #[test]
    fn variance_map_round_trips() {
        for a in [0.0, 0.01, 0.1, 0.5, 0.9] {
            assert!((alpha_from_variance(variance_from_alpha(a)) - a).abs() < 1e-12);
        }
    }

    #[test]
    fn single_conductor_has_one_lobe_of_its_roughness_and_fgd_energy() {
        let stack =
            Stack::new(vec![Layer::Conductor { ior: vec![0.2], k: vec![3.0], alpha: (0.3, 0.3), angle: 0.0 }], 1.0)
                .unwrap();
        let p = prepare(&stack, &Options::default()).unwrap();
        let lobes = p.lobes(0.7);
        assert_eq!(lobes.len(), 1);
        assert!((lobes[0].1 - 0.3).abs() < 1e-9);
        assert!((lobes[0].0[0] - tables::fgd().lookup(0.7, 0.3, 0.2, 3.0)).abs() < 1e-12);
    }
}
