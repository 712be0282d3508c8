//! Ground truth: Monte Carlo light transport in a layer stack, position-free in x and y (Guo, Hašan and Zhao 2018).
//!
//! Two estimators share the sampling below. `run` is a brute-force analog walk of light from wi that records where
//! energy leaves the top: directional albedo and binned lobes. `estimate_f` estimates f(wi, wo) itself: a camera
//! walk from wo (radiance, with the (η_a/η_b)² factor of each refraction) connects by next-event estimation to a
//! light subpath from wi that follows smooth (delta) interfaces up to its first non-delta event — a rough
//! interface, the base, or any point of a scattering slab it crosses. Every light path splits uniquely at that
//! event, so each is counted once and the estimator is unbiased for any mix of smooth and rough layers.
//!
//! Interfaces are sampled exactly as their BSDFs are defined: visible normals, then reflection or refraction with
//! probability F (weight G2/G1), smooth interfaces as deltas. Slabs use free-flight sampling with σ_t and
//! Henyey–Greenstein scattering (weight σ_s/σ_t); non-scattering slabs attenuate by Beer–Lambert. Russian roulette
//! keeps the estimate unbiased; paths reaching MAX_DEPTH are counted and reported. The boundaries and slabs
//! themselves are transport.rs's, which the adding-doubling solver shares.
//!
//! | Parameter      | Type   | Default             | Description                                                    |
//! |----------------|--------|---------------------|----------------------------------------------------------------|
//! | `distribution` | string | `ggx`               | microfacet distribution of every rough boundary                |
//! | `g2`           | string | `height_correlated` | masking-shadowing of every rough boundary                      |
//!
//! (the options of `models::REFERENCE`, the reference's catalogue entry.)

use crate::optics::diffuse;
use crate::optics::distribution::{G2Form, Microfacet};
use crate::optics::fresnel;
use crate::optics::{reflect, refract};
use crate::sampling::{cosine_hemisphere, henyey_greenstein, power_heuristic, sample_henyey_greenstein, Rng};
use crate::transport::{Base, ChannelStack, Slab};
use glam::DVec3;
use rayon::prelude::*;
use std::f64::consts::PI;

/// Scattering events after which a path is truncated (and counted).
pub const MAX_DEPTH: usize = 1000;
/// Paths per parallel task, reduced in order (deterministic whatever the thread count).
const PATHS_PER_TASK: usize = 4096;

/// How a path ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Exit {
    /// Left the top of the stack along `dir` carrying `weight` of the incident energy.
    Escaped {
        dir: DVec3,
        weight: f64,
    },
    Absorbed,
    Truncated,
}

/// Scatters a path travelling along `d` at an interface with relative IOR `eta` (below / above) and normal +z.
/// Returns the new travel direction and the weight factor, or None when the microfacet model loses the path.
fn scatter_interface(mf: &Microfacet, g2: G2Form, eta: f64, d: DVec3, rng: &mut Rng) -> Option<(DVec3, f64)> {
    // Work in the frame where the incident side is up: incident direction w = −d with w.z > 0.
    let (w, eta, flip) = if d.z < 0.0 { (-d, eta, 1.0) } else { (d, 1.0 / eta, -1.0) };
    let u = rng.uniform();
    let (out, weight) = if mf.is_smooth() {
        let f = fresnel::dielectric(w.z, eta);
        if u < f {
            (DVec3::new(-w.x, -w.y, w.z), 1.0)
        } else {
            (refract(w, DVec3::Z, eta)?, 1.0)
        }
    } else {
        let m = mf.sample_visible(w, rng.uniform(), rng.uniform());
        let f = fresnel::dielectric(w.dot(m), eta);
        let out = if u < f { reflect(w, m) } else { refract(w, m, eta)? };
        if (u < f) != (out.z > 0.0) {
            return None; // reflected below or refracted above the macrosurface: lost by single scattering
        }
        (out, mf.g2(g2, w, out, m) / mf.g1(w, m))
    };
    Some((flip * out, weight))
}

/// Scatters a path arriving at the opaque base along `d` (d.z < 0): new direction (z > 0) and weight.
fn scatter_base(base: &Base, g2: G2Form, d: DVec3, rng: &mut Rng) -> Option<(DVec3, f64)> {
    let w = -d;
    match base {
        Base::Conductor { mf, eta, k } => {
            if mf.is_smooth() {
                return Some((DVec3::new(-w.x, -w.y, w.z), fresnel::conductor(w.z, *eta, *k)));
            }
            let m = mf.sample_visible(w, rng.uniform(), rng.uniform());
            let out = reflect(w, m);
            if out.z <= 0.0 {
                return None;
            }
            Some((out, fresnel::conductor(w.dot(m), *eta, *k) * mf.g2(g2, w, out, m) / mf.g1(w, m)))
        }
        Base::Diffuse { albedo, sigma } => {
            let out = cosine_hemisphere(rng.uniform(), rng.uniform());
            Some((out, albedo * PI * diffuse::oren_nayar_shape(*sigma, w, out)))
        }
    }
}

/// Scatters a path travelling along `d` at boundary `b` (interface b, or the base when b = number of interfaces).
fn scatter_boundary(s: &ChannelStack, b: usize, d: DVec3, rng: &mut Rng) -> Option<(DVec3, f64)> {
    match s.interfaces.get(b) {
        Some(it) => scatter_interface(&it.mf, s.g2, it.eta, d, rng),
        None => scatter_base(&s.base, s.g2, d, rng),
    }
}

/// Russian roulette once a path has had a few events and lost half its weight: survives with probability
/// max(weight, 0.05) and is reweighted (unbiased). Returns false when the path is terminated.
fn russian_roulette(weight: &mut f64, events: usize, rng: &mut Rng) -> bool {
    if events > 4 && *weight < 0.5 {
        let q = weight.max(0.05);
        if rng.uniform() >= q {
            return false;
        }
        *weight /= q;
    }
    true
}

/// Solid-angle density of refracting from `w` (incident side up, w.z > 0) into `o` (o.z < 0) through `mf` with
/// relative IOR `eta`, without the probability 1 − F of choosing refraction; and F (Walter et al. 2007 eq. 17).
fn refraction_pdf(mf: &Microfacet, eta: f64, w: DVec3, o: DVec3) -> (f64, f64) {
    let h = -(w + eta * o);
    if h.length_squared() == 0.0 {
        return (0.0, 1.0);
    }
    let h = h.normalize();
    let h = if h.z < 0.0 { -h } else { h };
    let (wh, oh) = (w.dot(h), o.dot(h));
    if wh <= 0.0 || oh >= 0.0 {
        return (0.0, 1.0);
    }
    let jacobian = eta * eta * oh.abs() / (wh + eta * oh).powi(2);
    (mf.pdf_visible(w, h) * jacobian, fresnel::dielectric(wh, eta))
}

/// Density with which the walk, arriving at boundary `b` from direction `w_in` (pointing away on its side), leaves
/// along `w_out` (the new travel direction); 0 for delta boundaries. The pdfs of `scatter_interface` and
/// `scatter_base`, used for multiple importance sampling.
fn boundary_pdf(s: &ChannelStack, b: usize, w_in: DVec3, w_out: DVec3) -> f64 {
    if let Some(it) = s.interfaces.get(b) {
        if it.mf.is_smooth() {
            return 0.0;
        }
        let (w, o, eta) = if w_in.z > 0.0 { (w_in, w_out, it.eta) } else { (-w_in, -w_out, 1.0 / it.eta) };
        if o.z > 0.0 {
            let h = (w + o).normalize();
            return it.mf.pdf_visible(w, h) * fresnel::dielectric(w.dot(h), eta) / (4.0 * w.dot(h).abs());
        }
        let (pdf, f) = refraction_pdf(&it.mf, eta, w, o);
        return pdf * (1.0 - f);
    }
    match &s.base {
        Base::Conductor { mf, .. } if mf.is_smooth() => 0.0,
        Base::Conductor { mf, .. } => {
            let h = (w_in + w_out).normalize();
            mf.pdf_visible(w_in, h) / (4.0 * w_in.dot(h).abs())
        }
        Base::Diffuse { .. } => w_out.z.max(0.0) * std::f64::consts::FRAC_1_PI,
    }
}

/// Light sampled through a rough top interface into slab 0 (strategy A of the MIS at rough tops): travel direction,
/// flux weight (1 − F) G2/G1 and the density of the direction.
#[derive(Clone, Copy, Debug)]
struct LightSample {
    d: DVec3,
    weight: f64,
    pdf: f64,
}

fn sample_light_through_top(s: &ChannelStack, wi: DVec3, rng: &mut Rng) -> Option<LightSample> {
    let top = s.interfaces.first().filter(|it| !it.mf.is_smooth())?;
    let m = top.mf.sample_visible(wi, rng.uniform(), rng.uniform());
    let d = refract(wi, m, top.eta).filter(|d| d.z < 0.0)?;
    let (pdf, f) = refraction_pdf(&top.mf, top.eta, wi, d);
    let weight = (1.0 - f) * top.mf.g2(s.g2, wi, d, m) / top.mf.g1(wi, m);
    (pdf > 0.0 && weight > 0.0).then_some(LightSample { d, weight, pdf })
}

/// Where the light subpath can be joined: its first non-delta boundary, or a scattering slab it crosses.
#[derive(Clone, Copy, Debug)]
pub enum Target {
    /// Light reaches boundary `b` along the direction w_light (pointing away from the boundary), carrying `weight`
    /// of the incident irradiance.
    Surface { b: usize, w_light: DVec3, weight: f64 },
    /// Light crosses scattering slab `slab` along `d` from depth `z0`, carrying `weight` at entry.
    Volume { slab: usize, d: DVec3, z0: f64, weight: f64 },
}

/// Samples the light subpath from wi through delta boundaries (reflect or refract with probability F), collecting
/// the scattering slabs it crosses and ending at its first non-delta boundary (or when it leaves the stack).
fn light_targets(s: &ChannelStack, wi: DVec3, rng: &mut Rng, out: &mut Vec<Target>) {
    out.clear();
    if !s.is_delta(0) {
        out.push(Target::Surface { b: 0, w_light: wi, weight: 1.0 });
        return;
    }
    let (mut d, mut b, mut weight) = (-wi, 0, 1.0);
    for _ in 0..MAX_DEPTH {
        let Some((dir, w)) = scatter_boundary(s, b, d, rng) else { return };
        d = dir;
        weight *= w;
        if d.z > 0.0 && b == 0 {
            return; // reflected out of the stack: part of the specular lobe, not of f
        }
        let slab = if d.z > 0.0 { b - 1 } else { b };
        let sl = &s.slabs[slab];
        let sigma_t = sl.sigma_a + sl.sigma_s;
        if sl.thickness > 0.0 && sl.sigma_s > 0.0 {
            out.push(Target::Volume { slab, d, z0: if d.z > 0.0 { sl.thickness } else { 0.0 }, weight });
        }
        if sl.thickness > 0.0 && sigma_t > 0.0 {
            weight *= (-sigma_t * sl.thickness / d.z.abs()).exp();
        }
        b = if d.z > 0.0 { slab } else { slab + 1 };
        if !s.is_delta(b) {
            out.push(Target::Surface { b, w_light: -d, weight });
            return;
        }
        if weight < 1e-3 {
            // Russian roulette on the subpath (it may be trapped by total internal reflection).
            if rng.uniform() >= 0.5 {
                return;
            }
            weight *= 2.0;
        }
    }
}

/// One sample of f(wi, wo) (wi.z, wo.z > 0; specular delta lobes excluded). Returns None if the camera walk was
/// truncated at MAX_DEPTH (counted by the caller).
///
/// With a rough top, paths whose light enters through the top are found by two strategies combined with the power
/// heuristic (as in pbrt-v4's LayeredBxDF): (A) a light direction sampled through the top from wi, joined at camera
/// vertices in slab 0; (B) the camera path reaching the top from below, joined by evaluating the top's BTDF at wi.
pub fn estimate_f(s: &ChannelStack, wi: DVec3, wo: DVec3, rng: &mut Rng, targets: &mut Vec<Target>) -> Option<f64> {
    light_targets(s, wi, rng, targets);
    let light = sample_light_through_top(s, wi, rng);
    let slab0_tr = |depth: f64, d: DVec3| {
        let sl = &s.slabs[0];
        if sl.thickness == 0.0 {
            1.0
        } else {
            (-(sl.sigma_a + sl.sigma_s) * depth / d.z.abs()).exp()
        }
    };
    let n = s.interfaces.len();
    let (mut d, mut b, mut beta, mut f) = (-wo, 0, 1.0, 0.0);
    let mut last_pdf: Option<f64> = None; // density of the direction sampled at the last non-delta vertex
    let mut events = 0;
    while events < MAX_DEPTH {
        events += 1;
        for t in targets.iter() {
            if let Target::Surface { b: tb, w_light, weight } = *t {
                if tb == b {
                    // Strategy B at the top from below, weighted against A's density for the same direction.
                    let mis = match (b == 0 && d.z > 0.0, light, last_pdf) {
                        (true, Some(_), Some(pb)) => {
                            let top = &s.interfaces[0];
                            power_heuristic(pb, refraction_pdf(&top.mf, top.eta, wi, -d).0)
                        }
                        _ => 1.0,
                    };
                    f += beta * weight * s.boundary_f(b, w_light, -d) * mis;
                }
            }
        }
        if let (Some(l), 1) = (light, b) {
            // Strategy A at boundary 1 (from above: reflection, from below: transmission).
            let fv = s.boundary_f(1, -l.d, -d);
            if fv > 0.0 {
                let pb = boundary_pdf(s, 1, -d, -l.d);
                f += beta * fv * l.weight * slab0_tr(s.slabs[0].thickness, l.d) * power_heuristic(l.pdf, pb);
            }
        }
        let Some((dir, w)) = scatter_boundary(s, b, d, rng) else { return Some(f) };
        last_pdf = if s.is_delta(b) { None } else { Some(boundary_pdf(s, b, -d, dir)) };
        if b < n && dir.z * d.z > 0.0 {
            // Radiance crossing into the other medium: L_here = (η_here / η_there)² L_there.
            let eta = s.interfaces[b].eta; // η_below / η_above
            beta *= if d.z < 0.0 { 1.0 / (eta * eta) } else { eta * eta };
        }
        d = dir;
        beta *= w;
        if d.z > 0.0 && b == 0 {
            return Some(f);
        }
        let slab = if d.z > 0.0 { b - 1 } else { b };
        let sl = &s.slabs[slab];
        let sigma_t = sl.sigma_a + sl.sigma_s;
        let z = if d.z > 0.0 { sl.thickness } else { 0.0 };
        let at_collision = |z: f64, d: DVec3, new_d: DVec3, beta: f64| {
            let albedo = sl.sigma_s / sigma_t;
            for t in targets.iter() {
                if let Target::Volume { slab: ts, d: dl, z0, weight } = *t {
                    if ts == slab {
                        let tr = (-sigma_t * (z - z0).abs() / dl.z.abs()).exp();
                        f += beta * albedo * henyey_greenstein(dl.dot(-d), sl.g) * weight * tr / dl.z.abs();
                    }
                }
            }
            if let (Some(l), 0) = (light, slab) {
                // Strategy A at a collision in slab 0.
                let p = henyey_greenstein(l.d.dot(-d), sl.g);
                let pb = henyey_greenstein(d.dot(-l.d), sl.g);
                f += beta * albedo * p * l.weight * slab0_tr(z, l.d) / l.d.z.abs() * power_heuristic(l.pdf, pb);
            }
            last_pdf = Some(henyey_greenstein(d.dot(new_d), sl.g));
        };
        let Some(dir) = traverse(sl, d, z, rng, &mut events, &mut beta, at_collision) else {
            return if events >= MAX_DEPTH { None } else { Some(f) };
        };
        d = dir;
        b = if d.z > 0.0 { slab } else { slab + 1 };
        if !russian_roulette(&mut beta, events, rng) {
            return Some(f);
        }
    }
    None
}

/// Sums of `samples` estimates of f(wi, wo) from paths `first..first + samples`: (sum, sum of squares, truncated).
/// Path i uses stream (seed mixed with wi and wo, i): reproducible whatever the thread count or batch, and
/// independent between direction pairs (so averages over directions have honest standard errors).
pub fn run_f(s: &ChannelStack, wi: DVec3, wo: DVec3, (first, samples): (u64, u64), seed: u64) -> (f64, f64, u64) {
    let tasks = samples.div_ceil(PATHS_PER_TASK as u64);
    let seed = Rng::seed_for(seed, &[wi.x, wi.y, wi.z, wo.x, wo.y, wo.z]);
    let end = first + samples;
    let parts: Vec<(f64, f64, u64)> = (0..tasks)
        .into_par_iter()
        .map(|task| {
            let mut targets = Vec::new();
            let mut acc = (0.0, 0.0, 0u64);
            for i in first + task * PATHS_PER_TASK as u64..(first + (task + 1) * PATHS_PER_TASK as u64).min(end) {
                let mut rng = Rng::new(seed, i);
                match estimate_f(s, wi, wo, &mut rng, &mut targets) {
                    Some(v) => {
                        acc.0 += v;
                        acc.1 += v * v;
                    }
                    None => acc.2 += 1,
                }
            }
            acc
        })
        .collect();
    parts.into_iter().fold((0.0, 0.0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2))
}

/// Moves a path through a slab from depth `z` (0 = top) along `d` until it reaches a boundary, multiplying `weight`
/// by the slab's attenuation and scattering albedos. At each scattering event `at_collision(z, d_in, d_out, weight)`
/// is called with the weight before that event's albedo. Returns the direction on arrival, or None when the path is
/// lost (horizontal) or truncated (told apart by `events` reaching MAX_DEPTH).
fn traverse(
    slab: &Slab,
    mut d: DVec3,
    mut z: f64,
    rng: &mut Rng,
    events: &mut usize,
    weight: &mut f64,
    mut at_collision: impl FnMut(f64, DVec3, DVec3, f64),
) -> Option<DVec3> {
    let sigma_t = slab.sigma_a + slab.sigma_s;
    if slab.thickness == 0.0 || sigma_t == 0.0 {
        return Some(d);
    }
    loop {
        if d.z.abs() < 1e-12 {
            return None; // a horizontal path never leaves an infinite slab
        }
        let to_boundary = if d.z < 0.0 { slab.thickness - z } else { z } / d.z.abs();
        if slab.sigma_s == 0.0 {
            *weight *= (-slab.sigma_a * to_boundary).exp(); // Beer–Lambert
            return Some(d);
        }
        let t = -(1.0 - rng.uniform()).ln() / sigma_t;
        if t >= to_boundary {
            return Some(d);
        }
        z -= t * d.z;
        let new_d = sample_henyey_greenstein(d, slab.g, rng.uniform(), rng.uniform());
        at_collision(z, d, new_d, *weight);
        *weight *= slab.sigma_s / sigma_t;
        d = new_d;
        *events += 1;
        if *events >= MAX_DEPTH {
            return None;
        }
    }
}

/// Traces one path of light arriving from `wi` (pointing away from the surface, wi.z > 0).
pub fn trace(s: &ChannelStack, wi: DVec3, rng: &mut Rng) -> Exit {
    let mut d = -wi;
    let mut weight = 1.0;
    let mut next = 0; // index of the boundary the path reaches next: interface i < n, or the base at n
    let mut events = 0;
    while events < MAX_DEPTH {
        events += 1;
        let Some((dir, w)) = scatter_boundary(s, next, d, rng) else { return Exit::Absorbed };
        d = dir;
        weight *= w;
        // Enter the slab above (going up) or below (going down) the boundary just left.
        let slab = if d.z > 0.0 {
            if next == 0 {
                return Exit::Escaped { dir: d, weight };
            }
            next - 1
        } else {
            next
        };
        let z = if d.z > 0.0 { s.slabs[slab].thickness } else { 0.0 };
        let Some(dir) = traverse(&s.slabs[slab], d, z, rng, &mut events, &mut weight, |_, _, _, _| {}) else {
            return if events >= MAX_DEPTH { Exit::Truncated } else { Exit::Absorbed };
        };
        d = dir;
        next = if d.z > 0.0 { slab } else { slab + 1 };
        if !russian_roulette(&mut weight, events, rng) {
            return Exit::Absorbed;
        }
    }
    Exit::Truncated
}

/// Sums over many paths: energy escaping (and its square) per bin, and truncated paths.
#[derive(Clone, Debug, Default)]
pub struct Tally {
    pub paths: u64,
    pub sum: Vec<f64>,
    pub sum_sq: Vec<f64>,
    pub truncated: u64,
}

impl Tally {
    fn new(bins: usize) -> Tally {
        Tally { paths: 0, sum: vec![0.0; bins], sum_sq: vec![0.0; bins], truncated: 0 }
    }

    fn merge(mut self, other: Tally) -> Tally {
        self.paths += other.paths;
        self.truncated += other.truncated;
        self.sum.iter_mut().zip(&other.sum).for_each(|(a, b)| *a += b);
        self.sum_sq.iter_mut().zip(&other.sum_sq).for_each(|(a, b)| *a += b);
        self
    }

    /// Mean energy per path in each bin and its standard error.
    pub fn mean_and_stderr(&self) -> Vec<(f64, f64)> {
        debug_assert!(self.paths > 0);
        let n = self.paths as f64;
        self.sum
            .iter()
            .zip(&self.sum_sq)
            .map(|(s, s2)| {
                let mean = s / n;
                (mean, ((s2 / n - mean * mean).max(0.0) / (n - 1.0).max(1.0)).sqrt())
            })
            .collect()
    }
}

/// Runs paths `first..first + samples` from `wi` and tallies escaping energy with `bin(dir)` (None: not counted).
/// Path i uses stream (seed mixed with wi, i); tasks are reduced in order, so the result does not depend on the
/// thread count, and different directions get independent streams.
pub fn run(
    s: &ChannelStack,
    wi: DVec3,
    (first, samples): (u64, u64),
    seed: u64,
    bins: usize,
    bin: impl Fn(DVec3) -> Option<usize> + Sync,
) -> Tally {
    let tasks = samples.div_ceil(PATHS_PER_TASK as u64);
    let end = first + samples;
    let seed = Rng::seed_for(seed, &wi.to_array());
    let tallies: Vec<Tally> = (0..tasks)
        .into_par_iter()
        .map(|b| {
            let mut t = Tally::new(bins);
            for i in first + b * PATHS_PER_TASK as u64..(first + (b + 1) * PATHS_PER_TASK as u64).min(end) {
                let mut rng = Rng::new(seed, i);
                t.paths += 1;
                match trace(s, wi, &mut rng) {
                    Exit::Escaped { dir, weight } => {
                        if let Some(k) = bin(dir) {
                            t.sum[k] += weight;
                            t.sum_sq[k] += weight * weight;
                        }
                    }
                    Exit::Truncated => t.truncated += 1,
                    Exit::Absorbed => {}
                }
            }
            t
        })
        .collect();
    tallies.into_iter().fold(Tally::new(bins), Tally::merge)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::common::testing::{dielectric as coat, stack};
    use crate::optics::distribution::Distribution;
    use crate::stack::{Layer, Stack};

    fn albedo(s: &Stack, theta: f64, n: u64) -> (f64, f64) {
        let cs = ChannelStack::new(s, 0, crate::models::reference_surface());
        let wi = DVec3::new(theta.sin(), 0.0, theta.cos());
        run(&cs, wi, (0, n), 1, 1, |_| Some(0)).mean_and_stderr()[0]
    }

    #[test]
    fn white_furnace_of_lossless_stacks() {
        // Smooth interfaces, non-absorbing (scattering) slabs, white Lambert: every path escapes with all its energy.
        let white = Layer::Diffuse { albedo: vec![1.0], roughness: 0.0 };
        for layers in [
            vec![coat(1.5, 0.0, 0.0, 0.0, 0.0), white.clone()],
            vec![coat(1.5, 0.0, 1.0, 0.0, 2.0), coat(1.2, 0.0, 0.5, 0.0, 1.0), white.clone()],
        ] {
            let (a, se) = albedo(&stack(layers), 0.7, 20_000);
            assert!((a - 1.0).abs() <= 3.0 * se + 1e-12, "{a} ± {se}");
        }
    }

    fn f_estimate(s: &Stack, wi: DVec3, wo: DVec3, n: u64) -> (f64, f64) {
        let cs = ChannelStack::new(s, 0, crate::models::reference_surface());
        let (sum, sum2, _) = run_f(&cs, wi, wo, (0, n), 5);
        let mean = sum / n as f64;
        (mean, ((sum2 / n as f64 - mean * mean) / (n as f64 - 1.0)).sqrt())
    }

    #[test]
    fn f_of_smooth_coat_over_lambert_equals_closed_form() {
        let s = stack(vec![coat(1.5, 0.0, 0.0, 0.0, 0.0), Layer::Diffuse { albedo: vec![0.8], roughness: 0.0 }]);
        let f_int = fresnel::diffuse_reflectance(1.0 / 1.5);
        for (wi, wo) in [(DVec3::new(0.3, 0.0, 0.95), DVec3::new(0.5, 0.5, 0.7)), (DVec3::new(0.9, 0.1, 0.2), DVec3::Z)]
        {
            let (wi, wo) = (wi.normalize(), wo.normalize());
            let exact = crate::models::microfacet::smooth_coat_lambert(0.8, 1.5, f_int, wi.z, wo.z);
            let (mean, se) = f_estimate(&s, wi, wo, 200_000);
            assert!((mean - exact).abs() <= 3.0 * se, "{mean} ± {se} vs {exact}");
        }
    }

    #[test]
    fn f_of_single_rough_interface_is_exact() {
        let s = stack(vec![Layer::Conductor { ior: vec![0.2], k: vec![3.0], alpha: (0.3, 0.3), angle: 0.0 }]);
        let (wi, wo) = (DVec3::new(0.3, 0.0, 0.95).normalize(), DVec3::new(-0.2, 0.1, 0.9).normalize());
        let mf = Microfacet::new(Distribution::Ggx, 0.3, 0.3, 0.0);
        let exact = crate::bsdf::rough_conductor(&mf, G2Form::HeightCorrelated, 0.2, 3.0, wi, wo);
        let (mean, se) = f_estimate(&s, wi, wo, 1000);
        // Zero variance: every path evaluates the base BRDF exactly (the SE is cancellation noise of sum² − mean²).
        assert!((mean - exact).abs() < 1e-12 * exact && se < 1e-6 * exact, "{mean} ± {se} vs {exact}");
    }

    #[test]
    fn results_do_not_depend_on_thread_count() {
        let s = stack(vec![coat(1.5, 0.3, 1.0, 0.2, 0.5), Layer::Diffuse { albedo: vec![0.8], roughness: 0.0 }]);
        let cs = ChannelStack::new(&s, 0, crate::models::reference_surface());
        let wi = DVec3::new(0.5, 0.0, 0.75f64.sqrt());
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let a = one.install(|| run(&cs, wi, (0, 10_000), 9, 1, |_| Some(0)));
        let b = run(&cs, wi, (0, 10_000), 9, 1, |_| Some(0));
        assert_eq!(a.sum, b.sum);
        assert_eq!(a.sum_sq, b.sum_sq);
    }
}
