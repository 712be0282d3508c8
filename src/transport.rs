//! The physics of a stack as light transport sees it, one channel at a time: each interface's relative IOR and
//! microfacets, each slab's coefficients, the opaque base, and the BSDF of every boundary. The Monte Carlo reference
//! (reference.rs) samples these boundaries and slabs; the adding-doubling solver (tables/adding_doubling.rs) projects
//! them onto its grid. Both read them from here, so that they solve the same transport.

use crate::dual::Real;
use crate::optics::distribution::{Distribution, G2Form, Microfacet};
use crate::optics::{diffuse, fresnel};
use crate::stack::{Field, Layer, Stack};
use glam::DVec3;

/// The microsurface of every rough boundary: its distribution and masking-shadowing (the reference's options, which
/// `model="tabulated"` shares; models::reference_surface is their defaults).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Microsurface {
    pub distribution: Distribution,
    pub g2: G2Form,
}

/// One interface as a path sees it: roughness and the relative IOR η_below / η_above (f64, or Duals).
#[derive(Clone, Copy, PartialEq)]
pub struct Interface<T = f64> {
    pub mf: Microfacet<T>,
    pub eta: T,
}

/// The medium below an interface: thickness and coefficients (f64, or Duals: `ChannelStack::with_values`).
pub struct Slab<T = f64> {
    pub thickness: T,
    pub sigma_a: T,
    pub sigma_s: T,
    pub g: T,
}

/// The opaque base (f64, or Duals).
pub enum Base<T = f64> {
    Conductor { mf: Microfacet<T>, eta: T, k: T },
    Diffuse { albedo: T, sigma: T },
}

/// The stack resolved for one channel: interface i is the top of slab i; the base lies below the last slab. Boundary
/// b is interface b, or the base when b equals the number of interfaces. Its numbers are f64, or Duals carrying
/// parameter derivatives.
pub struct ChannelStack<T = f64> {
    pub interfaces: Vec<Interface<T>>,
    pub slabs: Vec<Slab<T>>,
    pub base: Base<T>,
    pub g2: G2Form,
}

impl ChannelStack {
    pub fn new(stack: &Stack, channel: usize, surface: Microsurface) -> ChannelStack {
        ChannelStack::with_values(stack, channel, surface, |_, _, v| v)
    }
}

impl<T: Real> ChannelStack<T> {
    /// Channel `channel` of `stack` with each number v of layer i's field taken as `value(i, field, v)`: f64, or a
    /// Dual seeded by a gradient's parameters (models::seeded).
    pub fn with_values(
        stack: &Stack,
        channel: usize,
        surface: Microsurface,
        value: impl Fn(usize, Field, f64) -> T,
    ) -> ChannelStack<T> {
        let (mut interfaces, mut slabs) = (Vec::new(), Vec::new());
        let g2 = surface.g2;
        for (i, (layer, rel)) in stack.layers.iter().zip(stack.interfaces()).enumerate() {
            let microfacet = |alpha: &(f64, f64), angle: f64| {
                let (ax, ay) = (value(i, Field::RoughnessX, alpha.0), value(i, Field::RoughnessY, alpha.1));
                Microfacet::<T>::with_parameters(surface.distribution, ax, ay, value(i, Field::Angle, angle))
            };
            match layer {
                Layer::Dielectric { alpha, angle, thickness, sigma_a, sigma_s, g, .. } => {
                    let mf = microfacet(alpha, *angle);
                    interfaces.push(Interface { mf, eta: value(i, Field::Ior, rel.eta[channel]) });
                    slabs.push(Slab {
                        thickness: value(i, Field::Thickness, *thickness),
                        sigma_a: value(i, Field::SigmaA, sigma_a[channel]),
                        sigma_s: value(i, Field::SigmaS, sigma_s[channel]),
                        g: value(i, Field::G, *g),
                    });
                }
                Layer::Conductor { alpha, angle, .. } => {
                    let mf = microfacet(alpha, *angle);
                    let (eta, k) = (value(i, Field::Ior, rel.eta[channel]), value(i, Field::K, rel.kappa[channel]));
                    return ChannelStack { interfaces, slabs, base: Base::Conductor { mf, eta, k }, g2 };
                }
                Layer::Diffuse { albedo, roughness } => {
                    let albedo = value(i, Field::Albedo, albedo[channel]);
                    let sigma = value(i, Field::DiffuseRoughness, *roughness);
                    return ChannelStack { interfaces, slabs, base: Base::Diffuse { albedo, sigma }, g2 };
                }
            }
        }
        unreachable!("validated stacks end in an opaque base")
    }

    /// BSDF value f(w_light, w_view) of boundary `b`: light arrives along w_light and leaves along w_view, both
    /// pointing away from the boundary (Walter et al. 2007 for rough interfaces, Oren–Nayar 1994 for the base).
    pub fn boundary_f(&self, b: usize, w_light: DVec3, w_view: DVec3) -> T {
        if let Some(it) = self.interfaces.get(b) {
            return crate::bsdf::rough_dielectric(&it.mf, self.g2, it.eta, w_light, w_view);
        }
        match &self.base {
            Base::Conductor { mf, eta, k } => crate::bsdf::rough_conductor(mf, self.g2, *eta, *k, w_light, w_view),
            Base::Diffuse { albedo, sigma } => *albedo * diffuse::oren_nayar_shape(*sigma, w_light, w_view),
        }
    }

    /// Boundary b's own numbers, all that its BSDF reads: an interface's IOR and microfacets; the base's IOR, κ and
    /// microfacets, or its albedo and σ.
    pub fn boundary_numbers(&self, b: usize) -> Vec<T> {
        match (self.interfaces.get(b), &self.base) {
            (Some(it), _) => [&[it.eta][..], &it.mf.numbers()].concat(),
            (None, Base::Conductor { mf, eta, k }) => [&[*eta, *k][..], &mf.numbers()].concat(),
            (None, Base::Diffuse { albedo, sigma }) => vec![*albedo, *sigma],
        }
    }

    /// The stack with every number as `x` maps it (to another kind of Real).
    pub fn map<R: Real>(&self, x: impl Fn(T) -> R) -> ChannelStack<R> {
        let slab =
            |s: &Slab<T>| Slab { thickness: x(s.thickness), sigma_a: x(s.sigma_a), sigma_s: x(s.sigma_s), g: x(s.g) };
        ChannelStack {
            interfaces: self.interfaces.iter().map(|it| Interface { mf: it.mf.map(&x), eta: x(it.eta) }).collect(),
            slabs: self.slabs.iter().map(slab).collect(),
            base: match &self.base {
                Base::Conductor { mf, eta, k } => Base::Conductor { mf: mf.map(&x), eta: x(*eta), k: x(*k) },
                Base::Diffuse { albedo, sigma } => Base::Diffuse { albedo: x(*albedo), sigma: x(*sigma) },
            },
            g2: self.g2,
        }
    }

    /// True when boundary `b` scatters through Dirac deltas only (a smooth interface or a smooth conductor).
    pub fn is_delta(&self, b: usize) -> bool {
        match self.interfaces.get(b) {
            Some(it) => it.mf.is_smooth(),
            None => matches!(&self.base, Base::Conductor { mf, .. } if mf.is_smooth()),
        }
    }
}

impl ChannelStack {
    /// The Dirac part of the reflection of boundaries b, b + 1, … for light arriving at zenith cosine `mu` above
    /// boundary b: the paths that meet only smooth boundaries and cross the slabs unscattered. Interface b over what
    /// lies below it (R, seen at the refracted cosine μt, attenuated there and back by e^{−2τ/μt}, Beer–Lambert) sums
    /// its inter-reflections, R' = F + (1 − F)² R / (1 − F R) (F is the same from either side); a rough boundary or
    /// a diffuse base returns none.
    pub fn dirac_reflectance(&self, b: usize, mu: f64) -> f64 {
        let Some(it) = self.interfaces.get(b) else {
            return match &self.base {
                Base::Conductor { mf, eta, k } if mf.is_smooth() => fresnel::conductor(mu, *eta, *k),
                _ => 0.0,
            };
        };
        if !it.mf.is_smooth() {
            return 0.0;
        }
        let f = fresnel::dielectric(mu, it.eta);
        let sin2_t = (1.0 - mu * mu) / (it.eta * it.eta);
        if sin2_t >= 1.0 {
            return f; // total internal reflection
        }
        let mu_t = (1.0 - sin2_t).sqrt();
        let sl = &self.slabs[b];
        let tau = (sl.sigma_a + sl.sigma_s) * sl.thickness;
        let below = if tau > 0.0 { (-2.0 * tau / mu_t).exp() } else { 1.0 } * self.dirac_reflectance(b + 1, mu_t);
        f + (1.0 - f) * (1.0 - f) * below / (1.0 - f * below)
    }
}
