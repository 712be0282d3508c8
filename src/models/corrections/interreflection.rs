//! lamina's inter-reflection corrections of the single-pass models (common/single_pass.rs), which, as published,
//! follow light once down and once up: `interreflection` sums the bounces between a diffuse base and the coat above
//! it in closed form, `conductor_interreflection` returns what a coat reflects back down onto a conductor base as a
//! reciprocal diffuse term of the right energy.

use crate::models::common::single_pass::{node_lerp, SpInterface, SpLayer, WalkOptions, INTERREFLECTION_NODES};
use crate::optics::distribution::G2Form;
use glam::DVec3;

/// The corrections that `opts` switch on, applied to a walk's layers.
pub fn correct(layers: &mut [SpLayer], opts: &WalkOptions) {
    if opts.interreflection {
        add_interreflection(layers);
    }
    if opts.conductor_interreflection {
        add_conductor_interreflection(layers);
    }
}

/// The inter-reflections between a diffuse base of albedo ρ and the coat above it, summed (lamina's correction):
/// light leaving the base diffusely returns with probability r (`coat_return`), so the base's light is multiplied by
/// Σ (ρ r)^k = 1/(1 − ρ r). For a smooth, clear coat this is the exact smooth-coat-over-Lambert result (e.g.
/// Mitsuba's `plastic`). Only the coat right above the base takes part; its roughness is ignored in r.
fn add_interreflection(layers: &mut [SpLayer]) {
    let n = layers.len();
    if n < 2 {
        return;
    }
    let (above, base) = layers.split_at_mut(n - 1);
    let (SpLayer::Dielectric { iface, thickness, sigma_t, .. }, SpLayer::Diffuse { albedo, gain, .. }) =
        (&above[n - 2], &mut base[0])
    else {
        return;
    };
    for (c, g) in gain.iter_mut().enumerate() {
        *g = 1.0 / (1.0 - albedo[c] * coat_return(iface.eta[c], sigma_t[c] * thickness));
    }
}

/// r = F̄(1/η) T̄²: the probability that diffuse light leaving a base comes back to it from the coat above, F̄ the
/// coat interface's hemispherical reflectance seen from inside (optics::fresnel::diffuse_reflectance) and T̄ its
/// slab's (`slab_transmittance`), crossed both ways.
fn coat_return(eta: f64, tau: f64) -> f64 {
    crate::optics::fresnel::diffuse_reflectance(1.0 / eta) * slab_transmittance(tau).powi(2)
}

/// T̄ = 2∫ e^{−τ/μ} μ dμ: the cosine-averaged transmittance of a slab of optical depth τ.
fn slab_transmittance(tau: f64) -> f64 {
    crate::quadrature::gauss_legendre(32)
        .iter()
        .map(|(x, w)| {
            let mu = 0.5 * (x + 1.0);
            0.5 * w * 2.0 * mu * if tau > 0.0 { (-tau / mu).exp() } else { 1.0 }
        })
        .sum()
}

/// The inter-reflections between a conductor base and the coat above it, summed (lamina's correction): of the light
/// the base reflects, the part K that the coat sends back down (Fresnel reflection inside it, total internal
/// reflection included) and its slab lets through, T̄², returns to the base, which a single pass leaves out. That light
/// is taken as diffuse from then on: the base reflects Ā of it (its hemispherical albedo) and (1 − F̄) T̄ of that
/// leaves, the coat returning r (`coat_return`), so X(μ) = A(μ) K(μ) T̄² Ā / (1 − Ā r) is what the base sends up
/// again for light arriving at cosine μ, and E = (1 − F̄) T̄ of it leaves. A reciprocal term carries exactly that
/// energy: f = T(μi) T(μo) / η² · g(μi′) g(μo′) / π with g = X √(E / Y), Y = 2∫ T(μo) X(μo′) μo dμo / η² (μo′ the
/// view refracted into a smooth coat), g tabulated per channel at INTERREFLECTION_NODES cosines. A and K are
/// single-scattering integrals over the base's visible normals (height-correlated Smith, four azimuths for an
/// anisotropic base).
fn add_conductor_interreflection(layers: &mut [SpLayer]) {
    let n = layers.len();
    if n < 2 {
        return;
    }
    let (above, base) = layers.split_at_mut(n - 1);
    let (SpLayer::Dielectric { iface: coat, thickness, sigma_t, .. }, SpLayer::Conductor { iface, diffuse }) =
        (&above[n - 2], &mut base[0])
    else {
        return;
    };
    let (iface, nodes): (&SpInterface, _) = (iface, crate::quadrature::gauss_legendre(16));
    let eta_up: Vec<f64> = coat.eta.iter().map(|e| 1.0 / e).collect();
    // Ā = ∫ A(μ) 2μ dμ per channel, and A K per channel at the table's nodes.
    let mut albedos = vec![0.0; eta_up.len()];
    for (x, w) in &nodes {
        let mu = 0.5 * (x + 1.0);
        for (albedo, (a, _)) in albedos.iter_mut().zip(base_reflection(iface, mu, &eta_up)) {
            *albedo += w * mu * a;
        }
    }
    let at_nodes: Vec<Vec<(f64, f64)>> = (0..INTERREFLECTION_NODES)
        .map(|j| base_reflection(iface, (j as f64 / (INTERREFLECTION_NODES - 1) as f64).max(1e-3), &eta_up))
        .collect();
    let mut table = Vec::with_capacity(iface.eta.len() * INTERREFLECTION_NODES);
    for (c, (eta, sigma_t)) in coat.eta.iter().zip(sigma_t).enumerate() {
        let eta = *eta;
        let albedo = albedos[c];
        let tau = sigma_t * thickness;
        let t_mean = slab_transmittance(tau);
        let series = t_mean * t_mean * albedo / (1.0 - albedo * coat_return(eta, tau));
        let x: Vec<f64> = at_nodes.iter().map(|r| r[c].1 * series).collect();
        let y: f64 = nodes
            .iter()
            .map(|(x_, w)| {
                let mu = 0.5 * (x_ + 1.0);
                let inside = (1.0 - (1.0 - mu * mu) / (eta * eta)).max(0.0).sqrt();
                w * mu * crate::optics::fresnel::dielectric_transmittance(mu, eta) * node_lerp(&x, inside)
            })
            .sum::<f64>()
            / (eta * eta);
        let escape = (1.0 - crate::optics::fresnel::diffuse_reflectance(1.0 / eta)) * t_mean;
        let scale = if y > 0.0 { (escape / y).sqrt() } else { 0.0 };
        table.extend(x.iter().map(|v| v * scale));
    }
    *diffuse = table;
}

/// (A, A K) per channel: the single-scattering albedo of a conductor interface lit at cosine `mu`, and the part of it
/// that a dielectric above of relative IOR `eta_up[c]` (above / below) reflects back down, averaged over four
/// azimuths. The visible normals and their masking are shared by every channel.
fn base_reflection(iface: &SpInterface, mu: f64, eta_up: &[f64]) -> Vec<(f64, f64)> {
    let mut out = vec![(0.0, 0.0); eta_up.len()];
    let count = 4 * 64;
    for k in 0..4 {
        let phi = std::f64::consts::FRAC_PI_4 * k as f64;
        let s = (1.0 - mu * mu).max(0.0).sqrt();
        let v = DVec3::new(s * phi.cos(), s * phi.sin(), mu.max(1e-6));
        for m in crate::tables::visible_normals(&iface.mf, v, 64) {
            let w = crate::optics::reflect(v, m);
            if w.z <= 0.0 {
                continue;
            }
            let g = iface.mf.g2(G2Form::HeightCorrelated, v, w, m) / iface.mf.g1(v, m);
            for (c, (a, ak)) in out.iter_mut().enumerate() {
                let f = crate::optics::fresnel::conductor(v.dot(m), iface.eta[c], iface.kappa[c]) * g;
                *a += f;
                *ak += f * crate::optics::fresnel::dielectric(w.z, eta_up[c]);
            }
        }
    }
    out.iter().map(|(a, ak)| (a / count as f64, ak / count as f64)).collect()
}

#[cfg(test)]
mod tests {
    use crate::models::common::testing::{args, conductor, dielectric, dir, f, hemisphere, stack};
    use crate::models::{weidlich_wilkie, Value};
    use crate::optics::fresnel;

    #[test]
    fn a_coated_mirror_metal_returns_what_its_coat_traps_and_no_more() {
        // A clear smooth coat over a rough conductor of κ → ∞ (F = 1, no absorption): all light leaves in the end,
        // so the light albedo (f's quadrature plus the coat's mirror reflection) is 1 less only the base's
        // single-scattering loss. The single pass leaves out what the coat sends back down; the correction returns it
        // (reciprocally) and stays within energy. Measured (θi 0, 40, 70°): 0.754 → 0.966, 0.624 → 0.956,
        // 0.554 → 0.937.
        let s = stack(vec![dielectric(1.5, 0.0, 0.0, 0.0, 0.0), conductor(1.0, 1e6, (0.3, 0.3))]);
        let model = |on: bool| {
            let opts = args(&weidlich_wilkie::INFO, &[("conductor_interreflection", Value::Flag(on))]);
            weidlich_wilkie::prepare(&s, &weidlich_wilkie::Options::parse(&opts, 1).unwrap()).unwrap()
        };
        let (published, corrected) = (model(false), model(true));
        for theta in [0.0, 40.0, 70.0] {
            let wi = dir(theta, 0.0);
            let albedo = |m: &dyn crate::models::Model| {
                hemisphere(128, 256, |wo| f(m, wi, wo, 1)[0]) + fresnel::dielectric(wi.z, 1.5)
            };
            let (a, b) = (albedo(&published), albedo(&corrected));
            assert!(a < b && b <= 1.0, "θi = {theta}°: {a} → {b}");
            let (x, y) = (dir(theta, 0.0), dir(55.0, 160.0));
            let (fxy, fyx) = (
                f(&corrected, x, y, 1)[0] - f(&published, x, y, 1)[0],
                f(&corrected, y, x, 1)[0] - f(&published, y, x, 1)[0],
            );
            assert!((fxy - fyx).abs() <= 1e-12 * fxy.abs(), "the added term is reciprocal: {fxy} vs {fyx}");
        }
    }
}
