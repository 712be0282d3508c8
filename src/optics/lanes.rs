//! The optics primitives in float32 lanes (engine/lanes.rs), for the engine's kernels: each mirrors its float64
//! function in this module's siblings, rewritten with the algebra the peers use (one division per Fresnel channel,
//! D from the unnormalised half vector, G1·G1/(4 cos cos) as one reciprocal, a rotation only for a rotated frame).
//! The tests hold each to its float64 twin.

use super::distribution::{Distribution, G2Form, Microfacet};
use super::fresnel::FresnelForm;
use crate::engine::{Floats, Mask, V3};

/// A conductor's relative complex IOR η + iκ, as the lanes' Fresnel terms take it.
#[derive(Clone, Copy, Debug)]
pub struct ConductorIor {
    form: FresnelForm,
    /// Exact: η² − κ² − 1, 4η²κ² and √(2η²κ²); the sign of t0 = η² − κ² − sin²θ over every angle.
    e2k2m1: f32,
    c4: f32,
    n: f32,
    sign: Sign,
    /// Schlick: F0. Lazányi: F = min(1, a + b (1 − cos)^5) with a = F0 and b = 4η / ((η + 1)² + κ²).
    f0: f32,
    b: f32,
}

/// The sign of t0 = η² − κ² − sin²θ for every θ: ≥ 0 (η² − κ² ≥ 1: a dielectric-like IOR), ≤ 0 (η ≤ κ: every
/// common metal), or either.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Sign {
    Positive,
    Negative,
    Mixed,
}

impl ConductorIor {
    pub fn new(form: FresnelForm, eta: f64, k: f64) -> ConductorIor {
        let e2k2 = eta * eta - k * k;
        ConductorIor {
            form,
            e2k2m1: (e2k2 - 1.0) as f32,
            c4: (4.0 * eta * eta * k * k) as f32,
            n: (2.0 * eta * eta * k * k).sqrt() as f32,
            sign: if e2k2 >= 1.0 {
                Sign::Positive
            } else if e2k2 <= 0.0 {
                Sign::Negative
            } else {
                Sign::Mixed
            },
            f0: super::fresnel::f0(eta, k) as f32,
            b: (4.0 * eta / ((eta + 1.0).powi(2) + k * k)) as f32,
        }
    }
}

/// Conductor Fresnel reflectance at cos θ in the chosen form (fresnel::conductor, schlick, lazanyi). The exact form
/// as F = ½ r_s (1 + r_p / r_s) = (A − B) P / ((A + B)(P + Q)) with A = a² + b² + cos²θ, B = 2a cos θ,
/// P = (a² + b²) cos²θ + sin⁴θ and Q = B sin²θ: one division. Where t0 = η² − κ² − sin²θ ≤ 0 (every common metal),
/// a = √(2η²κ²) / √(a² + b² − t0) without cancellation, and its denominator multiplies A ± B and P, Q instead of
/// dividing: still one division. Near index matching (below) and where t0 takes both signs, two more.
#[inline(always)]
pub fn conductor(cos: Floats, ior: &ConductorIor) -> Floats {
    let (zero, one) = (Floats::splat(0.0), Floats::splat(1.0));
    let cos = cos.max(zero).min(one);
    match ior.form {
        FresnelForm::Exact => {
            let cos2 = cos * cos;
            let sin2 = 1.0 - cos2;
            // t0 = η² − κ² − sin²θ as (η² − κ² − 1) + cos²θ: no cancellation for η² − κ² near 1 (η = 1, κ = 0, where F
            // vanishes, would otherwise keep float32's rounding of 1 − cos²θ).
            let t0 = cos.mul_add(cos, Floats::splat(ior.e2k2m1));
            let c4 = Floats::splat(ior.c4);
            let a2b2 = t0.mul_add(t0, c4).sqrt();
            let (sum, p) = (a2b2 + cos2, cos2.mul_add(a2b2, sin2 * sin2));
            if ior.sign == Sign::Negative {
                // a = n / d: A ± B and P, Q times d.
                let d = (a2b2 - t0).sqrt();
                let (sum_d, two_n_cos) = (sum * d, 2.0 * ior.n * cos);
                let p_d = p * d;
                return ((sum_d - two_n_cos) * p_d / ((sum_d + two_n_cos) * two_n_cos.mul_add(sin2, p_d))).max(zero);
            }
            let a2 = if ior.sign == Sign::Mixed {
                Floats::select(t0.ge(zero), 0.5 * (a2b2 + t0), 0.5 * c4 / (a2b2 - t0))
            } else {
                0.5 * (a2b2 + t0)
            };
            let a = a2.sqrt();
            let two_a_cos = 2.0 * a * cos;
            // r_s's numerator (a − cos θ)² + b². Without total internal reflection (η² − κ² ≥ 1) a ≈ cos θ near
            // index matching, where a² + b² + cos² θ − 2a cos θ cancels: there a − cos θ = (a² − cos² θ)/(a + cos θ)
            // = (η² − κ² − 1 + b²)/(a + cos θ), a sum of non-negative terms, with b² = η²κ²/a².
            let num = if ior.sign == Sign::Mixed {
                sum - two_a_cos
            } else {
                let b2 = (0.25 * c4) / a2.max(Floats::splat(f32::MIN_POSITIVE));
                let d = (b2 + ior.e2k2m1) / (a + cos);
                d.mul_add(d, b2)
            };
            let q = two_a_cos * sin2;
            (num * p / ((sum + two_a_cos) * (p + q))).max(zero)
        }
        FresnelForm::Schlick => {
            let x = 1.0 - cos;
            let x2 = x * x;
            (x2 * x2 * x).mul_add(Floats::splat(1.0 - ior.f0), Floats::splat(ior.f0))
        }
        FresnelForm::Lazanyi => {
            let x = 1.0 - cos;
            let x2 = x * x;
            (x2 * x2 * x).mul_add(Floats::splat(ior.b), Floats::splat(ior.f0)).min(one)
        }
    }
}

/// Dielectric Fresnel reflectance at cos θ ≥ 0 for relative IOR eta (fresnel::dielectric from the incident side),
/// ½ (r_s² + r_p²), 1 under total internal reflection. The amplitudes without the cancellation of cos θ − η cos θt
/// (η² cos² θt = cos² θ + η² − 1): r_s = −(η² − 1) / (cos θ + η cos θt)² and r_p = (η² − 1)((η² + 1) cos² θ − 1) /
/// (η² (η cos θ + cos θt)²), so that an IOR near 1 keeps its few digits of η² − 1 (computed in float64: float32's
/// rounding of η = 1.0001 is 6e-4 of η − 1).
#[inline(always)]
pub fn dielectric(cos: Floats, eta: f64) -> Floats {
    let (zero, one) = (Floats::splat(0.0), Floats::splat(1.0));
    let cos = cos.max(zero).min(one);
    let (m, e2) = ((eta * eta - 1.0) as f32, (eta * eta) as f32);
    let cos2 = cos * cos;
    // cos² θt = (cos² θ + η² − 1) / η², the square inside a fused multiply-add.
    let cos2_t = cos.mul_add(cos, Floats::splat(m)) * ((1.0 / (eta * eta)) as f32);
    let cos_t = cos2_t.max(zero).sqrt();
    let eta = eta as f32;
    let b = cos_t.mul_add(Floats::splat(eta), cos);
    let d = cos.mul_add(Floats::splat(eta), cos_t);
    let tiny = Floats::splat(f32::MIN_POSITIVE);
    let r_s = m / (b * b).max(tiny);
    let r_p = cos2.mul_add(Floats::splat(e2 + 1.0), -one) * m / (e2 * d * d).max(tiny);
    Floats::select(cos2_t.le(zero), one, 0.5 * r_s.mul_add(r_s, r_p * r_p))
}

/// A GGX microfacet interface as the lanes' reflection takes it: one roughness for every lane (`new`) or a roughness
/// per lane (`lanes`: Belcour's interpolated lobes).
#[derive(Clone, Copy, Debug)]
pub struct Ggx {
    /// αx², αy², 1 / αx², 1 / αy², 1 / (π αx αy).
    ax2: Floats,
    ay2: Floats,
    inv_ax2: Floats,
    inv_ay2: Floats,
    norm: Floats,
    /// (cos, sin) of the tangent frame's rotation, None for the unrotated frame.
    frame: Option<(Floats, Floats)>,
    height_correlated: bool,
}

impl Ggx {
    /// The lanes' form of `mf` with masking-shadowing `g2`: None for what it does not cover (Beckmann, the V-cavity,
    /// a smooth interface).
    pub fn new(mf: &Microfacet, g2: G2Form) -> Option<Ggx> {
        if mf.dist != Distribution::Ggx || g2 == G2Form::VCavity || mf.is_smooth() {
            return None;
        }
        Some(Ggx::record(mf, g2))
    }

    /// The roughness record of a rough `mf` of either distribution (`Visible::Beckmann` keeps Beckmann's in it).
    fn record(mf: &Microfacet, g2: G2Form) -> Ggx {
        let (ax, ay) = (mf.alpha_x, mf.alpha_y);
        let (c, s) = mf.frame();
        let splat = |x: f64| Floats::splat(x as f32);
        Ggx {
            ax2: splat(ax * ax),
            ay2: splat(ay * ay),
            inv_ax2: splat(1.0 / (ax * ax)),
            inv_ay2: splat(1.0 / (ay * ay)),
            norm: splat(std::f64::consts::FRAC_1_PI / (ax * ay)),
            frame: (s != 0.0).then_some((splat(c), splat(s))),
            height_correlated: g2 == G2Form::HeightCorrelated,
        }
    }

    /// GGX of roughness (αx, αy) > 0 per lane, along the tangent frame rotated by (cos, sin) per lane (None: the
    /// local frame), with a Smith G2 (`height_correlated` or separable): one division for the four reciprocals.
    #[inline(always)]
    pub fn lanes(ax: Floats, ay: Floats, frame: Option<(Floats, Floats)>, height_correlated: bool) -> Ggx {
        let r = 1.0 / (ax * ay);
        let (inv_ax, inv_ay) = (ay * r, ax * r);
        Ggx {
            ax2: ax * ax,
            ay2: ay * ay,
            inv_ax2: inv_ax * inv_ax,
            inv_ay2: inv_ay * inv_ay,
            norm: r * std::f32::consts::FRAC_1_PI,
            frame,
            height_correlated,
        }
    }
}

impl Ggx {
    /// a's roughness and frame where m is set, else b's, per lane (a mixture's chosen lobe); both of one G2.
    #[inline(always)]
    pub fn select(m: Mask, a: &Ggx, b: &Ggx) -> Ggx {
        let s = |x: Floats, y: Floats| Floats::select(m, x, y);
        let unrotated = (Floats::splat(1.0), Floats::splat(0.0));
        let frame = match (a.frame, b.frame) {
            (None, None) => None,
            (fa, fb) => {
                let ((ca, sa), (cb, sb)) = (fa.unwrap_or(unrotated), fb.unwrap_or(unrotated));
                Some((s(ca, cb), s(sa, sb)))
            }
        };
        Ggx {
            ax2: s(a.ax2, b.ax2),
            ay2: s(a.ay2, b.ay2),
            inv_ax2: s(a.inv_ax2, b.inv_ax2),
            inv_ay2: s(a.inv_ay2, b.inv_ay2),
            norm: s(a.norm, b.norm),
            frame,
            height_correlated: a.height_correlated,
        }
    }
}

/// σ = √(cos² θ + αx² x² + αy² y²) of a direction in the interface's frame: cos θ (1 + 2Λ) for GGX (Heitz 2014
/// eq. 72). (Functions rather than closures in the lanes' hot paths: a closure may be compiled outside the row
/// loop's instruction set.)
#[inline(always)]
fn smith_sigma(g: &Ggx, w: V3) -> Floats {
    (w.x * w.x).mul_add(g.ax2, (w.y * w.y).mul_add(g.ay2, w.z * w.z)).sqrt()
}

/// sin θ of a unit direction from its tangent components, √(x² + y²) (optics::sin_theta): no cancellation near the
/// normal, as 1 − cos²θ would have in float32.
#[inline(always)]
pub fn sin_theta(w: V3) -> Floats {
    w.x.mul_add(w.x, w.y * w.y).sqrt()
}

/// Microfacet reflection without the Fresnel factor, D(h) G2 / (4 cos θi cos θo), and the cosine wi·h its Fresnel
/// factor takes (bsdf::reflection_geometry), for GGX with a Smith G2; 0 unless both directions are above the
/// surface. D from h = wi + wo unnormalised: D = |h|⁴ / (π αx αy s²), s = hx²/αx² + hy²/αy² + hz² (Walter et al.
/// 2007 eq. 33), wi·h / |h| = |h| / 2; G2 / (4 cos θi cos θo) = 1 / ((cos θi + σi)(cos θo + σo)) separable and 1 / (2 (cos θo σi +
/// cos θi σo)) height-correlated, σ = √(cos² θ + αx² x² + αy² y²) (Heitz 2014 eqs. 72, 98, 99).
#[inline(always)]
pub fn ggx_reflection(g: &Ggx, wi: V3, wo: V3) -> (Floats, Floats) {
    let zero = Floats::splat(0.0);
    let above = wi.z.gt(zero) & wo.z.gt(zero);
    // h before the rotation: rotating wi and wo first would round them, which the sum of a nearly opposite pair
    // magnifies.
    let h = wi.plus(wo);
    let (wi, wo, h) = match g.frame {
        Some((c, s)) => (wi.rotate(c, s), wo.rotate(c, s), h.rotate(c, s)),
        None => (wi, wo, h),
    };
    let h2 = h.dot(h);
    let cos_h = 0.5 * h2.sqrt();
    let s = (h.x * h.x).mul_add(g.inv_ax2, (h.y * h.y).mul_add(g.inv_ay2, h.z * h.z));
    let (si, so) = (smith_sigma(g, wi), smith_sigma(g, wo));
    let masking = if g.height_correlated { 2.0 * wo.z.mul_add(si, wi.z * so) } else { (wi.z + si) * (wo.z + so) };
    let geo = h2 * h2 * g.norm / (s * s * masking);
    (Floats::and(above, geo), cos_h)
}

/// A reflected direction wi sampled for wo (unit, above the surface) through GGX's visible normals from two uniform
/// numbers (Microfacet::sample_visible: Heitz 2018, listing 1), and its pdf per unit solid angle, D_wo(m) / (4 wo·m)
/// = D(m) / (2 (cos θo + σo)) (Walter et al. 2007 eq. 14; D_wo = G1 (wo·m) D / cos θo, Heitz 2018 eq. 3, with
/// G1 = 2 cos θo / (cos θo + σo)).
#[inline(always)]
pub fn ggx_sample_reflection(g: &Ggx, wo: V3, u1: Floats, u2: Floats) -> (V3, Floats) {
    let (zero, one) = (Floats::splat(0.0), Floats::splat(1.0));
    let (v, vh, ax, ay) = stretched(g, wo);
    // The orthonormal basis (t1, t2, vh); t1 = x̂ where vh is the normal.
    let len2 = vh.x.mul_add(vh.x, vh.y * vh.y);
    let has = len2.gt(zero);
    let inv = 1.0 / len2.sqrt();
    let t1 = V3 { x: Floats::select(has, -vh.y * inv, one), y: Floats::and(has, vh.x * inv), z: zero };
    let t2 = V3 { x: -(vh.z * t1.y), y: vh.z * t1.x, z: vh.x.mul_add(t1.y, -(vh.y * t1.x)) };
    let r = u1.sqrt();
    let (sin, cos) = u2.sincos_2pi();
    let p1 = r * cos;
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * (1.0 - p1 * p1).max(zero).sqrt() + s * r * sin;
    let n = (1.0 - p1 * p1 - p2 * p2).max(zero).sqrt();
    let nh = V3 { x: p1 * t1.x + p2 * t2.x + n * vh.x, y: p1 * t1.y + p2 * t2.y + n * vh.y, z: p2 * t2.z + n * vh.z };
    let m = V3 { x: ax * nh.x, y: ay * nh.y, z: nh.z.max(zero) };
    let m = m.scale(1.0 / m.dot(m).sqrt());
    // D(m) = 1 / (π αx αy (mx²/αx² + my²/αy² + mz²)²).
    let q = (m.x * m.x).mul_add(g.inv_ax2, (m.y * m.y).mul_add(g.inv_ay2, m.z * m.z));
    let pdf = g.norm / (q * q * 2.0 * (v.z + smith_sigma(g, v)));
    (reflected(g, v, m), pdf)
}

/// wo in the interface's frame (v), and stretched to the standard configuration of unit roughness, (αx vx, αy vy, vz)
/// normalised, with αx and αy: where both distributions' visible-normal samplers start (Heitz 2018, Heitz & d'Eon
/// 2014).
#[inline(always)]
fn stretched(g: &Ggx, wo: V3) -> (V3, V3, Floats, Floats) {
    let v = match g.frame {
        Some((c, s)) => wo.rotate(c, s),
        None => wo,
    };
    let (ax, ay) = (g.ax2.sqrt(), g.ay2.sqrt());
    let vh = V3 { x: ax * v.x, y: ay * v.y, z: v.z };
    (v, vh.scale(1.0 / vh.dot(vh).sqrt()), ax, ay)
}

/// v (in the interface's frame) reflected about the unit normal m, 2 (v·m) m − v, and rotated back out of the frame.
#[inline(always)]
fn reflected(g: &Ggx, v: V3, m: V3) -> V3 {
    let wi = (m.scale(2.0 * v.dot(m))).plus(v.scale(Floats::splat(-1.0)));
    match g.frame {
        Some((c, s)) => wi.rotate(c, -s),
        None => wi,
    }
}

/// The pdf per unit solid angle of wi under GGX's visible-normal sampling for wo, D_wo(h) / (4 wo·h) =
/// D(h) / (2 (cos θo + σo)) (mixture::lobe_pdf; Walter et al. 2007 eq. 14, Heitz 2018 eq. 3), D from h = wi + wo
/// unnormalised as in `ggx_reflection`; for wo above the surface, and wi above it too (the mixture's pdf is 0
/// elsewhere).
#[inline(always)]
pub fn ggx_pdf_reflection(g: &Ggx, wi: V3, wo: V3) -> Floats {
    let h = wi.plus(wo);
    let (wo, h) = match g.frame {
        Some((c, s)) => (wo.rotate(c, s), h.rotate(c, s)),
        None => (wo, h),
    };
    let h2 = h.dot(h);
    let s = (h.x * h.x).mul_add(g.inv_ax2, (h.y * h.y).mul_add(g.inv_ay2, h.z * h.z));
    h2 * h2 * g.norm / (s * s * 2.0 * (wo.z + smith_sigma(g, wo)))
}

/// A rough interface's visible normals as a lane mixture proposes them (mixture::lobe_pdf's `Proposal::Reflection`):
/// GGX's or Beckmann's, the roughnesses and frame in `Ggx`'s record either way (αx², αy², their reciprocals,
/// 1 / (π αx αy), the rotation). One mixture's lobes share one distribution, as a model's interfaces do.
#[derive(Clone, Copy, Debug)]
pub enum Visible {
    Ggx(Ggx),
    Beckmann(Ggx),
}

impl Visible {
    /// The lobe of a rough `mf` (None for a smooth interface, which proposes none).
    pub fn new(mf: &Microfacet) -> Option<Visible> {
        let record = (!mf.is_smooth()).then(|| Ggx::record(mf, G2Form::Separable))?;
        Some(match mf.dist {
            Distribution::Ggx => Visible::Ggx(record),
            Distribution::Beckmann => Visible::Beckmann(record),
        })
    }

    /// a's lobe where m is set, else b's, per lane (`Ggx::select`).
    #[inline(always)]
    pub fn select(m: Mask, a: &Visible, b: &Visible) -> Visible {
        match (a, b) {
            (Visible::Ggx(a), Visible::Ggx(b)) => Visible::Ggx(Ggx::select(m, a, b)),
            (Visible::Beckmann(a), Visible::Beckmann(b)) => Visible::Beckmann(Ggx::select(m, a, b)),
            _ => unreachable!("one mixture's lobes share one distribution"),
        }
    }

    /// A reflected direction wi for wo through the lobe's visible normals, and its pdf (`ggx_sample_reflection`,
    /// `beckmann_sample_reflection`).
    #[inline(always)]
    pub fn sample(&self, wo: V3, u1: Floats, u2: Floats) -> (V3, Floats) {
        match self {
            Visible::Ggx(g) => ggx_sample_reflection(g, wo, u1, u2),
            Visible::Beckmann(b) => beckmann_sample_reflection(b, wo, u1, u2),
        }
    }

    /// The pdf of wi under the lobe for wo (`ggx_pdf_reflection`, `beckmann_pdf_reflection`).
    #[inline(always)]
    pub fn pdf(&self, wi: V3, wo: V3) -> Floats {
        match self {
            Visible::Ggx(g) => ggx_pdf_reflection(g, wi, wo),
            Visible::Beckmann(b) => beckmann_pdf_reflection(b, wi, wo),
        }
    }
}

/// Beckmann's Smith Λ(w) of a direction in the interface's frame (Microfacet::lambda; Heitz 2014 eq. 69):
/// (e^(−a²) / (a √π) − erfc a) / 2 with a = cos θ / √(αx² x² + αy² y²); 0 along the normal (a = ∞).
#[inline(always)]
fn beckmann_lambda(b: &Ggx, w: V3) -> Floats {
    let a = w.z / (w.x * w.x).mul_add(b.ax2, w.y * w.y * b.ay2).sqrt();
    let e = (-(a * a)).exp() / (a * std::f32::consts::PI.sqrt());
    0.5 * (e - a.erfc())
}

/// A reflected direction wi for wo (unit, above the surface) through Beckmann's visible normals of roughness record `b`
/// (Microfacet::sample_visible: Heitz & d'Eon 2014 §4): wo stretched to the standard configuration, the slopes of its
/// visible normals drawn (`beckmann_slopes`), unstretched, and wo reflected about the normal; and its pdf, from the
/// returned wi (`beckmann_pdf_reflection`: from the normal drawn, Beckmann's exponential would turn float32's
/// rounding of the reflection into 3e-4 of the pdf at α = 0.05).
#[inline(always)]
pub fn beckmann_sample_reflection(b: &Ggx, wo: V3, u1: Floats, u2: Floats) -> (V3, Floats) {
    let (v, vh, ax, ay) = stretched(b, wo);
    let (sx, sy) = beckmann_slopes(vh, u1, u2);
    let m = V3 { x: -(ax * sx), y: -(ay * sy), z: Floats::splat(1.0) };
    let wi = reflected(b, v, m.scale(1.0 / m.dot(m).sqrt()));
    (wi, beckmann_pdf_reflection(b, wi, wo))
}

/// The slopes (x̃, ỹ) of the standard Beckmann distribution's visible normals (α = 1) seen from the unit v
/// (distribution::beckmann_sample_slopes; Heitz & d'Eon 2014 §4). Along v's azimuth x̃ solves
/// G(x̃) = u1 G(c), G(x) = c (√π / 2) erfc(−x) + e^(−x²) / 2, c = cot θ (the density (c − x) e^(−x²) integrated), by
/// Halley's method kept inside a shrinking bracket [−6, min(c, 6)]; across it ỹ = erf⁻¹(2 u2 − 1); the pair rotated to
/// v's azimuth. Along the normal (c > 1e6) x̃ = erf⁻¹(2 u1 − 1). In float32 the root is found to the rounding of G,
/// which fixes x̃ to ε G / G'(x̃): finely where the density is high, coarsely in its tails.
#[inline(always)]
fn beckmann_slopes(v: V3, u1: Floats, u2: Floats) -> (Floats, Floats) {
    let (zero, one) = (Floats::splat(0.0), Floats::splat(1.0));
    let sin_t = v.x.mul_add(v.x, v.y * v.y).sqrt();
    let tilted = sin_t.gt(Floats::splat(1e-12));
    let (cos_phi, sin_phi) = (Floats::select(tilted, v.x / sin_t, one), Floats::and(tilted, v.y / sin_t));
    // The root where v is tilted (c ≤ 1e6; clamped elsewhere, whose result the normal's replaces).
    let c = (v.z / sin_t).min(Floats::splat(1e6));
    let normal = c.ge(Floats::splat(1e6));
    // The start (Jakob's form, Mitsuba's Beckmann sampler; our own fit): in the erf domain, where the CDF is nearly a
    // power, erf x̃ ≈ erf c − (1 + erf c) (1 − u1)^p, p a cubic in tan(θ/2) fitted by least squares over θ and u1. The
    // loop below then ends after its third pass in 99.97% of 16-lane groups (α = 0.3, random wo), after seven from the
    // normal's deviate. Along the normal, the normal's deviate erf⁻¹(2 u1 − 1) itself.
    let erf_c = 1.0 - c.erfc();
    let p = (sin_t / (1.0 + v.z)).poly(&[1.018_243_5, -1.914_486_3, 2.186_381_5, -0.865_382_2]);
    let below = 0.5 * (1.0 + erf_c) * (1.0 - (p * (1.0 - u1).ln()).exp());
    let start = Floats::select(normal, u1, below).erf_inv_uniform();
    let total = beckmann_slope_cdf(c, c);
    let target = u1 * total;
    let (mut lo, mut hi) = (Floats::splat(-6.0), c.min(Floats::splat(6.0)));
    let mut x = start.max(lo).min(hi);
    for _ in 0..24 {
        let f = beckmann_slope_cdf(x, c) - target;
        let above = f.gt(zero);
        hi = Floats::select(above, x, hi);
        lo = Floats::select(above, lo, x);
        // Halley's step with G' = (c − x) e^(−x²) and G'' = −(1 + 2x (c − x)) e^(−x²), Newton's f / G' over
        // 1 − f G'' / (2 G'²) (half Newton's iterations here), or Newton's where that factor is far from 1 (near
        // x = c, where G' vanishes and Halley's step would stall).
        let e = (-(x * x)).exp();
        let (g, h) = ((c - x) * e, -(2.0 * x).mul_add(c - x, one) * e);
        let newton = f / g;
        let r = newton * h / (2.0 * g);
        let step = Floats::select(r.abs().lt(Floats::splat(0.5)), newton / (1.0 - r), newton);
        // A root found (f = 0: x is then lo) stays: the bracket is closed.
        let guess = x - step;
        let inside = guess.ge(lo) & guess.le(hi);
        let next = Floats::select(inside, guess, 0.5 * (lo + hi));
        // Done where the step, the residual (to 4 ulp of u1) or the bracket is at float32's resolution.
        let moving = (next - x).abs().gt(Floats::splat(2e-7) * x.abs().max(one));
        let off = f.abs().gt(Floats::splat(2.4e-7) * total);
        let done = !(moving & off & (hi - lo).gt(Floats::splat(1e-6)));
        x = next;
        if done.all() {
            break;
        }
    }
    let x = Floats::select(normal, start, x);
    let y = u2.erf_inv_uniform();
    (cos_phi.mul_add(x, -(sin_phi * y)), sin_phi.mul_add(x, cos_phi * y))
}

/// G(x) = c (√π / 2) erfc(−x) + e^(−x²) / 2, the unnormalised CDF of `beckmann_slopes`' x̃ (a function, not a
/// closure: a closure may be compiled outside the row loop's instruction set).
#[inline(always)]
fn beckmann_slope_cdf(x: Floats, c: Floats) -> Floats {
    (c * (0.5 * std::f32::consts::PI.sqrt())).mul_add((-x).erfc(), 0.5 * (-(x * x)).exp())
}

/// The pdf per unit solid angle of wi under Beckmann's visible-normal sampling for wo, D_wo(h) / (4 wo·h) =
/// D(h) G1(wo) / (4 cos θo) (mixture::lobe_pdf; Walter et al. 2007 eq. 14, Heitz 2018 eq. 3), D from h = wi + wo
/// unnormalised (`beckmann_d`), and G1 = 1 / (1 + Λ(wo)); for wo and wi above the surface.
#[inline(always)]
pub fn beckmann_pdf_reflection(b: &Ggx, wi: V3, wo: V3) -> Floats {
    let h = wi.plus(wo);
    let (wo, h) = match b.frame {
        Some((c, s)) => (wo.rotate(c, s), h.rotate(c, s)),
        None => (wo, h),
    };
    let (h2, z2) = (h.dot(h), h.z * h.z);
    let slope = (h.x * h.x).mul_add(b.inv_ax2, h.y * h.y * b.inv_ay2);
    beckmann_d(slope, z2, h2, b.norm) / (4.0 * wo.z * (1.0 + beckmann_lambda(b, wo)))
}

/// Beckmann's D(h) from h unnormalised, exp(−(hx²/αx² + hy²/αy²) / hz²) |h|⁴ / (π αx αy hz⁴) (Walter et al. 2007
/// eq. 25), given slope = hx²/αx² + hy²/αy², hz², |h|² and 1 / (π αx αy); 0 where the exponential underflows (not
/// 0 · ∞ for hz → 0).
#[inline(always)]
fn beckmann_d(slope: Floats, z2: Floats, h2: Floats, norm: Floats) -> Floats {
    let e = (-(slope / z2)).exp();
    Floats::and(e.gt(Floats::splat(0.0)), e * (h2 * h2 * norm / (z2 * z2)))
}

/// A cosine-weighted direction on the upper hemisphere from two uniform numbers (sampling::cosine_hemisphere: Malley's
/// method, r = √u1, φ = 2π u2).
#[inline(always)]
pub fn cosine_hemisphere(u1: Floats, u2: Floats) -> V3 {
    let r = u1.sqrt();
    let (sin, cos) = u2.sincos_2pi();
    V3 { x: r * cos, y: r * sin, z: (1.0 - u1).max(Floats::splat(0.0)).sqrt() }
}

/// Dielectric transmittance 1 − F at cos θ ≥ 0 (fresnel::dielectric_transmittance), without cancellation at grazing
/// incidence: 2η cos θ cos θt (1 / (cos θ + η cos θt)² + 1 / (η cos θ + cos θt)²); 0 under total internal reflection.
#[inline(always)]
pub fn dielectric_transmittance(cos: Floats, eta: f64) -> Floats {
    let zero = Floats::splat(0.0);
    let cos = cos.max(zero).min(Floats::splat(1.0));
    let cos2_t = cos.mul_add(cos, Floats::splat((eta * eta - 1.0) as f32)) * ((1.0 / (eta * eta)) as f32);
    let cos_t = cos2_t.max(zero).sqrt();
    let e = eta as f32;
    let (s, p) = (cos_t.mul_add(Floats::splat(e), cos), cos.mul_add(Floats::splat(e), cos_t));
    let t = (2.0 * e) * cos * cos_t * (1.0 / (s * s) + 1.0 / (p * p));
    Floats::and(cos2_t.gt(zero), t)
}

/// A microfacet interface with Torrance–Sparrow's V-cavity masking-shadowing as the lanes take it, of GGX or
/// Beckmann normals (Weidlich–Wilkie's lobes).
#[derive(Clone, Copy, Debug)]
pub struct VCavity {
    beckmann: bool,
    /// 1 / αx², 1 / αy², 1 / (π αx αy).
    inv_ax2: f32,
    inv_ay2: f32,
    norm: f32,
    frame: Option<(Floats, Floats)>,
}

impl VCavity {
    /// The lanes' form of `mf`; None for a smooth interface.
    pub fn new(mf: &Microfacet) -> Option<VCavity> {
        if mf.is_smooth() {
            return None;
        }
        let (ax, ay) = (mf.alpha_x, mf.alpha_y);
        let (c, s) = mf.frame();
        Some(VCavity {
            beckmann: mf.dist == Distribution::Beckmann,
            inv_ax2: (1.0 / (ax * ax)) as f32,
            inv_ay2: (1.0 / (ay * ay)) as f32,
            norm: (std::f64::consts::FRAC_1_PI / (ax * ay)) as f32,
            frame: (s != 0.0).then_some((Floats::splat(c as f32), Floats::splat(s as f32))),
        })
    }
}

/// V-cavity masking-shadowing of a reflected pair above the surface (distribution::v_cavity at h = wi + wo, where
/// wi·h = wo·h = |h|²/2): min(1, 4 hz min(cos θi, cos θo) / |h|²); 0 unless both are above.
#[inline(always)]
pub fn v_cavity(wi: V3, wo: V3) -> Floats {
    let zero = Floats::splat(0.0);
    let h = wi.plus(wo);
    let g = (4.0 * h.z * wi.z.min(wo.z) / h.dot(h)).min(Floats::splat(1.0));
    Floats::and(wi.z.gt(zero) & wo.z.gt(zero), g)
}

/// D(h) G2 / (4 cos θi cos θo) with the V-cavity G2, and wi·h (bsdf::reflection_geometry); 0 unless both directions
/// are above. D from h = wi + wo unnormalised: GGX |h|⁴ / (π αx αy s²), s = hx²/αx² + hy²/αy² + hz² (Walter et al.
/// 2007 eq. 33); Beckmann exp(−(hx²/αx² + hy²/αy²) / hz²) |h|⁴ / (π αx αy hz⁴) (eq. 25).
#[inline(always)]
pub fn v_cavity_reflection(v: &VCavity, wi: V3, wo: V3) -> (Floats, Floats) {
    let h = match v.frame {
        Some((c, s)) => wi.plus(wo).rotate(c, s),
        None => wi.plus(wo),
    };
    let h2 = h.dot(h);
    let slope = (h.x * h.x).mul_add(Floats::splat(v.inv_ax2), h.y * h.y * v.inv_ay2);
    let z2 = h.z * h.z;
    let d = if v.beckmann {
        beckmann_d(slope, z2, h2, Floats::splat(v.norm))
    } else {
        let s = slope + z2;
        h2 * h2 * v.norm / (s * s)
    };
    // G2 / (4 cos θi cos θo) = min(1 / (4 cos θi cos θo), hz / (|h|² max(cos θi, cos θo))): the product of the
    // cosines, which underflows for a grazing direction, only where it is the smaller term.
    let masking = (1.0 / (4.0 * wi.z * wo.z)).min(h.z / (h2 * wi.z.max(wo.z)));
    let above = wi.z.gt(Floats::splat(0.0)) & wo.z.gt(Floats::splat(0.0));
    (Floats::and(above, d * masking), 0.5 * h2.sqrt())
}

/// D(h) G2 / (4 cos θi cos θo) and wi·h for Beckmann normals with a Smith G2 (bsdf::reflection_geometry); 0 unless
/// both directions are above. D from h = wi + wo unnormalised (`beckmann_d`); G2 = 1 / ((1 + Λi)(1 + Λo)) separable,
/// 1 / (1 + Λi + Λo) height-correlated (Heitz 2014 eqs. 98, 99), Λ by `beckmann_lambda`.
#[inline(always)]
pub fn beckmann_reflection(b: &Ggx, wi: V3, wo: V3) -> (Floats, Floats) {
    let (zero, one) = (Floats::splat(0.0), Floats::splat(1.0));
    let above = wi.z.gt(zero) & wo.z.gt(zero);
    let h = wi.plus(wo);
    let (wi, wo, h) = match b.frame {
        Some((c, s)) => (wi.rotate(c, s), wo.rotate(c, s), h.rotate(c, s)),
        None => (wi, wo, h),
    };
    let (h2, z2) = (h.dot(h), h.z * h.z);
    let slope = (h.x * h.x).mul_add(b.inv_ax2, h.y * h.y * b.inv_ay2);
    let d = beckmann_d(slope, z2, h2, b.norm);
    let (li, lo) = (beckmann_lambda(b, wi), beckmann_lambda(b, wo));
    let masking = if b.height_correlated { one + li + lo } else { (one + li) * (one + lo) };
    (Floats::and(above, d / (4.0 * wi.z * wo.z * masking)), 0.5 * h2.sqrt())
}

/// A rough interface's reflection lobe in lanes: GGX or Beckmann with a Smith G2, or either with the V-cavity.
/// (One per layer, built at `prepare` and read in the row loop: unboxed, whatever the variants' sizes.)
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug)]
pub enum Lobe {
    Smith(Ggx),
    /// Beckmann's normals with a Smith G2, in `Ggx`'s roughness record.
    BeckmannSmith(Ggx),
    VCavity(VCavity),
}

impl Lobe {
    /// The lobe of `mf` with masking-shadowing `g2`: None for a smooth interface.
    pub fn new(mf: &Microfacet, g2: G2Form) -> Option<Lobe> {
        match (g2, mf.dist) {
            (G2Form::VCavity, _) => VCavity::new(mf).map(Lobe::VCavity),
            (_, Distribution::Ggx) => Ggx::new(mf, g2).map(Lobe::Smith),
            (_, Distribution::Beckmann) => (!mf.is_smooth()).then(|| Lobe::BeckmannSmith(Ggx::record(mf, g2))),
        }
    }

    /// D G2 / (4 cos θi cos θo) and wi·h (`ggx_reflection`, `beckmann_reflection`, `v_cavity_reflection`).
    #[inline(always)]
    pub fn reflection(&self, wi: V3, wo: V3) -> (Floats, Floats) {
        match self {
            Lobe::Smith(g) => ggx_reflection(g, wi, wo),
            Lobe::BeckmannSmith(b) => beckmann_reflection(b, wi, wo),
            Lobe::VCavity(v) => v_cavity_reflection(v, wi, wo),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf;
    use crate::optics::fresnel;
    use glam::DVec3;

    fn lanes(ws: &[DVec3]) -> V3 {
        let c = |k: usize| Floats(std::array::from_fn(|i| ws[i % ws.len()][k] as f32));
        V3 { x: c(0), y: c(1), z: c(2) }
    }

    /// Directions over the hemisphere and the grazing band, rounded to float32 (both sides of a comparison take the
    /// same rounded directions: float32's rounding of a direction moves the half vector of a grazing pair by up to
    /// 1e-5 relative, a difference of the inputs, not of the arithmetic).
    fn directions(n: usize, seed: u64) -> Vec<DVec3> {
        let mut rng = crate::sampling::Rng::new(seed, 0);
        (0..n)
            .map(|_| {
                let z = if rng.uniform() < 0.2 { 1e-3 * rng.uniform() + 1e-6 } else { rng.uniform() };
                let phi = 2.0 * std::f64::consts::PI * rng.uniform();
                let s = (1.0 - z * z).sqrt();
                DVec3::new(s * phi.cos(), s * phi.sin(), z).as_vec3().as_dvec3()
            })
            .collect()
    }

    #[test]
    fn the_conductor_fresnel_forms_match_their_float64_twins() {
        // Relative to F (absolute 1e-12: float64 rounding of an F that vanishes, η = 1, κ = 0), over cos θ in (0, 1]:
        // gold, copper, a dielectric-like κ ≈ 0, a weakly absorbing metal, nearly index-matched ones, and IORs whose
        // η² − κ² − sin²θ takes both signs (total internal reflection for κ = 0). The engine's bound, 1e-5.
        for form in FresnelForm::ALL {
            for (eta, k) in [
                (0.18, 3.4),
                (0.27, 3.6),
                (0.5, 0.6),
                (1.5, 1e-4),
                (2.5, 0.2),
                (1.0, 1.0),
                (1.0, 0.0),
                (1.001, 0.01),
                (0.9, 0.3),
                (0.5, 0.1),
                (0.7, 0.0),
            ] {
                let ior = ConductorIor::new(form, eta, k);
                for i in 0..1000 {
                    let cos = (i as f32 + 0.5) / 1000.0;
                    let got = conductor(Floats::splat(cos), &ior).0[0] as f64;
                    let want = form.conductor(cos as f64, eta, k);
                    assert!(
                        (got - want).abs() <= 1e-5 * want + 1e-12,
                        "{form:?} η = {eta}, κ = {k}, cos = {cos}: {got} vs {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_dielectric_fresnel_matches_its_float64_twin() {
        // Relative to F over cos θ in (0, 1], from outside (η > 1) and from inside (η < 1, total internal reflection
        // past the critical angle), η near 1 included. Measured: 1.5e-6 at most, near the Brewster angle where F is small.
        for eta in [1.5, 1.33, 2.4, 1.0 / 1.5, 1.0 / 1.1, 1.0001, 1.0 / 1.0001, 1.0 + 1e-9] {
            for i in 0..2000 {
                let cos = (i as f32 + 0.5) / 2000.0;
                let got = dielectric(Floats::splat(cos), eta).0[0] as f64;
                let want = fresnel::dielectric(cos as f64, eta);
                // Near the critical angle (cos² θ = 1 − η²) F's slope in cos θt is finite but cos θt = √(critical)/η
                // is not: float32's rounding of η² − 1 (3e-8) moves cos θt by 1.5e-8 / cos θt, and F by a few times
                // that, 1e-7 / √|critical| (it exceeds 4e-6 F within 1e-3 of the critical angle).
                let critical = (cos as f64).powi(2) - (1.0 - eta * eta);
                let tol = 4e-6 * want + 1e-9 + 1e-7 / critical.abs().sqrt();
                assert!((got - want).abs() <= tol, "η = {eta}, cos = {cos}: {got} vs {want}");
            }
        }
    }

    #[test]
    fn beckmanns_visible_normals_match_their_float64_twins() {
        // From the same u, the lanes' reflected direction against Microfacet::sample_visible's (float64), and the pdf
        // at the lanes' direction against mixture::lobe_pdf, for isotropic, anisotropic and rotated Beckmann. The
        // float32 root of the slope's CDF is fixed only to ε G / G' (`beckmann_slopes`), coarsely in the density's
        // tails: 99% of the directions within 3e-5 of float64's and all within 1e-3 (measured: 1.7e-5 and 2.8e-4, at
        // α = 1). The pdf within 1e-5 relative (measured 6.7e-6).
        use crate::models::common::mixture::lobe_pdf;
        use crate::models::Proposal;
        let n = 40_000;
        let wos = directions(n, 3);
        let mut rng = crate::sampling::Rng::new(4, 0);
        let us: Vec<(f32, f32)> = (0..n).map(|_| (rng.uniform() as f32, rng.uniform() as f32)).collect();
        for (ax, ay, angle) in [(0.05, 0.05, 0.0), (0.3, 0.3, 0.0), (0.1, 0.6, 0.7), (1.0, 1.0, 0.0)] {
            let mf = Microfacet::new(Distribution::Beckmann, ax, ay, angle);
            let Some(Visible::Beckmann(b)) = Visible::new(&mf) else { panic!("a rough Beckmann lobe") };
            let (mut gaps, mut worst_pdf) = (Vec::new(), 0.0f64);
            for (wo, u) in wos.chunks(crate::engine::LANES).zip(us.chunks(crate::engine::LANES)) {
                let u1 = Floats(std::array::from_fn(|i| u[i % u.len()].0));
                let u2 = Floats(std::array::from_fn(|i| u[i % u.len()].1));
                let (wi, pdf) = beckmann_sample_reflection(&b, lanes(wo), u1, u2);
                for (i, &wo) in wo.iter().enumerate() {
                    let m = mf.sample_visible(wo, u[i].0 as f64, u[i].1 as f64);
                    let want = 2.0 * wo.dot(m) * m - wo;
                    let got = DVec3::new(wi.x.0[i] as f64, wi.y.0[i] as f64, wi.z.0[i] as f64);
                    gaps.push((got - want).abs().max_element());
                    if got.z > 0.0 {
                        let exact = lobe_pdf(&Proposal::Reflection(mf), got, wo);
                        worst_pdf = worst_pdf.max((pdf.0[i] as f64 - exact).abs() / exact);
                    }
                }
            }
            gaps.sort_by(f64::total_cmp);
            let (p99, max) = (gaps[gaps.len() * 99 / 100], gaps[gaps.len() - 1]);
            assert!(p99 <= 3e-5 && max <= 1e-3, "α = ({ax}, {ay}): 99% {p99}, worst {max}");
            assert!(worst_pdf <= 1e-5, "α = ({ax}, {ay}): pdf {worst_pdf}");
        }
    }

    #[test]
    fn beckmann_reflection_matches_its_float64_twin() {
        // As GGX's below, for Beckmann with a Smith G2 (its Λ from the lanes' erfc and exp). Measured: 2.1e-6 at
        // most.
        let (wis, wos) = (directions(4000, 5), directions(4000, 6));
        let mut worst = 0.0f64;
        for (ax, ay, angle) in [(1e-3, 1e-3, 0.0), (0.05, 0.05, 0.0), (0.3, 0.3, 0.0), (0.1, 0.6, 0.7), (1.0, 1.0, 0.0)]
        {
            for form in [G2Form::Separable, G2Form::HeightCorrelated] {
                let mf = Microfacet::new(Distribution::Beckmann, ax, ay, angle);
                let lobe = Lobe::new(&mf, form).unwrap();
                let want: Vec<f64> = wis
                    .iter()
                    .zip(&wos)
                    .map(|(&wi, &wo)| bsdf::reflection_geometry(&mf, form, wi, wo).map_or(0.0, |g| g.0))
                    .collect();
                let peak = want.iter().fold(0.0, |a: f64, &b| a.max(b));
                for (k, (wi8, wo8)) in wis.chunks(8).zip(wos.chunks(8)).enumerate() {
                    let (geo, _) = lobe.reflection(lanes(wi8), lanes(wo8));
                    for i in 0..wi8.len() {
                        let gw = want[8 * k + i];
                        if gw >= 1e-3 * peak && gw > 1e-30 {
                            worst = worst.max((geo.0[i] as f64 - gw).abs() / gw);
                        }
                        // Below 1e-35, float32 underflows (at α = 1e-3 every random pair is that far from the lobe).
                        let tol = if gw >= 1e-3 * peak { 1e-5 * gw } else { 1e-8 * peak };
                        let tol = tol.max(1e-35);
                        assert!((geo.0[i] as f64 - gw).abs() <= tol, "α = ({ax}, {ay}) {form:?}: {} vs {gw}", geo.0[i]);
                    }
                }
            }
        }
        assert!(worst <= 1e-5, "worst {worst}");
    }

    #[test]
    fn ggx_reflection_matches_its_float64_twin() {
        // Relative to the geometry term where it is ≥ 1e-3 of the largest value on these pairs, absolute below, for
        // smooth-ish, rough, anisotropic and rotated GGX, both G2 forms. Measured: 3e-6 at most (α = 1e-3, whose lobe
        // turns float32's rounding of the directions into a relative change of D).
        let (wis, wos) = (directions(4000, 1), directions(4000, 2));
        for (ax, ay, angle) in
            [(1e-3, 1e-3, 0.0), (0.05, 0.05, 0.0), (0.3, 0.3, 0.0), (0.1, 0.6, 0.0), (0.1, 0.6, 0.7), (1.0, 1.0, 0.0)]
        {
            for form in [G2Form::Separable, G2Form::HeightCorrelated] {
                let mf = Microfacet::new(Distribution::Ggx, ax, ay, angle);
                let g = Ggx::new(&mf, form).unwrap();
                let want: Vec<(f64, f64)> = wis
                    .iter()
                    .zip(&wos)
                    .map(|(&wi, &wo)| {
                        bsdf::reflection_geometry(&mf, form, wi, wo).unwrap_or((0.0, wi.dot((wi + wo).normalize())))
                    })
                    .collect();
                let peak = want.iter().map(|w| w.0).fold(0.0, f64::max);
                for (k, (wi8, wo8)) in wis.chunks(8).zip(wos.chunks(8)).enumerate() {
                    let (geo, cos_h) = ggx_reflection(&g, lanes(wi8), lanes(wo8));
                    for i in 0..wi8.len() {
                        let (gw, cw) = want[8 * k + i];
                        let tol = if gw >= 1e-3 * peak { 1e-5 * gw } else { 1e-8 * peak };
                        assert!(
                            (geo.0[i] as f64 - gw).abs() <= tol,
                            "α = ({ax}, {ay}) {form:?}: {} vs {gw} at {} {}",
                            geo.0[i],
                            wi8[i],
                            wo8[i]
                        );
                        // The float64 form wi·h/|h| cancels (1 + wi·wo) for nearly opposite grazing directions,
                        // whose length differs from 1 by float32's rounding: up to 1.2e-5 there.
                        assert!((cos_h.0[i] as f64 - cw).abs() <= 2e-5, "cos h: {} vs {cw}", cos_h.0[i]);
                    }
                }
            }
        }
    }

    #[test]
    fn dielectric_transmittance_matches_its_float64_twin() {
        // Relative to T over cos θ in (0, 1], grazing included (where 1 − F in float32 would lose T). Same critical
        // angle allowance as the reflectance. Measured: 1.3e-6 at most.
        for eta in [1.5, 1.33, 2.4, 1.0 / 1.5, 1.0001, 1.0 + 1e-9] {
            for i in 0..2000 {
                let cos = (i as f32 + 0.5) / 2000.0;
                let got = dielectric_transmittance(Floats::splat(cos), eta).0[0] as f64;
                let want = fresnel::dielectric_transmittance(cos as f64, eta);
                let critical = (cos as f64).powi(2) - (1.0 - eta * eta);
                let tol = 4e-6 * want + 1e-9 + 1e-7 / critical.abs().sqrt();
                assert!((got - want).abs() <= tol, "η = {eta}, cos = {cos}: {got} vs {want}");
            }
        }
    }

    #[test]
    fn v_cavity_reflection_matches_its_float64_twin() {
        // As ggx_reflection's test, for V-cavity lobes of Beckmann and GGX normals.
        let (wis, wos) = (directions(4000, 3), directions(4000, 4));
        for dist in [Distribution::Beckmann, Distribution::Ggx] {
            for (ax, ay, angle) in [(0.05, 0.05, 0.0), (0.3, 0.3, 0.0), (0.1, 0.6, 0.7), (1.0, 1.0, 0.0)] {
                let mf = Microfacet::new(dist, ax, ay, angle);
                let v = VCavity::new(&mf).unwrap();
                let want: Vec<f64> = wis
                    .iter()
                    .zip(&wos)
                    .map(|(&wi, &wo)| bsdf::reflection_geometry(&mf, G2Form::VCavity, wi, wo).map_or(0.0, |g| g.0))
                    .collect();
                let peak = want.iter().fold(0.0, |a: f64, &b| a.max(b));
                for (k, (wi8, wo8)) in wis.chunks(8).zip(wos.chunks(8)).enumerate() {
                    let (geo, _) = v_cavity_reflection(&v, lanes(wi8), lanes(wo8));
                    for i in 0..wi8.len() {
                        let gw = want[8 * k + i];
                        // wi·h = |h|²/2 holds for unit directions; these are unit to float32's rounding, |w|² − 1 ≤
                        // 1.2e-7, which the nearly opposite pairs' small |h|² magnifies (float64's twin takes them
                        // as given); and a sharp lobe turns the rounding of h into 4e-7 / (α |h|) of D (as
                        // tests/test_engine.py's conditioning).
                        let h2 = (wi8[i] + wo8[i]).length_squared();
                        let rel = 1e-5 + 1.2e-7 / h2 + 4e-7 / (ax.min(ay) * h2.sqrt());
                        let tol = (rel * gw).max(if gw >= 1e-3 * peak { 0.0 } else { 1e-8 * peak });
                        assert!(
                            (geo.0[i] as f64 - gw).abs() <= tol,
                            "{dist:?} α = ({ax}, {ay}): {} vs {gw} at {} {} (h {})",
                            geo.0[i],
                            wi8[i],
                            wo8[i],
                            (wi8[i] + wo8[i]).length()
                        );
                    }
                }
            }
        }
    }
}
