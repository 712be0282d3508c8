//! The adding-doubling of energies and covariances through the stack (Belcour 2018 §5, in the form of the
//! published reference loop), and the hemispherical reflectance from below that a diffuse base sees.

use super::cov::{alpha_from_variance, hg_variance, variance_from_alpha, Cov, Lobe};
use super::Prepared;
use crate::optics::{fresnel, jacobian};
use crate::tables;

/// Belcour's optional TIR step (reference code, "decoupling approximation"): before interface i > 0, a factor T of
/// the energy Ti0 that goes back up through interface i − 1 (cosine cti below it, roughness of the lobe, relative
/// IOR η < 1 going up) is moved into Ri0: Ri0 += (1 − T) Ti0, Ti0 ← T Ti0.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tir {
    /// No TIR step.
    Off,
    /// T = the rough interface's mean transmittance E[1 − F] (what the reference code's table holds): the Fresnel
    /// factor already in Ti0 is applied a second time.
    Transmittance,
    /// T = 1 − the fraction of visible normals that totally reflect: only the TIR itself.
    Fraction,
}

impl Tir {
    /// The names `from_str` reads, in the order of `ALL`.
    pub const NAMES: [&'static str; 3] = ["off", "transmittance", "fraction"];
    pub const ALL: [Tir; 3] = [Tir::Off, Tir::Transmittance, Tir::Fraction];
}

impl std::str::FromStr for Tir {
    type Err = crate::error::Error;
    fn from_str(s: &str) -> crate::error::Result<Self> {
        crate::error::parse_choice("tir", s, &Self::NAMES, &Self::ALL)
    }
}

pub(super) enum Step {
    /// A rough interface: relative IOR per channel (below / above), κ per channel (conductors), roughness
    /// (αx, αy) along its tangent frame rotated by `angle`.
    Interface { eta: Vec<f64>, kappa: Vec<f64>, alpha: (f64, f64), angle: f64, conductor: bool },
    /// A slab: thickness and coefficients per channel.
    Medium { thickness: f64, sigma_a: Vec<f64>, sigma_s: Vec<f64>, g: f64 },
}

/// A Lambertian base: albedo, relative IOR of the medium above it (against the outside) and R̄↑ per channel.
pub(super) struct DiffuseBase {
    pub(super) albedo: Vec<f64>,
    pub(super) eta: f64,
    pub(super) r_up: Vec<f64>,
}

/// The mean over channels.
pub(super) fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// Energies and variances of the stack above the current interface (Belcour 2018 §5, reference-code notation).
pub(super) struct State {
    pub(super) r0i: Vec<f64>,
    pub(super) t0i: Vec<f64>,
    pub(super) ri0: Vec<f64>,
    pub(super) ti0: Vec<f64>,
    pub(super) s_r0i: Cov,
    pub(super) s_t0i: Cov,
    pub(super) s_ri0: Cov,
    pub(super) s_ti0: Cov,
    pub(super) j0i: f64,
    pub(super) ji0: f64,
}

/// The statistics of one step: energies per channel, covariances and (first-order, scalar) Jacobians.
pub(super) struct StepStats {
    pub(super) r12: Vec<f64>,
    pub(super) t12: Vec<f64>,
    pub(super) r21: Vec<f64>,
    pub(super) t21: Vec<f64>,
    pub(super) s_r12: Cov,
    pub(super) s_t12: Cov,
    pub(super) s_r21: Cov,
    pub(super) s_t21: Cov,
    pub(super) j12: f64,
    pub(super) j21: f64,
}

impl State {
    /// Adds one step below the stack (adding-doubling on energies and covariances); returns the lobe reflected by
    /// this step.
    pub(super) fn add(&mut self, st: &StepStats, j21_in_variance: bool) -> Lobe {
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
        let s_r0i = if er0i > 0.0 { (r0i * self.s_r0i + mr0i * lobe_variance) / er0i } else { Cov::ZERO };
        let j = if j21_in_variance { st.j21 } else { st.j12 };
        let s_t0i = j * self.s_t0i + st.s_t12 + j * (st.s_r12 + self.s_ri0) * mrr;
        let s_ri0 = if eri0 > 0.0 {
            (r21 * st.s_r21 + mri0 * (st.s_t12 + j * (st.s_t21 + self.s_ri0 + mrr * (st.s_r12 + self.s_ri0)))) / eri0
        } else {
            Cov::ZERO
        };
        let s_ti0 = self.ji0 * st.s_t21 + self.s_ti0 + self.ji0 * (st.s_r12 + self.s_ri0) * mrr;
        let lobe = if mr0i > 0.0 {
            Lobe { energy: m_r0i, cov: lobe_variance }
        } else {
            Lobe { energy: vec![0.0; c], cov: Cov::ZERO }
        };
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
    pub(super) fn hemispherical_reflectance_from_below(&self, eta: f64) -> Vec<f64> {
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
            .map(|t| crate::quadrature::integrate(|mu| 2.0 * mu * (-2.0 * t / mu.max(1e-12)).exp(), 0.0, mu_c, 4))
            .collect();
        let half = 0.5 * (1.0 - mu_o_min);
        for (x, w) in crate::quadrature::gauss_legendre(16) {
            let mu_o = mu_o_min + half * (1.0 + x);
            let (_, state) = self.adding(mu_o, 1.0, 0.0);
            for (rk, ri0) in r.iter_mut().zip(&state.ri0) {
                *rk += w * half * 2.0 * mu_o * ri0 / (eta * eta);
            }
        }
        r
    }

    /// Runs the adding-doubling from the top for a viewing direction of cosine `cos_theta` and azimuth
    /// (`cos_phi`, `sin_phi`): the lobes and the final stack statistics.
    pub(super) fn adding(&self, cos_theta: f64, cos_phi: f64, sin_phi: f64) -> (Vec<Lobe>, State) {
        let c = self.channels;
        let fgd = tables::fgd();
        let mut s = State {
            r0i: vec![0.0; c],
            t0i: vec![1.0; c],
            ri0: vec![0.0; c],
            ti0: vec![1.0; c],
            s_r0i: Cov::ZERO,
            s_t0i: Cov::ZERO,
            s_ri0: Cov::ZERO,
            s_ti0: Cov::ZERO,
            j0i: 1.0,
            ji0: 1.0,
        };
        let mut cti = cos_theta.clamp(1e-4, 1.0);
        let mut lobes = Vec::new();
        // Mean relative IOR of the last interface crossed (below / above), for the TIR step.
        let mut eta_above: Option<f64> = None;
        for step in &self.steps {
            match step {
                Step::Interface { eta, kappa, alpha: (ax, ay), angle, conductor } => {
                    let n12 = mean(eta);
                    let stt = (1.0 - cti * cti).max(0.0).sqrt() / n12;
                    let ctt = if stt <= 1.0 { (1.0 - stt * stt).sqrt() } else { -1.0 };
                    let transmissive = ctt > 0.0 && !conductor;
                    // Each axis of the interface's covariance through the roughness map h.
                    let cov = |scale: f64| {
                        Cov::oriented(variance_from_alpha(ax * scale), variance_from_alpha(ay * scale), *angle)
                    };
                    let s_r12 = cov(1.0);
                    // Transmission roughness scale s: how far the transmitted mean moves per unit of facet slope,
                    // |J_t(θi)|, over how far the reflection at the next interface moves it, |J_r(θt)| (and the
                    // reverse going up). At the lobe mean (h = n) the exact Jacobians are these multiples of I, so
                    // this is the exact-Jacobian transport at the mean and the paper's |η cos θt − cos θi| /
                    // (2η cos θt); the reference code freezes the cosines to 1 (normal incidence).
                    let (ci, ct) = if self.opts.real_cosines { (cti, ctt) } else { (1.0, 1.0) };
                    let scale = |cos_i: f64, cos_t: f64, eta: f64| {
                        let t = jacobian::refraction_scale(cos_i, eta).unwrap_or(0.0);
                        t.abs() / jacobian::reflection_scale(cos_t)
                    };
                    let (s_t12, s_t21, j12, j21) = if transmissive {
                        (cov(scale(ci, ct, n12)), cov(scale(ct, ci, 1.0 / n12)), ctt / cti * n12, cti / ctt / n12)
                    } else {
                        (Cov::ZERO, Cov::ZERO, 1.0, 1.0)
                    };
                    // FGD at the roughness, along the viewing azimuth, of the incoming lobe convolved with the
                    // interface.
                    let temp_alpha = alpha_from_variance((s.s_t0i + s_r12).along(cos_phi, sin_phi));
                    if let Some(up) = eta_above.filter(|_| self.opts.tir != Tir::Off) {
                        let table = tables::steinberg::steinberg();
                        let t = match self.opts.tir {
                            Tir::Transmittance => table.tabulated(cti, temp_alpha, 1.0 / up).0,
                            _ => 1.0 - table.tir_fraction(cti, temp_alpha, 1.0 / up),
                        };
                        for (r, ti) in s.ri0.iter_mut().zip(s.ti0.iter_mut()) {
                            *r = (*r + (1.0 - t) * *ti).clamp(0.0, 1.0);
                            *ti *= t;
                        }
                    }
                    let r12: Vec<f64> = (0..c)
                        .map(|k| {
                            if temp_alpha == 0.0 || self.opts.fresnel_energy {
                                fresnel::conductor(cti, eta[k], kappa[k]) // FGD at α = 0 is the Fresnel term itself
                            } else {
                                fgd.lookup(cti, temp_alpha, eta[k], kappa[k])
                            }
                        })
                        .collect();
                    let t12: Vec<f64> = if !transmissive {
                        vec![0.0; c]
                    } else if self.opts.microfacet_transmission && temp_alpha > 0.0 {
                        let table = tables::steinberg::steinberg();
                        eta.iter().map(|e| table.transmitted(cti, temp_alpha, *e)).collect()
                    } else {
                        r12.iter().map(|r| 1.0 - r).collect()
                    };
                    let (r21, t21) =
                        if transmissive { (r12.clone(), t12.clone()) } else { (vec![0.0; c], vec![0.0; c]) };
                    let st = StepStats { r12, t12, r21, t21, s_r12, s_t12, s_r21: s_r12, s_t21, j12, j21 };
                    lobes.push(s.add(&st, self.opts.jacobian_j21));
                    if !transmissive {
                        s.t0i.fill(0.0);
                        s.ti0.fill(0.0);
                        return (lobes, s);
                    }
                    cti = ctt;
                    eta_above = Some(n12);
                }
                Step::Medium { thickness, sigma_a, sigma_s, g } => {
                    let t: Vec<f64> = (0..c)
                        .map(|k| {
                            // (1 + σs d/μ) e^{−σt d/μ} ≤ (1 + τ) e^{−τ}: 0 once τ overflows the exponential.
                            let tau = (thickness / cti) * (sigma_a[k] + sigma_s[k]);
                            if tau < 745.0 {
                                (1.0 + sigma_s[k] * thickness / cti) * (-tau).exp()
                            } else {
                                0.0
                            }
                        })
                        .collect();
                    let s_t = if mean(sigma_s) > 0.0 { Cov::iso(hg_variance(*g)) } else { Cov::ZERO };
                    let zero = vec![0.0; c];
                    let st = StepStats {
                        r12: zero.clone(),
                        t12: t.clone(),
                        r21: zero,
                        t21: t,
                        s_r12: Cov::ZERO,
                        s_t12: s_t,
                        s_r21: Cov::ZERO,
                        s_t21: s_t,
                        j12: 1.0,
                        j21: 1.0,
                    };
                    s.add(&st, self.opts.jacobian_j21);
                }
            }
        }
        (lobes, s)
    }
}
