//! The adding-doubling of energies and covariances through the stack (Belcour 2018 §5, in the form of the
//! published reference loop), and the hemispherical reflectance from below that a diffuse base sees.

use super::cov::{alpha_from_variance, hg_variance, variance_from_alpha, Cov, Lobe};
use super::Options;
use crate::dual::Real;
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

/// One step of the stack, its parameters in f64 or in Duals (parameter gradients).
pub(super) enum Step<T = f64> {
    /// A rough interface: relative IOR per channel (below / above), κ per channel (conductors), roughness
    /// (αx, αy) along its tangent frame rotated by `angle`.
    Interface { eta: Vec<T>, kappa: Vec<T>, alpha: (T, T), angle: T, conductor: bool },
    /// A slab: thickness and coefficients per channel.
    Medium { thickness: T, sigma_a: Vec<T>, sigma_s: Vec<T>, g: T },
}

/// A Lambertian base: albedo, relative IOR of the medium above it (against the outside) and R̄↑ per channel.
pub(super) struct DiffuseBase<T = f64> {
    pub(super) albedo: Vec<T>,
    pub(super) eta: T,
    pub(super) r_up: Vec<T>,
}

/// The mean over channels.
pub(super) fn mean<T: Real>(v: &[T]) -> T {
    v.iter().fold(T::from(0.0), |a, &b| a + b) / v.len() as f64
}

/// Energies and variances of the stack above the current interface (Belcour 2018 §5, reference-code notation).
pub(super) struct State<T = f64> {
    pub(super) r0i: Vec<T>,
    pub(super) t0i: Vec<T>,
    pub(super) ri0: Vec<T>,
    pub(super) ti0: Vec<T>,
    pub(super) s_r0i: Cov<T>,
    pub(super) s_t0i: Cov<T>,
    pub(super) s_ri0: Cov<T>,
    pub(super) s_ti0: Cov<T>,
    pub(super) j0i: T,
    pub(super) ji0: T,
}

/// The statistics of one step: energies per channel, covariances and (first-order, scalar) Jacobians.
pub(super) struct StepStats<T> {
    pub(super) r12: Vec<T>,
    pub(super) t12: Vec<T>,
    pub(super) r21: Vec<T>,
    pub(super) t21: Vec<T>,
    pub(super) s_r12: Cov<T>,
    pub(super) s_t12: Cov<T>,
    pub(super) s_r21: Cov<T>,
    pub(super) s_t21: Cov<T>,
    pub(super) j12: T,
    pub(super) j21: T,
}

impl<T: Real> State<T> {
    /// Adds one step below the stack (adding-doubling on energies and covariances); returns the lobe reflected by
    /// this step.
    pub(super) fn add(&mut self, st: &StepStats<T>, j21_in_variance: bool) -> Lobe<T> {
        let c = self.r0i.len();
        let zero = T::from(0.0);
        let denom: Vec<T> = (0..c).map(|k| T::from(1.0) - self.ri0[k] * st.r12[k]).collect();
        let ok = mean(&denom).value() > 0.0;
        let safe = |x: T, k: usize| if ok { x / denom[k] } else { zero };
        let m_r0i: Vec<T> = (0..c).map(|k| safe(self.t0i[k] * st.r12[k] * self.ti0[k], k)).collect();
        let m_ri0: Vec<T> = (0..c).map(|k| safe(st.t21[k] * self.ri0[k] * st.t12[k], k)).collect();
        let m_rr: Vec<T> = (0..c).map(|k| safe(self.ri0[k] * st.r12[k], k)).collect();
        let e_r0i: Vec<T> = (0..c).map(|k| self.r0i[k] + m_r0i[k]).collect();
        let e_t0i: Vec<T> = (0..c).map(|k| safe(self.t0i[k] * st.t12[k], k)).collect();
        let e_ri0: Vec<T> = (0..c).map(|k| st.r21[k] + m_ri0[k]).collect();
        let e_ti0: Vec<T> = (0..c).map(|k| safe(st.t21[k] * self.ti0[k], k)).collect();
        let (r0i, er0i, eri0, mr0i, mri0, mrr, r21) =
            (mean(&self.r0i), mean(&e_r0i), mean(&e_ri0), mean(&m_r0i), mean(&m_ri0), mean(&m_rr), mean(&st.r21));
        let below = self.s_t0i + st.s_r12 + (st.s_r12 + self.s_ri0) * mrr;
        let lobe_variance = self.s_ti0 + below * self.j0i;
        let s_r0i = if er0i.value() > 0.0 { (self.s_r0i * r0i + lobe_variance * mr0i) / er0i } else { Cov::zero() };
        let j = if j21_in_variance { st.j21 } else { st.j12 };
        let s_t0i = self.s_t0i * j + st.s_t12 + (st.s_r12 + self.s_ri0) * j * mrr;
        let s_ri0 = if eri0.value() > 0.0 {
            (st.s_r21 * r21 + (st.s_t12 + (st.s_t21 + self.s_ri0 + (st.s_r12 + self.s_ri0) * mrr) * j) * mri0) / eri0
        } else {
            Cov::zero()
        };
        let s_ti0 = st.s_t21 * self.ji0 + self.s_ti0 + (st.s_r12 + self.s_ri0) * self.ji0 * mrr;
        let lobe = if mr0i.value() > 0.0 {
            Lobe { energy: m_r0i, cov: lobe_variance }
        } else {
            Lobe { energy: vec![zero; c], cov: Cov::zero() }
        };
        (self.r0i, self.t0i, self.ri0, self.ti0) = (e_r0i, e_t0i, e_ri0, e_ti0);
        (self.s_r0i, self.s_t0i, self.s_ri0, self.s_ti0) = (s_r0i, s_t0i, s_ri0, s_ti0);
        self.j0i = self.j0i * st.j12;
        self.ji0 = self.ji0 * st.j21;
        lobe
    }
}

/// R̄↑ = ∫ R↑(μ) 2μ dμ over cosines μ in the medium above the base. Below the critical cosine μc light is totally
/// reflected; above it, Snell's law (μ dμ = μo dμo / η², η the total relative IOR) turns the integral into one over
/// the outside cosine μo, where the integrand is smooth: R̄↑ = μc² + ∫ R↑(μo) 2μo dμo / η².
///
/// Totally reflected light still crosses the slab directly above the base twice: that part is ∫₀^μc 2μ e^{−2τ/μ} dμ
/// with τ the slab's optical depth (exact for one slab; deeper slabs are ignored there).
pub(super) fn hemispherical_reflectance_from_below<T: Real>(
    steps: &[Step<T>],
    opts: &Options,
    channels: usize,
    eta: T,
) -> Vec<T> {
    let one = T::from(1.0);
    let mu_c = if eta.value() > 1.0 { (one - one / (eta * eta)).sqrt() } else { T::from(0.0) };
    let mu_o_min = (one - eta * eta).max_c(0.0).sqrt();
    let tau: Vec<T> = match steps.last() {
        Some(Step::Medium { thickness, sigma_a, sigma_s, .. }) => {
            sigma_a.iter().zip(sigma_s).map(|(&a, &s)| (a + s) * *thickness).collect()
        }
        _ => vec![T::from(0.0); channels],
    };
    let mut r: Vec<T> = tau
        .iter()
        .map(|&t| {
            crate::quadrature::integrate(|mu: T| mu * 2.0 * (-(t * 2.0) / mu.max_c(1e-12)).exp(), T::from(0.0), mu_c, 4)
        })
        .collect();
    let half = (one - mu_o_min) * 0.5;
    for (x, w) in crate::quadrature::gauss_legendre(16) {
        let mu_o = mu_o_min + half * (1.0 + x);
        let (_, state) = adding(steps, opts, channels, mu_o, 1.0, 0.0);
        for (rk, &ri0) in r.iter_mut().zip(&state.ri0) {
            *rk = *rk + half * w * 2.0 * mu_o * ri0 / (eta * eta);
        }
    }
    r
}

/// Runs the adding-doubling of `steps` from the top for a viewing direction of cosine `cos_theta` and azimuth
/// (`cos_phi`, `sin_phi`): the lobes and the final stack statistics.
pub(super) fn adding<T: Real>(
    steps: &[Step<T>],
    opts: &Options,
    channels: usize,
    cos_theta: T,
    cos_phi: f64,
    sin_phi: f64,
) -> (Vec<Lobe<T>>, State<T>) {
    let c = channels;
    let (zero, one) = (T::from(0.0), T::from(1.0));
    let fgd = tables::fgd();
    let mut s = State {
        r0i: vec![zero; c],
        t0i: vec![one; c],
        ri0: vec![zero; c],
        ti0: vec![one; c],
        s_r0i: Cov::zero(),
        s_t0i: Cov::zero(),
        s_ri0: Cov::zero(),
        s_ti0: Cov::zero(),
        j0i: one,
        ji0: one,
    };
    let mut cti = cos_theta.clamp_c(1e-4, 1.0);
    let mut lobes = Vec::new();
    // Mean relative IOR of the last interface crossed (below / above), for the TIR step.
    let mut eta_above: Option<T> = None;
    for step in steps {
        match step {
            Step::Interface { eta, kappa, alpha: (ax, ay), angle, conductor } => {
                let n12 = mean(eta);
                let stt = (one - cti * cti).max_c(0.0).sqrt() / n12;
                let ctt = if stt.value() <= 1.0 { (one - stt * stt).sqrt() } else { -one };
                let transmissive = ctt.value() > 0.0 && !conductor;
                // Each axis of the interface's covariance through the roughness map h.
                let cov = |scale: T| {
                    Cov::oriented(variance_from_alpha(*ax * scale), variance_from_alpha(*ay * scale), *angle)
                };
                let s_r12 = cov(one);
                // Transmission roughness scale s: how far the transmitted mean moves per unit of facet slope,
                // |J_t(θi)|, over how far the reflection at the next interface moves it, |J_r(θt)| (and the
                // reverse going up). At the lobe mean (h = n) the exact Jacobians are these multiples of I, so
                // this is the exact-Jacobian transport at the mean and the paper's |η cos θt − cos θi| /
                // (2η cos θt); the reference code freezes the cosines to 1 (normal incidence).
                let (ci, ct) = if opts.real_cosines { (cti, ctt) } else { (one, one) };
                let scale = |cos_i: T, cos_t: T, eta: T| {
                    let t = jacobian::refraction_scale(cos_i, eta).unwrap_or(zero);
                    t.abs() / jacobian::reflection_scale(cos_t)
                };
                let (s_t12, s_t21, j12, j21) = if transmissive {
                    (cov(scale(ci, ct, n12)), cov(scale(ct, ci, one / n12)), ctt / cti * n12, cti / ctt / n12)
                } else {
                    (Cov::zero(), Cov::zero(), one, one)
                };
                // FGD at the roughness, along the viewing azimuth, of the incoming lobe convolved with the
                // interface.
                let temp_alpha = alpha_from_variance((s.s_t0i + s_r12).along(cos_phi, sin_phi));
                if let Some(up) = eta_above.filter(|_| opts.tir != Tir::Off) {
                    // The TIR step reads lamina's tables at values (no gradient: `gradient` refuses tir).
                    let table = tables::steinberg::steinberg();
                    let (cti, alpha, up) = (cti.value(), temp_alpha.value(), up.value());
                    let t = match opts.tir {
                        Tir::Transmittance => table.tabulated(cti, alpha, 1.0 / up).0,
                        _ => 1.0 - table.tir_fraction(cti, alpha, 1.0 / up),
                    };
                    for (r, ti) in s.ri0.iter_mut().zip(s.ti0.iter_mut()) {
                        *r = (*r + *ti * (1.0 - t)).clamp_c(0.0, 1.0);
                        *ti = *ti * t;
                    }
                }
                let r12: Vec<T> = (0..c)
                    .map(|k| {
                        if temp_alpha.value() == 0.0 || opts.fresnel_energy {
                            fresnel::conductor(cti, eta[k], kappa[k]) // FGD at α = 0 is the Fresnel term itself
                        } else {
                            fgd.lookup(cti, temp_alpha, eta[k], kappa[k])
                        }
                    })
                    .collect();
                let t12: Vec<T> = if !transmissive {
                    vec![zero; c]
                } else if opts.microfacet_transmission && temp_alpha.value() > 0.0 {
                    // lamina's table at values (no gradient: `gradient` refuses microfacet_transmission).
                    let table = tables::steinberg::steinberg();
                    eta.iter().map(|e| T::from(table.transmitted(cti.value(), temp_alpha.value(), e.value()))).collect()
                } else {
                    r12.iter().map(|&r| one - r).collect()
                };
                let (r21, t21) = if transmissive { (r12.clone(), t12.clone()) } else { (vec![zero; c], vec![zero; c]) };
                let st = StepStats { r12, t12, r21, t21, s_r12, s_t12, s_r21: s_r12, s_t21, j12, j21 };
                lobes.push(s.add(&st, opts.jacobian_j21));
                if !transmissive {
                    s.t0i.fill(zero);
                    s.ti0.fill(zero);
                    return (lobes, s);
                }
                cti = ctt;
                eta_above = Some(n12);
            }
            Step::Medium { thickness, sigma_a, sigma_s, g } => {
                let t: Vec<T> = (0..c)
                    .map(|k| {
                        // (1 + σs d/μ) e^{−σt d/μ} ≤ (1 + τ) e^{−τ}: 0 once τ overflows the exponential.
                        let tau = (*thickness / cti) * (sigma_a[k] + sigma_s[k]);
                        if tau.value() < 745.0 {
                            (sigma_s[k] * *thickness / cti + 1.0) * (-tau).exp()
                        } else {
                            zero
                        }
                    })
                    .collect();
                let s_t = if mean(sigma_s).value() > 0.0 { Cov::iso(hg_variance(*g)) } else { Cov::zero() };
                let st = StepStats {
                    r12: vec![zero; c],
                    t12: t.clone(),
                    r21: vec![zero; c],
                    t21: t,
                    s_r12: Cov::zero(),
                    s_t12: s_t,
                    s_r21: Cov::zero(),
                    s_t21: s_t,
                    j12: one,
                    j21: one,
                };
                s.add(&st, opts.jacobian_j21);
            }
        }
    }
    (lobes, s)
}
