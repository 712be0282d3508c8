//! `model="belcour"`: Belcour 2018, "Efficient rendering of layered materials using an atomic decomposition with
//! statistical operators" — per-lobe energy, mean (as a cosine) and variance (in the projected disc, through the
//! roughness map h) carried through the stack by adding-doubling, in the form of the published reference loop;
//! one GGX lobe per interface, all centred on the mirror direction.
//!
//! Anisotropy (Yamaguchi et al. 2019): every variance is a symmetric 2x2 covariance Σ in the projected disc,
//! expressed in the stack's local tangent frame; an interface of roughness (αx, αy) whose tangent frame is rotated by
//! `angle` contributes Σ = R(angle) diag(h(αx), h(αy)) R(angle)ᵀ, and the adding-doubling combines covariances with
//! the same (scalar) energy weights and first-order Jacobians as the scalar model. Each output lobe is eigen-
//! decomposed into an anisotropic GGX lobe: α along the eigenvectors, its tangent angle that of the first one. FGD is
//! looked up at the roughness the lobe has along the viewing azimuth. An isotropic stack keeps every Σ = σI, which
//! reproduces the scalar model (to rounding). The Jacobians stay the scalar first-order ones (J ∝ I); the
//! hemispherical reflectance R̄↑ seen by a diffuse base is computed at azimuth 0.
//!
//! Statistics are computed for the viewing direction wo (or for |wo·h| with `symmetric`, Belcour §6, which makes
//! the BRDF reciprocal). Slabs are medium steps (Beer–Lambert absorption and forward Henyey–Greenstein scattering,
//! no lobe). A diffuse base contributes ρ/π · T↓(θi) T↑(θo) / ((1 − ρ R̄↑) η²) — lamina's choice, which is exact
//! for a smooth coat (Mitsuba's `plastic`): the energies transmitted down from wi and up to wo (one adding pass
//! each), the inter-reflections with the stack's hemispherical reflectance from below R̄↑ (precomputed by
//! quadrature, 1 under total internal reflection), and the radiance compression η² of the medium above the base.

use super::{eval_rows, Options, BLOCK};
use crate::bsdf;
use crate::optics::fresnel;
use crate::optics::jacobian;
use crate::optics::microfacet::{Distribution, G2Form, Microfacet};
use crate::stack::{value_error, Layer, Result, Stack};
use crate::tables;
use glam::DVec3;
use rayon::prelude::*;
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

/// A symmetric 2x2 covariance of directions projected on the tangent plane (Yamaguchi et al. 2019 §4), in the local
/// tangent frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Cov {
    pub xx: f64,
    pub xy: f64,
    pub yy: f64,
}

impl Cov {
    pub const ZERO: Cov = Cov { xx: 0.0, xy: 0.0, yy: 0.0 };

    pub fn iso(v: f64) -> Cov {
        Cov { xx: v, xy: 0.0, yy: v }
    }

    /// R diag(vx, vy) Rᵀ with R the rotation by `angle` (Yamaguchi et al. 2019 eq. 7).
    pub fn oriented(vx: f64, vy: f64, angle: f64) -> Cov {
        if vx == vy {
            return Cov::iso(vx);
        }
        let (s, c) = angle.sin_cos();
        Cov { xx: c * c * vx + s * s * vy, xy: c * s * (vx - vy), yy: s * s * vx + c * c * vy }
    }

    /// The variance along the unit tangent direction (cos φ, sin φ).
    pub fn along(self, cos_phi: f64, sin_phi: f64) -> f64 {
        cos_phi * cos_phi * self.xx + 2.0 * cos_phi * sin_phi * self.xy + sin_phi * sin_phi * self.yy
    }

    /// Eigen-decomposition: (λ₁, λ₂, angle of λ₁'s eigenvector); (v, v, 0) for an isotropic Σ = vI.
    pub fn eigen(self) -> (f64, f64, f64) {
        let (l1, l2, cos, sin) = self.eigen_frame();
        (l1, l2, sin.atan2(cos))
    }

    /// Eigen-decomposition with the eigenvector of λ₁ ≥ λ₂ as (cos, sin) of its angle in (−π/2, π/2]: the unit
    /// vector along (Σ_xx − λ₂, Σ_xy), or along (Σ_xy, λ₁ − Σ_xx) when Σ_xx < Σ_yy (no trigonometric call, no branch:
    /// loops over it vectorize); (v, v, 1, 0) for Σ = vI.
    #[inline(always)]
    pub fn eigen_frame(self) -> (f64, f64, f64, f64) {
        let mean = 0.5 * (self.xx + self.yy);
        let half = 0.5 * (self.xx - self.yy);
        let r = (half * half + self.xy * self.xy).sqrt();
        let (x, y) = if half >= 0.0 { (half + r, self.xy) } else { (self.xy, r - half) };
        let (x, y) = if x < 0.0 { (-x, -y) } else { (x, y) };
        let len = (x * x + y * y).sqrt();
        if r > 0.0 {
            (mean + r, mean - r, x / len, y / len)
        } else {
            (mean, mean, 1.0, 0.0)
        }
    }

    /// The roughness matrix R diag(αx, αy) Rᵀ of this covariance's GGX lobe: h⁻¹ applied to its eigenvalues.
    pub fn alpha_matrix(self) -> Cov {
        let (ax, ay, angle) = self.ggx();
        Cov::oriented(ax, ay, angle)
    }

    /// The anisotropic GGX lobe (αx, αy, tangent angle) of this covariance: h⁻¹ of the eigenvalues.
    pub fn ggx(self) -> (f64, f64, f64) {
        let (l1, l2, angle) = self.eigen();
        (alpha_from_variance(l1), alpha_from_variance(l2), angle)
    }
}

impl std::ops::Add for Cov {
    type Output = Cov;
    fn add(self, o: Cov) -> Cov {
        Cov { xx: self.xx + o.xx, xy: self.xy + o.xy, yy: self.yy + o.yy }
    }
}

impl std::ops::Mul<Cov> for f64 {
    type Output = Cov;
    fn mul(self, c: Cov) -> Cov {
        Cov { xx: self * c.xx, xy: self * c.xy, yy: self * c.yy }
    }
}

impl std::ops::Mul<f64> for Cov {
    type Output = Cov;
    fn mul(self, d: f64) -> Cov {
        Cov { xx: self.xx * d, xy: self.xy * d, yy: self.yy * d }
    }
}

impl std::ops::Div<f64> for Cov {
    type Output = Cov;
    fn div(self, d: f64) -> Cov {
        Cov { xx: self.xx / d, xy: self.xy / d, yy: self.yy / d }
    }
}

/// One output lobe: energy per channel and its anisotropic GGX roughness and tangent angle.
#[derive(Clone, Debug, PartialEq)]
pub struct Lobe {
    pub energy: Vec<f64>,
    pub cov: Cov,
}

impl Lobe {
    /// (αx, αy, angle) of the lobe's GGX distribution.
    pub fn roughness(&self) -> (f64, f64, f64) {
        self.cov.ggx()
    }
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
    /// The reference code's TIR step before each interface below the first.
    pub tir: Tir,
}

/// Belcour's optional TIR step (reference code, "decoupling approximation"): before interface i > 0, a factor T of
/// the energy Ti0 that goes back up through interface i − 1 (cosine cti below it, roughness of the lobe, relative
/// IOR η < 1 going up) is moved into Ri0: Ri0 += (1 − T) Ti0, Ti0 ← T Ti0.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Tir {
    /// No TIR step.
    #[default]
    Off,
    /// T = the rough interface's mean transmittance E[1 − F] (what the reference code's table holds): the Fresnel
    /// factor already in Ti0 is applied a second time.
    Transmittance,
    /// T = 1 − the fraction of visible normals that totally reflect: only the TIR itself.
    Fraction,
}

enum Step {
    /// A rough interface: relative IOR per channel (below / above), κ per channel (conductors), roughness
    /// (αx, αy) along its tangent frame rotated by `angle`.
    Interface { eta: Vec<f64>, kappa: Vec<f64>, alpha: (f64, f64), angle: f64, conductor: bool },
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
/// Anisotropic stacks add the viewing azimuth φ as a second axis (the statistics have period π in φ): 128 cosine
/// nodes x 32 azimuths uniform in `pseudo_angle` (nearly uniform in φ), bilinear.
const TABLE_NODES: usize = 512;
const ANISO_NODES: usize = 128;
const ANISO_AZIMUTHS: usize = 32;

struct LobeTable {
    lobes: usize,
    nodes: usize,
    azimuths: usize,
    /// Values per lobe: the GGX roughness (isotropic stacks) or the roughness matrix (`Cov::alpha_matrix`, xx, xy,
    /// yy; anisotropic stacks), then the energy per channel. No h⁻¹ is evaluated per evaluation.
    width: usize,
    /// [node][azimuth][lobe][width]: each run's record is contiguous, so that interpolation reads whole records.
    record: Vec<f64>,
    /// [node][azimuth][channel]: energy transmitted down to the base (T0i) and up from it (Ti0).
    t_down: Vec<f64>,
    t_up: Vec<f64>,
}

/// Table corners of up to BLOCK rows: run index and bilinear weight of each of the four corners, per row.
struct Corners {
    index: [[i32; BLOCK]; 4],
    weight: [[f64; BLOCK]; 4],
}

pub struct Prepared {
    steps: Vec<Step>,
    anisotropic: bool,
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
    for layer in &stack.layers {
        let (alpha, angle) = match layer {
            Layer::Dielectric { alpha, angle, .. } | Layer::Conductor { alpha, angle, .. } => (*alpha, *angle),
            Layer::Diffuse { roughness, .. } if *roughness > 0.0 => {
                return value_error("model 'belcour' takes a Lambertian diffuse base (roughness 0)");
            }
            Layer::Diffuse { .. } => ((0.0, 0.0), 0.0),
        };
        match layer {
            Layer::Dielectric { ior, thickness, sigma_a, sigma_s, g, .. } => {
                let eta = ior.iter().zip(&above).map(|(n, a)| n / a).collect();
                steps.push(Step::Interface { eta, kappa: vec![0.0; stack.channels], alpha, angle, conductor: false });
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
                steps.push(Step::Interface { eta, kappa, alpha, angle, conductor: true });
            }
            Layer::Diffuse { albedo, .. } => {
                let eta = above.iter().sum::<f64>() / above.len() as f64 / stack.ext_ior;
                diffuse = Some(DiffuseBase { albedo: albedo.clone(), eta, r_up: vec![] });
            }
        }
    }
    let anisotropic = steps.iter().any(|s| matches!(s, Step::Interface { alpha, .. } if alpha.0 != alpha.1));
    let mut p = Prepared {
        steps,
        anisotropic,
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
    s_r0i: Cov,
    s_t0i: Cov,
    s_ri0: Cov,
    s_ti0: Cov,
    j0i: f64,
    ji0: f64,
}

/// The statistics of one step: energies per channel, covariances and (first-order, scalar) Jacobians.
struct StepStats {
    r12: Vec<f64>,
    t12: Vec<f64>,
    r21: Vec<f64>,
    t21: Vec<f64>,
    s_r12: Cov,
    s_t12: Cov,
    s_r21: Cov,
    s_t21: Cov,
    j12: f64,
    j21: f64,
}

impl State {
    /// Adds one step below the stack (adding-doubling on energies and covariances); returns the lobe reflected by
    /// this step.
    fn add(&mut self, st: &StepStats, j21_in_variance: bool) -> Lobe {
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
            let (_, state) = self.adding(mu_o, 1.0, 0.0);
            for (rk, ri0) in r.iter_mut().zip(&state.ri0) {
                *rk += w * half * 2.0 * mu_o * ri0 / (eta * eta);
            }
        }
        r
    }

    fn tabulate(&self) -> LobeTable {
        let c = self.channels;
        let (nodes, azimuths) = if self.anisotropic { (ANISO_NODES, ANISO_AZIMUTHS) } else { (TABLE_NODES, 1) };
        let runs: Vec<_> = (0..nodes * azimuths)
            .into_par_iter()
            .map(|k| {
                let mu = ((k / azimuths) as f64 / (nodes - 1) as f64).powi(2);
                let p = std::f64::consts::PI * (k % azimuths) as f64 / azimuths as f64;
                let (cos, sin) = direction_of_pseudo_angle(p);
                self.adding(mu, cos, sin)
            })
            .collect();
        let lobes = runs.iter().map(|(l, _)| l.len()).max().unwrap_or(0);
        let width = if self.anisotropic { 3 } else { 1 } + c;
        let mut t = LobeTable {
            lobes,
            nodes,
            azimuths,
            width,
            record: vec![0.0; runs.len() * lobes * width],
            t_down: Vec::with_capacity(runs.len() * c),
            t_up: Vec::with_capacity(runs.len() * c),
        };
        for (k, (l, state)) in runs.iter().enumerate() {
            for (j, lobe) in l.iter().enumerate() {
                let v = &mut t.record[(k * lobes + j) * width..][..width];
                let m = lobe.cov.alpha_matrix();
                let alpha: &[f64] = if self.anisotropic { &[m.xx, m.xy, m.yy] } else { &[lobe.roughness().0] };
                v[..alpha.len()].copy_from_slice(alpha);
                v[alpha.len()..].copy_from_slice(&lobe.energy);
            }
            t.t_down.extend_from_slice(&state.t0i);
            t.t_up.extend_from_slice(&state.ti0);
        }
        t
    }

    /// The lobes for a viewing direction `wo` (unit, above the surface).
    pub fn lobes(&self, wo: DVec3) -> Vec<Lobe> {
        let (cos_phi, sin_phi) = azimuth(wo);
        self.adding(wo.z, cos_phi, sin_phi).0
    }

    /// Runs the adding-doubling from the top for a viewing direction of cosine `cos_theta` and azimuth
    /// (`cos_phi`, `sin_phi`): the lobes and the final stack statistics.
    fn adding(&self, cos_theta: f64, cos_phi: f64, sin_phi: f64) -> (Vec<Lobe>, State) {
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
                    let (ci, ct) = if self.variant.real_cosines { (cti, ctt) } else { (1.0, 1.0) };
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
                    if let Some(up) = eta_above.filter(|_| self.variant.tir != Tir::Off) {
                        let table = tables::steinberg::steinberg();
                        let t = match self.variant.tir {
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
                    eta_above = Some(n12);
                }
                Step::Medium { thickness, sigma_a, sigma_s, g } => {
                    let t: Vec<f64> = (0..c)
                        .map(|k| {
                            (1.0 + sigma_s[k] * thickness / cti)
                                * (-(thickness / cti) * (sigma_a[k] + sigma_s[k])).exp()
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
        if self.table.is_some() {
            return self.eval_block([&[wi.x], &[wi.y], &[wi.z]], [&[wo.x], &[wo.y], &[wo.z]], out);
        }
        let cos_theta = if self.symmetric { wo.dot((wi + wo).normalize()).abs() } else { wo.z };
        let (cos_phi, sin_phi) = azimuth(wo);
        let (lobes, view) = self.adding(cos_theta, cos_phi, sin_phi);
        for lobe in &lobes {
            self.add_lobe(lobe.roughness(), &lobe.energy, wi, wo, out);
        }
        if self.diffuse.is_some() {
            // T↓ at θi and T↑ at θo (not at |wo·h|): symmetric under exchange, since T0i = Ti0 in this model.
            let (ci, si) = azimuth(wi);
            let light = self.adding(wi.z, ci, si).1;
            let view = if self.symmetric { self.adding(wo.z, cos_phi, sin_phi).1 } else { view };
            self.add_diffuse(|ch| light.t0i[ch], |ch| view.ti0[ch], out);
        }
    }

    /// Adds one GGX lobe of roughness (αx, αy, tangent angle) with per-channel `energy`; a lobe of roughness 0 is
    /// a Dirac delta, not part of f.
    fn add_lobe(&self, (ax, ay, angle): (f64, f64, f64), energy: &[f64], wi: DVec3, wo: DVec3, out: &mut [f64]) {
        let mf = Microfacet::new(Distribution::Ggx, ax, ay, angle);
        let shape = bsdf::reflection_geometry(&mf, self.g2, wi, wo).map_or(0.0, |(geo, _)| geo);
        for (o, e) in out.iter_mut().zip(energy) {
            *o += e * shape;
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

    /// Bilinear interpolation corners of directions (columns x, y, and the cosine θ to look up) in the table: linear
    /// in √cos θ and in the azimuth's `pseudo_angle` (period π); isotropic tables use the first two corners only.
    #[inline(always)]
    fn corners(t: &LobeTable, cos_theta: &[f64], x: &[f64], y: &[f64]) -> Corners {
        let mut c = Corners { index: [[0; BLOCK]; 4], weight: [[0.0; BLOCK]; 4] };
        let (n, azimuths) = (cos_theta.len(), t.azimuths as i32);
        // Each pass a loop of its own, so that it vectorizes (positions as i32: AVX2 converts f64 to i32 only).
        let mut v = [0.0; BLOCK];
        if azimuths > 1 {
            for r in 0..n {
                v[r] = pseudo_angle(x[r], y[r]) * (FRAC_1_PI * azimuths as f64);
            }
        }
        for r in 0..n {
            let (k, fk) = tables::node(cos_theta[r].clamp(0.0, 1.0).sqrt(), t.nodes);
            let k = k as i32;
            let a = (v[r] as i32).min(azimuths - 1);
            let fa = v[r] - a as f64;
            let b = if a + 1 == azimuths { 0 } else { a + 1 };
            (c.index[0][r], c.weight[0][r]) = (k * azimuths + a, (1.0 - fk) * (1.0 - fa));
            (c.index[1][r], c.weight[1][r]) = ((k + 1) * azimuths + a, fk * (1.0 - fa));
            (c.index[2][r], c.weight[2][r]) = (k * azimuths + b, (1.0 - fk) * fa);
            (c.index[3][r], c.weight[3][r]) = ((k + 1) * azimuths + b, fk * fa);
        }
        c
    }
}

impl Prepared {
    /// `eval` for a block of columns (see models::Evaluator::eval_block). A tabulated stack runs in passes over the
    /// block: table corners per row; the records of all lobes interpolated per row (contiguous reads); then per lobe
    /// its roughness (eigen-decomposed for anisotropic stacks), its GGX shape (a branch-free loop that vectorizes)
    /// and its energies per channel; then the diffuse base. Without a table, row by row.
    #[inline(always)]
    pub fn eval_block(&self, wi: [&[f64]; 3], wo: [&[f64]; 3], out: &mut [f64]) {
        let n = wi[0].len();
        let c = self.channels;
        let Some(t) = &self.table else {
            return eval_rows(wi, wo, out, |wi, wo, o| self.eval(wi, wo, o));
        };
        let ([ix, iy, iz], [ox, oy, oz]) = (wi.map(|col| &col[..n]), wo.map(|col| &col[..n]));
        let mut above = [false; BLOCK];
        let mut cos_theta = [0.0; BLOCK];
        for r in 0..n {
            above[r] = iz[r] > 0.0 && oz[r] > 0.0;
            cos_theta[r] = if self.symmetric {
                let (wi, wo) = (DVec3::new(ix[r], iy[r], iz[r]), DVec3::new(ox[r], oy[r], oz[r]));
                wo.dot((wi + wo).normalize()).abs()
            } else {
                oz[r]
            };
        }
        let (above, anisotropic) = (&above[..n], t.azimuths > 1);
        let corners = Self::corners(t, &cos_theta[..n], ox, oy);
        let ([mut ax, mut ay, mut cos, mut sin], mut shape) = ([[0.0; BLOCK]; 4], [0.0; BLOCK]);
        if anisotropic {
            // Per row, the records of all lobes interpolated at once (contiguous reads of the four corners).
            let w = t.lobes * t.width;
            let mut values = vec![0.0; n * w];
            for (r, v) in values.chunks_exact_mut(w).enumerate() {
                let [r0, r1, r2, r3] = std::array::from_fn(|q| &t.record[corners.index[q][r] as usize * w..][..w]);
                let [w0, w1, w2, w3] = std::array::from_fn(|q| corners.weight[q][r]);
                for i in 0..w {
                    v[i] = w0 * r0[i] + w1 * r1[i] + w2 * r2[i] + w3 * r3[i];
                }
            }
            for j in 0..t.lobes {
                let lobe = |r: usize| &values[r * w + j * t.width..][..t.width];
                // The roughness matrices as columns (xx, xy, yy in ax, ay, cos), then eigen-decomposed in place.
                for r in 0..n {
                    (ax[r], ay[r], cos[r]) = (lobe(r)[0], lobe(r)[1], lobe(r)[2]);
                }
                for r in 0..n {
                    (ax[r], ay[r], cos[r], sin[r]) = Cov { xx: ax[r], xy: ay[r], yy: cos[r] }.eigen_frame();
                }
                let frame = Some([&cos[..n], &sin[..n]]);
                ggx_shapes(self.g2, [&ax[..n], &ay[..n]], frame, above, wi, wo, &mut shape);
                for (r, o) in out.chunks_exact_mut(c).enumerate() {
                    for (o, e) in o.iter_mut().zip(&lobe(r)[3..]) {
                        *o += e * shape[r];
                    }
                }
            }
        } else {
            // Two corners along cos θ: each value gathered from its two records.
            let (k, weight) = ([&corners.index[0][..n], &corners.index[1][..n]], &corners.weight);
            for j in 0..t.lobes {
                let at = |q: usize, r: usize| (k[q][r] as usize * t.lobes + j) * t.width;
                for r in 0..n {
                    ax[r] = weight[0][r] * t.record[at(0, r)] + weight[1][r] * t.record[at(1, r)];
                }
                ggx_shapes(self.g2, [&ax[..n], &ax[..n]], None, above, wi, wo, &mut shape);
                for (r, o) in out.chunks_exact_mut(c).enumerate() {
                    let (a, b) = (at(0, r) + 1, at(1, r) + 1);
                    for (ch, o) in o.iter_mut().enumerate() {
                        *o += (weight[0][r] * t.record[a + ch] + weight[1][r] * t.record[b + ch]) * shape[r];
                    }
                }
            }
        }
        if self.diffuse.is_some() {
            // T↓ at θi and T↑ at θo: the lobes' corners serve for wo unless they were found at |wo·h|.
            let down_at = Self::corners(t, iz, ix, iy);
            let up_symmetric = self.symmetric.then(|| Self::corners(t, oz, ox, oy));
            let up_at = up_symmetric.as_ref().unwrap_or(&corners);
            for (r, o) in out.chunks_exact_mut(c).enumerate().filter(|&(r, _)| above[r]) {
                let at = |corners: &Corners, table: &[f64], ch: usize| {
                    (0..4).map(|q| corners.weight[q][r] * table[corners.index[q][r] as usize * c + ch]).sum::<f64>()
                };
                self.add_diffuse(|ch| at(&down_at, &t.t_down, ch), |ch| at(up_at, &t.t_up, ch), o);
            }
        }
    }
}

/// D G2 / (4 cos θi cos θo) of GGX lobes of roughness `alpha` = [αx, αy] per row, along the tangent frame `frame`
/// = [cos, sin] per row (None: the local frame), for a block of columns; 0 where a row is not above the surface or
/// its lobe is a Dirac delta (α = 0).
#[inline(always)]
fn ggx_shapes(
    form: G2Form,
    alpha: [&[f64]; 2],
    frame: Option<[&[f64]; 2]>,
    above: &[bool],
    wi: [&[f64]; 3],
    wo: [&[f64]; 3],
    shape: &mut [f64],
) {
    // One loop per G2 form, the form a known constant in each, so that it vectorizes.
    #[inline(always)]
    fn shapes(
        form: G2Form,
        alpha: [&[f64]; 2],
        frame: Option<[&[f64]; 2]>,
        above: &[bool],
        wi: [&[f64]; 3],
        wo: [&[f64]; 3],
        shape: &mut [f64],
    ) {
        let n = above.len();
        let ([ax, ay], shape) = (alpha.map(|col| &col[..n]), &mut shape[..n]);
        let ([ix, iy, iz], [ox, oy, oz]) = (wi.map(|col| &col[..n]), wo.map(|col| &col[..n]));
        let frame = frame.map(|f| f.map(|col| &col[..n]));
        let ggx = Microfacet::new(Distribution::Ggx, 1.0, 1.0, 0.0);
        for r in 0..n {
            let (wi, wo) = (DVec3::new(ix[r], iy[r], iz[r]), DVec3::new(ox[r], oy[r], oz[r]));
            let mf = match frame {
                Some([cos, sin]) => ggx.with_frame(ax[r], ay[r], cos[r], sin[r]),
                None => ggx.with_alpha(ax[r], ay[r]),
            };
            let f = bsdf::reflection_geometry(&mf, form, wi, wo).map_or(0.0, |(g, _)| g);
            shape[r] = if above[r] { f } else { 0.0 };
        }
    }
    match form {
        G2Form::HeightCorrelated => shapes(G2Form::HeightCorrelated, alpha, frame, above, wi, wo, shape),
        G2Form::Separable => shapes(G2Form::Separable, alpha, frame, above, wi, wo, shape),
        G2Form::VCavity => shapes(G2Form::VCavity, alpha, frame, above, wi, wo, shape),
    }
}

/// A monotonic stand-in for the azimuth φ modulo π, without trigonometric calls: (x, y) folded into the upper
/// half-plane, then the octant's atan(t) by t (π/4 + 0.273 (1 − t)) (Rajan et al. 2006, within 0.004 rad of φ), so
/// that table nodes uniform in it are nearly uniform in φ. In [0, π): φ = π folds to 0, and so does the normal.
#[inline(always)]
fn pseudo_angle(x: f64, y: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};
    let (x, y) = if y < 0.0 { (-x, -y) } else { (x, y) };
    let t = x.abs().min(y) / x.abs().max(y);
    let a = t * (FRAC_PI_4 + 0.273 * (1.0 - t));
    let a = if y > x.abs() { FRAC_PI_2 - a } else { a };
    let p = if x < 0.0 { PI - a } else { a };
    if p.is_finite() && p < PI {
        p
    } else {
        0.0
    }
}

/// (cos φ, sin φ) of the azimuth whose `pseudo_angle` is p ∈ [0, π) (by bisection: it is within 0.004 of φ).
fn direction_of_pseudo_angle(p: f64) -> (f64, f64) {
    let (mut lo, mut hi) = ((p - 0.01).max(0.0), (p + 0.01).min(std::f64::consts::PI));
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if pseudo_angle(mid.cos(), mid.sin()) < p {
            lo = mid
        } else {
            hi = mid
        }
    }
    let phi = 0.5 * (lo + hi);
    (phi.cos(), phi.sin())
}

/// (cos φ, sin φ) of a direction's azimuth; (1, 0) along the normal.
fn azimuth(w: DVec3) -> (f64, f64) {
    let r = w.x.hypot(w.y);
    if r == 0.0 {
        (1.0, 0.0)
    } else {
        (w.x / r, w.y / r)
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
    fn covariance_eigen_decomposition_round_trips() {
        let c = Cov::oriented(0.3, 0.05, 0.7);
        let (l1, l2, angle) = c.eigen();
        assert!((l1 - 0.3).abs() < 1e-12 && (l2 - 0.05).abs() < 1e-12);
        let back = Cov::oriented(l1, l2, angle);
        assert!((back.xx - c.xx).abs() < 1e-12 && (back.xy - c.xy).abs() < 1e-12 && (back.yy - c.yy).abs() < 1e-12);
        assert_eq!(Cov::iso(0.2).eigen(), (0.2, 0.2, 0.0));
        assert!((c.along(0.7f64.cos(), 0.7f64.sin()) - 0.3).abs() < 1e-12);
    }

    #[test]
    fn pseudo_angle_is_monotonic_in_the_azimuth_and_round_trips() {
        let mut last = -1.0;
        for k in 0..3600 {
            let phi = std::f64::consts::PI * k as f64 / 3600.0;
            let p = pseudo_angle(phi.cos(), phi.sin());
            assert!(p > last && (p - phi).abs() < 4e-3, "φ = {phi}: {p} after {last}");
            assert_eq!(pseudo_angle(-phi.cos(), -phi.sin()), p, "period π");
            let (c, s) = direction_of_pseudo_angle(p);
            assert!((c - phi.cos()).abs() < 1e-12 && (s - phi.sin()).abs() < 1e-12);
            last = p;
        }
        assert_eq!(pseudo_angle(0.0, 0.0), 0.0);
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
        let lobes = p.lobes(DVec3::new((1.0f64 - 0.49).sqrt(), 0.0, 0.7));
        assert_eq!(lobes.len(), 1);
        let (ax, ay, angle) = lobes[0].roughness();
        assert!((ax - 0.3).abs() < 1e-9 && ax == ay && angle == 0.0);
        assert!((lobes[0].energy[0] - tables::fgd().lookup(0.7, 0.3, 0.2, 3.0)).abs() < 1e-12);
    }
}
