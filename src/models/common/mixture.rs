//! Importance sampling for every model: a one-sample mixture of the lobes the model proposes for the viewing
//! direction (`Model::proposals`), each reflection lobe sampled through its visible normals (Heitz 2018) and
//! diffuse terms by the cosine-weighted hemisphere (pbrt-v4's and Mitsuba 3's BSDF sampling). The pdf is the
//! mixture's, per unit solid angle of wi; the weight f·cos θi / pdf is computed by the caller from the model's own f,
//! so any mixture is unbiased.

use crate::models::{Model, Proposal};
use crate::optics::reflect;
use crate::sampling::cosine_hemisphere;
use glam::DVec3;
use std::f64::consts::FRAC_1_PI;

/// Share of a layered model's sampling mixture given to the cosine lobe, so that the pdf covers every direction where
/// f is non-zero: the lobes of layers under a coat are proposed at the outside directions, which they only approach.
pub const DEFENSIVE: f64 = 0.05;

/// A layered model's mixture from its terms' estimated energies: the terms with energy, plus the DEFENSIVE cosine
/// share (none when nothing has energy: only Dirac lobes).
pub fn defensive_mixture(terms: Vec<(f64, Proposal)>) -> Vec<(f64, Proposal)> {
    let mut lobes: Vec<(f64, Proposal)> = terms.into_iter().filter(|(w, _)| *w > 0.0).collect();
    let total: f64 = lobes.iter().map(|(w, _)| w).sum();
    if total > 0.0 {
        lobes.push((DEFENSIVE * total / (1.0 - DEFENSIVE), Proposal::Cosine));
    }
    lobes
}

/// The factor that turns f at a sampled direction wi into the sample's weight f cos θi / pdf; 0 for a lost sample
/// (pdf 0). Every sampler's weight (`Stack.sample`, the renderer's BSDF samples, and their WGSL mirror) is f times it.
#[inline]
pub fn weight_factor(wi: DVec3, pdf: f64) -> f64 {
    if pdf > 0.0 {
        wi.z / pdf
    } else {
        0.0
    }
}

/// pdf of wi under one lobe for the viewing direction wo: D_wo(h) / (4 wo·h) for a reflection lobe (the Jacobian
/// of the reflection map, Walter et al. 2007 eq. 14), cos θi / π for the cosine lobe.
pub fn lobe_pdf(lobe: &Proposal, wi: DVec3, wo: DVec3) -> f64 {
    match lobe {
        Proposal::Cosine => wi.z.max(0.0) * FRAC_1_PI,
        Proposal::Reflection(mf) => {
            let h = (wi + wo).normalize();
            let c = wo.dot(h);
            if c > 0.0 && h.is_finite() {
                mf.pdf_visible(wo, h) / (4.0 * c)
            } else {
                0.0
            }
        }
    }
}

/// The mixture's pdf of wi for the viewing direction wo; 0 below the horizon.
pub fn mixture_pdf(lobes: &[(f64, Proposal)], wi: DVec3, wo: DVec3) -> f64 {
    let total: f64 = lobes.iter().map(|(w, _)| w).sum();
    if wi.z <= 0.0 || wo.z <= 0.0 || total <= 0.0 {
        return 0.0;
    }
    lobes.iter().map(|(w, lobe)| w / total * lobe_pdf(lobe, wi, wo)).sum()
}

/// pdf(wi | wo) of `model`'s sampling.
pub fn pdf(model: &dyn Model, wi: DVec3, wo: DVec3) -> f64 {
    if wo.z <= 0.0 {
        return 0.0;
    }
    mixture_pdf(&model.proposals(wo), wi, wo)
}

/// Samples wi for the viewing direction wo from three uniform numbers (u[0] picks the lobe, u[1], u[2] the
/// direction): (wi, pdf). pdf = 0 when nothing can be sampled (wo below the horizon, only Dirac lobes) or when the
/// sampled direction lies below the horizon (a lost sample: weight 0).
pub fn sample(model: &dyn Model, wo: DVec3, u: [f64; 3]) -> (DVec3, f64) {
    if wo.z <= 0.0 {
        return (DVec3::Z, 0.0);
    }
    sample_mixture(&model.proposals(wo), wo, u)
}

/// `sample` from the mixture `lobes` proposed for wo (a caller that samples one wo many times computes it once).
pub fn sample_mixture(lobes: &[(f64, Proposal)], wo: DVec3, u: [f64; 3]) -> (DVec3, f64) {
    let total: f64 = lobes.iter().map(|(w, _)| w).sum();
    if lobes.is_empty() || total <= 0.0 || wo.z <= 0.0 {
        return (DVec3::Z, 0.0);
    }
    let (u0, u1, u2) = (u[0].clamp(0.0, 1.0) * total, u[1].clamp(0.0, 1.0), u[2].clamp(0.0, 1.0));
    let mut acc = 0.0;
    let mut chosen = &lobes[lobes.len() - 1].1;
    for (w, lobe) in lobes {
        acc += w;
        if u0 < acc {
            chosen = lobe;
            break;
        }
    }
    let wi = match chosen {
        Proposal::Cosine => cosine_hemisphere(u1, u2),
        Proposal::Reflection(mf) => reflect(wo, mf.sample_visible(wo, u1, u2)),
    };
    if wi.z.is_nan() || wi.z <= 0.0 {
        return (wi, 0.0);
    }
    (wi, mixture_pdf(lobes, wi, wo))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::common::testing::{args, conductor, dielectric, dir, hemisphere, lambert, stack};
    use crate::models::{steinberg, Model};

    #[test]
    fn the_pdf_integrates_to_the_share_of_samples_kept() {
        // ∫ pdf dω over the upper hemisphere is the probability that a sample lands there (a reflected visible normal
        // may leave it): the quadrature of `pdf` against the fraction of 2^18 samples with pdf > 0 (its standard
        // error 1e-3 at most; measured 3e-4 apart at most).
        let opts = steinberg::Options::parse(&args(&steinberg::INFO, &[])).unwrap();
        let coated = |base| stack(vec![dielectric(1.5, 0.3, 0.5, 0.2, 0.4), base]);
        for (m, theta) in [lambert(0.5), conductor(0.27, 3.4, (0.25, 0.1))]
            .into_iter()
            .flat_map(|base| [10.0, 50.0, 80.0].map(|t| (steinberg::prepare(&coated(base.clone()), &opts).unwrap(), t)))
        {
            let wo = dir(theta, 30.0);
            let integral = hemisphere(256, 512, |wi| pdf(&m, wi, wo) / wi.z);
            let n = 1 << 18;
            let kept = (0..n)
                .filter(|&k| {
                    let u = [
                        (k as f64 + 0.5) / n as f64,
                        (k as f64 * 0.754_877_666).fract(),
                        (k as f64 * 0.569_840_291).fract(),
                    ];
                    sample(&m, wo, u).1 > 0.0
                })
                .count() as f64
                / n as f64;
            assert!((integral - kept).abs() < 3e-3, "θo = {theta}°: ∫ pdf = {integral}, kept {kept}");
            assert!(m.proposals(wo).iter().all(|(w, _)| *w > 0.0));
        }
    }
}
