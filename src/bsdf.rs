//! BSDFs of a single rough interface built from the optics primitives: microfacet reflection (conductor or
//! dielectric) and rough dielectric transmission (Walter et al. 2007), from either side. All return f without
//! the cosine; directions point away from the surface (docs/conventions.md).

use crate::dual::{dir, dot, normalize, plus, value, Dir, Real, With};
use crate::optics::distribution::{G2Form, Microfacet};
use crate::optics::fresnel;
use glam::DVec3;

/// Microfacet reflection without the Fresnel factor: D(h) G2 / (4 |cos θi| |cos θo|) and the cosine wi·h that
/// the Fresnel factor takes (Cook–Torrance 1982; Walter et al. 2007 eq. 20). Same-side directions only. The
/// directions are f64, or Duals where a parameter moves them (a single-pass walk's refracted directions).
#[inline(always)]
pub fn reflection_geometry<T, C>(
    mf: &Microfacet<T>,
    form: G2Form,
    wi: impl Into<Dir<C>>,
    wo: impl Into<Dir<C>>,
) -> Option<(T, C)>
where
    C: Real,
    T: With<C> + From<C>,
{
    let (wi, wo) = (wi.into(), wo.into());
    // Computed first and selected last (no early return), so that loops over it vectorize.
    let h = normalize(plus(wi, wo));
    let h = if h[2].value() < 0.0 { h.map(|x| -x) } else { h };
    let g = mf.g2_at(form, wi, wo, h);
    let geo = mf.d(h) * g / ((wi[2] * wo[2]).abs() * 4.0);
    ((wi[2] * wo[2]).value() > 0.0 && !mf.is_smooth() && g.value() != 0.0).then_some((geo, dot(wi, h)))
}

/// Rough conductor BRDF F(wi·h) D G2 / (4 cos θi cos θo) with the exact conductor Fresnel of η + iκ.
pub fn rough_conductor<T: Real>(mf: &Microfacet<T>, form: G2Form, eta: T, k: T, wi: DVec3, wo: DVec3) -> T {
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return T::from(0.0);
    }
    reflection_geometry(mf, form, wi, wo).map_or(T::from(0.0), |(geo, cos_h)| geo * fresnel::conductor(cos_h, eta, k))
}

/// Rough dielectric BSDF (Walter et al. 2007 eqs. 20–21) for radiance: reflection when wi and wo lie on the
/// same side, transmission otherwise. `eta` = η_below / η_above; light arrives along wi and leaves along wo. The
/// roughness and the IOR are f64 or Duals (the transmission's half vector moves with the IOR).
pub fn rough_dielectric<T: Real>(mf: &Microfacet<T>, form: G2Form, eta: T, wi: DVec3, wo: DVec3) -> T {
    let zero = T::from(0.0);
    if wi.z == 0.0 || wo.z == 0.0 || mf.is_smooth() {
        return zero;
    }
    if wi.z * wo.z > 0.0 {
        return reflection_geometry(mf, form, wi, wo)
            .map_or(zero, |(geo, cos_h)| geo * fresnel::dielectric(cos_h, eta));
    }
    let (eta_i, eta_o) = if wi.z > 0.0 { (T::from(1.0), eta) } else { (eta, T::from(1.0)) };
    let h = [-(eta_i * wi.x + eta_o * wo.x), -(eta_i * wi.y + eta_o * wo.y), -(eta_i * wi.z + eta_o * wo.z)];
    if dot(h, h).value() == 0.0 {
        return zero;
    }
    let h = normalize(h);
    let h = if h[2].value() < 0.0 { h.map(|x| -x) } else { h };
    let (ih, oh) = (dot(dir(wi), h), dot(dir(wo), h));
    let g = mf.g2(form, wi, wo, value(h));
    if g.value() == 0.0 {
        return zero;
    }
    let denom = eta_i * ih + eta_o * oh;
    let t = T::from(1.0) - fresnel::dielectric(ih, eta);
    (ih * oh).abs() / (wi.z * wo.z).abs() * eta_o * eta_o * t * mf.d(h) * g / (denom * denom)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optics::distribution::Distribution;

    fn dir(theta: f64, phi: f64) -> DVec3 {
        DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
    }

    #[test]
    fn transmission_obeys_generalised_reciprocity() {
        // f_t(wi, wo) / η_o² = f_t(wo, wi) / η_i² (Walter et al. 2007 §5.2; Veach 1997 §5.2).
        let mf = Microfacet::new(Distribution::Ggx, 0.3, 0.5, 0.2);
        let (wi, wo) = (dir(0.5, 0.3), -dir(0.4, 2.5));
        let eta = 1.5;
        let a = rough_dielectric(&mf, G2Form::HeightCorrelated, eta, wi, wo);
        let b = rough_dielectric(&mf, G2Form::HeightCorrelated, eta, wo, wi);
        assert!(a > 0.0);
        assert!((a / (eta * eta) - b).abs() < 1e-12 * a, "{a} {b}");
    }

    #[test]
    fn reflection_is_reciprocal_on_both_sides() {
        let mf = Microfacet::new(Distribution::Beckmann, 0.2, 0.4, 1.0);
        for s in [1.0, -1.0] {
            let (wi, wo) = (s * dir(0.3, 0.1), s * dir(1.2, 2.0));
            let a = rough_dielectric(&mf, G2Form::Separable, 1.33, wi, wo);
            let b = rough_dielectric(&mf, G2Form::Separable, 1.33, wo, wi);
            assert!(a > 0.0 && (a - b).abs() < 1e-12 * a);
        }
    }
}
