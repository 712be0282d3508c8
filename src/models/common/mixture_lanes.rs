//! Importance sampling in float32 lanes (mixture.rs's one-sample mixture): a model whose lane kernel also proposes
//! its mixture in lanes (`Proposals`) samples through `sample`, with no dispatch code of its own. Per lane the same
//! lobe is picked from u[0] as `mixture::sample_mixture` picks it, the direction is drawn from u[1], u[2] (GGX's or
//! Beckmann's visible normals, or the cosine), the pdf is the whole mixture's, and the weight f cos θi / pdf takes
//! the kernel's own f.
//! Lanes and float64 pick different lobes only where u[0] lies within float32's rounding of a boundary between two
//! lobes' shares.

use super::mixture::DEFENSIVE;
use crate::engine::{self, Floats, Kernel, Mask, Rows, V3};
use crate::optics::lanes::{cosine_hemisphere, Visible};
use std::f32::consts::FRAC_1_PI;

/// Terms a lane mixture holds at the most (a model with more samples on the float64 path).
pub const MAX_TERMS: usize = 8;

/// A sampling mixture per lane, in the order of the model's `proposals`: each term's weight per lane (0 where the
/// float64 mixture leaves it out) and its lobe (None: the cosine).
pub struct LaneMixture {
    terms: [(Floats, Option<Visible>); MAX_TERMS],
    count: usize,
}

impl LaneMixture {
    pub fn new() -> LaneMixture {
        LaneMixture { terms: [(Floats::splat(0.0), None); MAX_TERMS], count: 0 }
    }

    /// Appends a term: its weight per lane (negative or NaN taken as 0, as the float64 mixture drops terms without
    /// energy) and its lobe (None: the cosine).
    #[inline(always)]
    pub fn push(&mut self, weight: Floats, lobe: Option<Visible>) {
        debug_assert!(self.count < MAX_TERMS);
        let zero = Floats::splat(0.0);
        self.terms[self.count] = (Floats::select(weight.gt(zero), weight, zero), lobe);
        self.count += 1;
    }

    fn total(&self) -> Floats {
        self.terms[..self.count].iter().fold(Floats::splat(0.0), |t, (w, _)| t + *w)
    }

    /// mixture::defensive_mixture: the DEFENSIVE cosine share of the terms' total.
    #[inline(always)]
    pub fn add_defensive_share(&mut self) {
        let total = self.total();
        self.push(total * (DEFENSIVE / (1.0 - DEFENSIVE)) as f32, None);
    }
}

/// The mean of per-channel lanes (a term's weight: the mean of its energies over the channels).
#[inline(always)]
pub fn mean(v: &[Floats]) -> Floats {
    v.iter().fold(Floats::splat(0.0), |s, &x| s + x) * (1.0 / v.len() as f32)
}

impl Default for LaneMixture {
    fn default() -> LaneMixture {
        LaneMixture::new()
    }
}

/// A lane kernel's sampling mixture for LANES viewing directions (unit, above the surface where it matters): the
/// lane form of its model's `Model::proposals`.
pub trait Proposals: Kernel {
    fn proposals(&self, wo: V3) -> LaneMixture;
}

/// `Stack.sample`'s rows of float32 (wo, u) by the kernel's mixture (`engine::sample`); false where a row needs the
/// careful path.
pub fn sample<K: Proposals>(kernel: &K, channels: usize, wo: Rows, u: Rows, out: &mut [f32]) -> bool {
    engine::sample(&Mixture { kernel, channels }, 3 + channels + 1, wo, u, out)
}

struct Mixture<'a, K> {
    kernel: &'a K,
    channels: usize,
}

impl<K: Proposals> engine::Sampler for Mixture<'_, K> {
    #[inline(always)]
    fn sample(&self, wo: V3, u: V3, out: &mut [Floats]) {
        let zero = Floats::splat(0.0);
        let mix = self.kernel.proposals(wo);
        let terms = &mix.terms[..mix.count];
        let total = mix.total();
        let valid = wo.z.gt(zero) & total.gt(zero);
        // The first term whose running sum exceeds u[0]·total, else the last with a weight (sample_mixture).
        let u0 = u.x * total;
        let (mut acc, mut taken) = (zero, Mask::NONE);
        let mut picked = [Mask::NONE; MAX_TERMS];
        for (p, (w, _)) in picked.iter_mut().zip(terms) {
            acc = acc + *w;
            *p = !taken & u0.lt(acc);
            taken = taken | *p;
        }
        for (p, (w, _)) in picked.iter_mut().zip(terms).rev() {
            let last = !taken & w.gt(zero);
            *p = *p | last;
            taken = taken | last;
        }
        // The picked lobe's roughness per lane, one visible-normal sample, and the cosine where a cosine was picked.
        let mut lobe: Option<Visible> = None;
        let mut cosine = Mask::NONE;
        for (&p, (_, g)) in picked.iter().zip(terms) {
            match (g, lobe) {
                (Some(g), Some(l)) => lobe = Some(Visible::select(p, g, &l)),
                (Some(g), None) => lobe = Some(*g),
                (None, _) => cosine = cosine | p,
            }
        }
        let diffuse = cosine_hemisphere(u.y, u.z);
        let wi = match &lobe {
            Some(g) => V3::select(cosine, diffuse, g.sample(wo, u.y, u.z).0),
            None => diffuse,
        };
        // A wo below the surface samples the normal; a lost sample (wi below it) keeps its direction, and the normal
        // stands in for it in f and the pdf (its weight and pdf are 0).
        let normal = V3::splat([0.0, 0.0, 1.0]);
        let sampled = V3::select(valid, wi, normal);
        let kept = valid & wi.z.gt(zero);
        let wi = V3::select(kept, wi, normal);
        // mixture::mixture_pdf.
        let mut pdf = zero;
        for (w, g) in terms {
            let lobe_pdf = match g {
                Some(g) => g.pdf(wi, wo),
                None => wi.z * FRAC_1_PI,
            };
            pdf = w.mul_add(lobe_pdf, pdf);
        }
        let pdf = Floats::and(kept, pdf / total);
        let kept = kept & pdf.gt(zero);
        let (head, rest) = out.split_at_mut(3);
        let (weight, tail) = rest.split_at_mut(self.channels);
        self.kernel.eval(wi, wo, weight);
        let factor = Floats::and(kept, wi.z / pdf);
        weight.iter_mut().for_each(|w| *w = *w * factor);
        tail[0] = Floats::and(kept, pdf);
        head.copy_from_slice(&[sampled.x, sampled.y, sampled.z]);
    }
}
