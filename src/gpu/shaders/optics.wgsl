// Optics primitives on the GPU, in float32: each function mirrors the Rust function of the same name in src/optics
// (fresnel.rs, distribution.rs, diffuse.rs, mod.rs) and src/bsdf.rs, and tests/test_gpu.py holds them together.
// Conventions: docs/conventions.md (local frame, z = normal, directions pointing away from the surface).

const PI: f32 = 3.14159265358979;
const FRAC_1_PI: f32 = 0.318309886183791;

// optics::to_tangent_frame: a local direction in a layer's tangent frame rotated by angle (cos, sin).
fn to_tangent_frame(w: vec3<f32>, cos_phi: f32, sin_phi: f32) -> vec3<f32> {
    return vec3<f32>(cos_phi * w.x + sin_phi * w.y, -sin_phi * w.x + cos_phi * w.y, w.z);
}

// fresnel::refraction_cosines: (|cos_i| ≤ 1, the relative IOR seen from the incident side, cos_t); cos_t < 0
// marks total internal reflection (Rust: None).
fn refraction_cosines(cos_in: f32, eta_in: f32) -> vec3<f32> {
    var cos_i = cos_in;
    var eta = eta_in;
    if cos_i < 0.0 {
        cos_i = -cos_i;
        eta = 1.0 / eta;
    }
    cos_i = min(cos_i, 1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return vec3<f32>(cos_i, eta, -1.0);
    }
    return vec3<f32>(cos_i, eta, sqrt(1.0 - sin2_t));
}

// fresnel::dielectric: exact unpolarized dielectric Fresnel reflectance (Born & Wolf §1.5); 1 under TIR.
fn fresnel_dielectric(cos_in: f32, eta_in: f32) -> f32 {
    let r = refraction_cosines(cos_in, eta_in);
    if r.z < 0.0 {
        return 1.0;
    }
    let cos_i = r.x;
    let eta = r.y;
    let cos_t = r.z;
    let r_s = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let r_p = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    return 0.5 * (r_s * r_s + r_p * r_p);
}

// fresnel::dielectric_transmittance: 1 − F without cancellation near grazing incidence; 0 under TIR.
fn fresnel_dielectric_transmittance(cos_in: f32, eta_in: f32) -> f32 {
    let r = refraction_cosines(cos_in, eta_in);
    if r.z < 0.0 {
        return 0.0;
    }
    let cos_i = r.x;
    let eta = r.y;
    let cos_t = r.z;
    let s = cos_i + eta * cos_t;
    let p = eta * cos_i + cos_t;
    return 2.0 * eta * cos_i * cos_t * (1.0 / (s * s) + 1.0 / (p * p));
}

// fresnel::conductor: exact unpolarized conductor Fresnel reflectance of eta + ik (Born & Wolf §14.2).
fn fresnel_conductor(cos_in: f32, eta: f32, k: f32) -> f32 {
    let cos_i = clamp(cos_in, 0.0, 1.0);
    let cos2 = cos_i * cos_i;
    let sin2 = 1.0 - cos2;
    let t0 = eta * eta - k * k - sin2;
    let a2b2 = sqrt(t0 * t0 + 4.0 * eta * eta * k * k);
    var a2 = 0.5 * (a2b2 + t0);
    if t0 < 0.0 {
        a2 = 2.0 * eta * eta * k * k / (a2b2 - t0); // the same a² without the cancellation (fresnel::conductor)
    }
    let a = sqrt(a2);
    let den_s = a2b2 + 2.0 * a * cos_i + cos2;
    var r_s = 1.0;
    if den_s > 0.0 {
        r_s = max((a2b2 - 2.0 * a * cos_i + cos2) / den_s, 0.0);
    }
    let num = cos2 * a2b2 - 2.0 * a * cos_i * sin2 + sin2 * sin2;
    let den = cos2 * a2b2 + 2.0 * a * cos_i * sin2 + sin2 * sin2;
    var r_p = r_s;
    if den > 0.0 {
        r_p = max(r_s * num / den, 0.0);
    }
    return 0.5 * (r_s + r_p);
}

// fresnel::f0: reflectance at normal incidence of eta + ik.
fn fresnel_f0(eta: f32, k: f32) -> f32 {
    return ((eta - 1.0) * (eta - 1.0) + k * k) / ((eta + 1.0) * (eta + 1.0) + k * k);
}

// fresnel::schlick: Schlick 1994, F0 + (1 − F0)(1 − cos θ)^5.
fn fresnel_schlick(cos_i: f32, f0: f32) -> f32 {
    let m = 1.0 - clamp(cos_i, 0.0, 1.0);
    return f0 + (1.0 - f0) * m * m * m * m * m;
}

// fresnel::lazanyi: Lazányi & Szirmay-Kalos 2005, at most 1.
fn fresnel_lazanyi(cos_i: f32, eta: f32, k: f32) -> f32 {
    let c = 1.0 - clamp(cos_i, 0.0, 1.0);
    let m = c * c * c * c * c;
    return min(((eta - 1.0) * (eta - 1.0) + 4.0 * eta * m + k * k) / ((eta + 1.0) * (eta + 1.0) + k * k), 1.0);
}

// fresnel::one_minus_pow5: 1 − (1 − cos θ)^5 without cancellation near grazing incidence.
fn one_minus_pow5(cos_i: f32) -> f32 {
    let c = clamp(cos_i, 0.0, 1.0);
    let x = 1.0 - c;
    return c * (1.0 + x * (1.0 + x * (1.0 + x * (1.0 + x))));
}

// fresnel::schlick_transmittance: (1 − F0)(1 − (1 − cos θ)^5).
fn fresnel_schlick_transmittance(cos_i: f32, f0: f32) -> f32 {
    return (1.0 - f0) * one_minus_pow5(cos_i);
}

// fresnel::lazanyi_transmittance: 4η(1 − (1 − cos θ)^5) / [(η+1)² + κ²], at least 0.
fn fresnel_lazanyi_transmittance(cos_i: f32, eta: f32, k: f32) -> f32 {
    return max(4.0 * eta * one_minus_pow5(cos_i) / ((eta + 1.0) * (eta + 1.0) + k * k), 0.0);
}

// FresnelForm::conductor: form 0 exact, 1 Schlick, 2 Lazányi.
fn fresnel_form_conductor(form: u32, cos_i: f32, eta: f32, k: f32) -> f32 {
    switch form {
        case 1u: { return fresnel_schlick(cos_i, fresnel_f0(eta, k)); }
        case 2u: { return fresnel_lazanyi(cos_i, eta, k); }
        default: { return fresnel_conductor(cos_i, eta, k); }
    }
}

// FresnelForm::dielectric: the exact form, or the conductor form's approximation with κ = 0 where η ≥ 1.
fn fresnel_form_dielectric(form: u32, cos_i: f32, eta: f32) -> f32 {
    if form == 0u || eta < 1.0 {
        return fresnel_dielectric(cos_i, eta);
    }
    return fresnel_form_conductor(form, cos_i, eta, 0.0);
}

// FresnelForm::dielectric_transmittance: 1 − fresnel_form_dielectric without cancellation at grazing incidence.
fn fresnel_form_dielectric_transmittance(form: u32, cos_i: f32, eta: f32) -> f32 {
    if form == 0u || eta < 1.0 {
        return fresnel_dielectric_transmittance(cos_i, eta);
    }
    if form == 1u {
        return fresnel_schlick_transmittance(cos_i, fresnel_f0(eta, 0.0));
    }
    return fresnel_lazanyi_transmittance(cos_i, eta, 0.0);
}

// Microfacet: distribution (0 GGX, 1 Beckmann), roughness along the tangent frame rotated by (cos_phi, sin_phi);
// smooth = 1 for a Dirac interface (roughness (0, 0)). The roughnesses are already clamped to MIN_ALPHA.
struct Microfacet {
    dist: u32,
    smooth_: u32,
    alpha_x: f32,
    alpha_y: f32,
    cos_phi: f32,
    sin_phi: f32,
}

const MIN_ALPHA: f32 = 1e-4;  // distribution::MIN_ALPHA

// Microfacet::with_alpha: the same distribution and frame at roughness (αx, αy), a Dirac interface at (0, 0).
fn mf_with_alpha(mf: Microfacet, alpha_x: f32, alpha_y: f32) -> Microfacet {
    let smooth_ = u32(alpha_x == 0.0 && alpha_y == 0.0);
    return Microfacet(mf.dist, smooth_, max(alpha_x, MIN_ALPHA), max(alpha_y, MIN_ALPHA), mf.cos_phi, mf.sin_phi);
}

// sampling::orthonormal_basis: two tangents completing the unit normal n (Duff et al. 2017).
fn orthonormal_basis(n: vec3<f32>) -> array<vec3<f32>, 2> {
    let sign = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    return array<vec3<f32>, 2>(
        vec3<f32>(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        vec3<f32>(b, sign + n.y * n.y * a, -n.y),
    );
}

// libm's erf as Abramowitz & Stegun 7.1.26 (|error| < 1.5e-7), for Beckmann's Λ.
fn erf(x: f32) -> f32 {
    let t = 1.0 / (1.0 + 0.3275911 * abs(x));
    let y = 1.0 - (((((1.061405429 * t - 1.453152027) * t) + 1.421413741) * t - 0.284496736) * t + 0.254829592) * t * exp(-x * x);
    return select(-y, y, x >= 0.0);
}

// Microfacet::d: Walter et al. 2007 eq. 33 (GGX) and eq. 25 (Beckmann), anisotropic (Heitz 2014 eq. 85/86).
fn mf_d(mf: Microfacet, m_in: vec3<f32>) -> f32 {
    let m = to_tangent_frame(m_in, mf.cos_phi, mf.sin_phi);
    if m.z <= 0.0 {
        return 0.0;
    }
    let x = m.x / mf.alpha_x;
    let y = m.y / mf.alpha_y;
    let z2 = m.z * m.z;
    if mf.dist == 0u {
        let s = x * x + y * y + z2;
        return 1.0 / (PI * mf.alpha_x * mf.alpha_y * s * s);
    }
    return exp(-(x * x + y * y) / z2) / (PI * mf.alpha_x * mf.alpha_y * z2 * z2);
}

// Microfacet::projected_alpha: α(φ) along the azimuth of w in the tangent frame (Heitz 2014 eq. 80); αx along the
// normal.
fn mf_projected_alpha(mf: Microfacet, w_in: vec3<f32>) -> f32 {
    let w = to_tangent_frame(w_in, mf.cos_phi, mf.sin_phi);
    let r2 = w.x * w.x + w.y * w.y;
    if r2 == 0.0 {
        return mf.alpha_x;
    }
    let ax = w.x * mf.alpha_x;
    let ay = w.y * mf.alpha_y;
    return sqrt((ax * ax + ay * ay) / r2);
}

// Microfacet::lambda: Smith Λ (Heitz 2014 eq. 72 GGX, eq. 69 Beckmann) with the projected roughness.
fn mf_lambda(mf: Microfacet, w_in: vec3<f32>) -> f32 {
    let w = to_tangent_frame(w_in, mf.cos_phi, mf.sin_phi);
    let ax = w.x * mf.alpha_x;
    let ay = w.y * mf.alpha_y;
    let alpha_tan2 = (ax * ax + ay * ay) / (w.z * w.z);
    if mf.dist == 0u {
        return 0.5 * (sqrt(1.0 + alpha_tan2) - 1.0);
    }
    let a = 1.0 / sqrt(alpha_tan2);
    return 0.5 * (erf(a) - 1.0) + exp(-a * a) / (2.0 * a * sqrt(PI));
}

// Microfacet::g1: Smith masking (Heitz 2014 eq. 43).
fn mf_g1(mf: Microfacet, w: vec3<f32>, m: vec3<f32>) -> f32 {
    if dot(w, m) * w.z <= 0.0 {
        return 0.0;
    }
    return 1.0 / (1.0 + mf_lambda(mf, w));
}

// Microfacet::g2_separable: G1(wi) G1(wo) (Heitz 2014 eq. 98).
fn mf_g2_separable(mf: Microfacet, wi: vec3<f32>, wo: vec3<f32>, m: vec3<f32>) -> f32 {
    return mf_g1(mf, wi, m) * mf_g1(mf, wo, m);
}

// Microfacet::g2_height_correlated: 1 / (1 + Λ(wi) + Λ(wo)) (Heitz 2014 eq. 99).
fn mf_g2_height_correlated(mf: Microfacet, wi: vec3<f32>, wo: vec3<f32>, m: vec3<f32>) -> f32 {
    if dot(wi, m) * wi.z <= 0.0 || dot(wo, m) * wo.z <= 0.0 {
        return 0.0;
    }
    return 1.0 / (1.0 + mf_lambda(mf, wi) + mf_lambda(mf, wo));
}

// distribution::v_cavity: Torrance–Sparrow 1967 / Cook–Torrance 1982 V-cavity masking-shadowing.
fn v_cavity(wi: vec3<f32>, wo: vec3<f32>, m: vec3<f32>) -> f32 {
    let im = dot(wi, m);
    let om = dot(wo, m);
    if im * wi.z <= 0.0 || om * wo.z <= 0.0 {
        return 0.0;
    }
    return min(min(abs(2.0 * m.z * wo.z / om), abs(2.0 * m.z * wi.z / im)), 1.0);
}

// Microfacet::g2: form 0 separable, 1 height-correlated, 2 V-cavity.
fn mf_g2(mf: Microfacet, form: u32, wi: vec3<f32>, wo: vec3<f32>, m: vec3<f32>) -> f32 {
    switch form {
        case 0u: { return mf_g2_separable(mf, wi, wo, m); }
        case 1u: { return mf_g2_height_correlated(mf, wi, wo, m); }
        default: { return v_cavity(wi, wo, m); }
    }
}

// bsdf::reflection_geometry: D G2 / (4 |cos θi cos θo|) and wi·h (Walter et al. 2007 eq. 20); (0, 0) where there
// is no rough reflection.
fn reflection_geometry(mf: Microfacet, form: u32, wi: vec3<f32>, wo: vec3<f32>) -> vec2<f32> {
    var h = normalize(wi + wo);
    if h.z < 0.0 {
        h = -h;
    }
    let g = mf_g2(mf, form, wi, wo, h);
    if wi.z * wo.z <= 0.0 || mf.smooth_ != 0u || g == 0.0 {
        return vec2<f32>(0.0, 0.0);
    }
    return vec2<f32>(mf_d(mf, h) * g / (4.0 * abs(wi.z * wo.z)), dot(wi, h));
}

// diffuse::oren_nayar_shape: qualitative Oren–Nayar 1994 (eq. 30) per unit albedo.
fn oren_nayar_shape(sigma: f32, wi: vec3<f32>, wo: vec3<f32>) -> f32 {
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return 0.0;
    }
    if sigma == 0.0 {
        return FRAC_1_PI;
    }
    let s2 = sigma * sigma;
    let a = 1.0 - 0.5 * s2 / (s2 + 0.33);
    let b = 0.45 * s2 / (s2 + 0.09);
    let sin_i = sqrt(max(1.0 - wi.z * wi.z, 0.0));
    let sin_o = sqrt(max(1.0 - wo.z * wo.z, 0.0));
    var cos_dphi = 0.0;
    if sin_i > 1e-12 && sin_o > 1e-12 {
        cos_dphi = clamp((wi.x * wo.x + wi.y * wo.y) / (sin_i * sin_o), -1.0, 1.0);
    }
    let sin_alpha_tan_beta = sin_i * sin_o / max(max(wi.z, wo.z), 1e-12);
    return FRAC_1_PI * (a + b * max(cos_dphi, 0.0) * sin_alpha_tan_beta);
}

// The tables' lookup (src/tables): a lower node and the fraction of the way to the next.
struct Node {
    i: i32,
    f: f32,
}

// tables::node: lower node and fraction of x on n uniform nodes over [0, 1], clamped.
fn table_node(x: f32, n: u32) -> Node {
    let s = clamp(x, 0.0, 1.0) * f32(n - 1u);
    let i = min(i32(s), i32(n) - 2);
    return Node(i, s - f32(i));
}


// tables::Grid::lookup's corners: for coordinates x (each clamped to [0, 1]) on a grid of d ≤ 4 axes with dims[a]
// nodes each (the last axis fastest), the lower corner's record index, the axes' strides and the fractions; the 2^d
// corners' indices and multilinear weights follow from them (corner_index, corner_weight).
struct GridPoint {
    base: u32,
    d: u32,
    strides: vec4<u32>,
    f: vec4<f32>,
}

fn grid_point(x: vec4<f32>, dims: vec4<u32>, d: u32) -> GridPoint {
    var g = GridPoint(0u, d, vec4<u32>(0u), vec4<f32>(0.0));
    var stride = 1u;
    for (var a = i32(d) - 1; a >= 0; a--) {
        let node = table_node(x[a], dims[a]);
        g.strides[a] = stride;
        g.f[a] = node.f;
        g.base += u32(node.i) * stride;
        stride *= dims[a];
    }
    return g;
}

// Corner k's record index: bit d − 1 − a of k steps along axis a.
fn corner_index(g: GridPoint, k: u32) -> u32 {
    var index = g.base;
    for (var a = 0u; a < g.d; a++) {
        index += ((k >> (g.d - 1u - a)) & 1u) * g.strides[a];
    }
    return index;
}

// Corner k's multilinear weight.
fn corner_weight(g: GridPoint, k: u32) -> f32 {
    var weight = 1.0;
    for (var a = 0u; a < g.d; a++) {
        weight *= select(1.0 - g.f[a], g.f[a], ((k >> (g.d - 1u - a)) & 1u) == 1u);
    }
    return weight;
}

// optics::reflect: w mirrored about the unit normal n.
fn reflect_about(w: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    return 2.0 * dot(w, n) * n - w;
}

// sampling::cosine_hemisphere: a cosine-weighted direction about +z from two uniform numbers.
fn cosine_hemisphere(u1: f32, u2: f32) -> vec3<f32> {
    let r = sqrt(u1);
    let phi = 2.0 * PI * u2;
    return vec3<f32>(r * cos(phi), r * sin(phi), sqrt(max(1.0 - u1, 0.0)));
}

// Microfacet::pdf_visible: the visible normals' density G1(wi, m) max(0, wi·m) D(m) / cos θi (Heitz 2018 eq. 3).
fn mf_pdf_visible(mf: Microfacet, wi: vec3<f32>, m: vec3<f32>) -> f32 {
    if wi.z <= 0.0 {
        return 0.0;
    }
    return mf_g1(mf, wi, m) * max(dot(wi, m), 0.0) * mf_d(mf, m) / wi.z;
}

// distribution::erf_inv: Giles 2010's single-precision approximation (the CPU refines it by Newton in float64).
fn erf_inv(y_in: f32) -> f32 {
    let y = clamp(y_in, -0.99999994, 0.99999994);
    var w = -log((1.0 - y) * (1.0 + y));
    var p: f32;
    if w < 5.0 {
        w -= 2.5;
        p = 2.81022636e-08;
        p = 3.43273939e-07 + p * w;
        p = -3.5233877e-06 + p * w;
        p = -4.39150654e-06 + p * w;
        p = 0.00021858087 + p * w;
        p = -0.00125372503 + p * w;
        p = -0.00417768164 + p * w;
        p = 0.246640727 + p * w;
        p = 1.50140941 + p * w;
    } else {
        w = sqrt(w) - 3.0;
        p = -0.000200214257;
        p = 0.000100950558 + p * w;
        p = 0.00134934322 + p * w;
        p = -0.00367342844 + p * w;
        p = 0.00573950773 + p * w;
        p = -0.0076224613 + p * w;
        p = 0.00943887047 + p * w;
        p = 1.00167406 + p * w;
        p = 2.83297682 + p * w;
    }
    return p * y;
}

// distribution::beckmann_sample_slopes: the visible slopes of the standard Beckmann configuration seen from v
// (Heitz & d'Eon 2014 §4): x by inverting its CDF (Newton safeguarded by bisection), y by erf⁻¹, rotated to v's azimuth.
fn beckmann_sample_slopes(v: vec3<f32>, u1: f32, u2: f32) -> vec2<f32> {
    let sin_t = sqrt(max(1.0 - v.z * v.z, 0.0));
    var cos_phi = 1.0;
    var sin_phi = 0.0;
    var x: f32;
    if sin_t > 1e-6 {
        cos_phi = v.x / sin_t;
        sin_phi = v.y / sin_t;
    }
    let c = v.z / max(sin_t, 1e-30);
    if sin_t <= 1e-6 || c > 1e6 {
        x = erf_inv(2.0 * u1 - 1.0);
    } else {
        let sqrt_pi = sqrt(PI);
        let target_ = u1 * (0.5 * c * sqrt_pi * (1.0 + erf(c)) + 0.5 * exp(-c * c));
        var lo = -6.0;
        var hi = min(c, 6.0);
        x = 0.5 * (lo + hi);
        for (var k = 0; k < 32; k++) {
            let f = 0.5 * c * sqrt_pi * (1.0 + erf(x)) + 0.5 * exp(-x * x) - target_;
            if f > 0.0 {
                hi = x;
            } else {
                lo = x;
            }
            let newton = x - f / ((c - x) * exp(-x * x));
            x = select(0.5 * (lo + hi), newton, newton > lo && newton < hi);
            if hi - lo < 1e-6 {
                break;
            }
        }
    }
    let y = erf_inv(2.0 * u2 - 1.0);
    return vec2<f32>(cos_phi * x - sin_phi * y, sin_phi * x + cos_phi * y);
}

// Microfacet::sample_visible: a visible normal for wi from two uniform numbers (GGX: Heitz 2018 listing 1;
// Beckmann: Heitz & d'Eon 2014 §4).
fn mf_sample_visible(mf: Microfacet, wi: vec3<f32>, u1: f32, u2: f32) -> vec3<f32> {
    let v = to_tangent_frame(wi, mf.cos_phi, mf.sin_phi);
    let vh = normalize(vec3<f32>(mf.alpha_x * v.x, mf.alpha_y * v.y, v.z));
    var m: vec3<f32>;
    if mf.dist == 0u {
        let len2 = vh.x * vh.x + vh.y * vh.y;
        var t1 = vec3<f32>(1.0, 0.0, 0.0);
        if len2 > 0.0 {
            t1 = vec3<f32>(-vh.y, vh.x, 0.0) / sqrt(len2);
        }
        let t2 = cross(vh, t1);
        let r = sqrt(u1);
        let phi = 2.0 * PI * u2;
        let p1 = r * cos(phi);
        let s = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - s) * sqrt(max(1.0 - p1 * p1, 0.0)) + s * r * sin(phi);
        let nh = p1 * t1 + p2 * t2 + sqrt(max(1.0 - p1 * p1 - p2 * p2, 0.0)) * vh;
        m = vec3<f32>(mf.alpha_x * nh.x, mf.alpha_y * nh.y, max(nh.z, 0.0));
    } else {
        let slope = beckmann_sample_slopes(vh, u1, u2);
        m = vec3<f32>(-slope.x * mf.alpha_x, -slope.y * mf.alpha_y, 1.0);
    }
    return to_tangent_frame(normalize(m), mf.cos_phi, -mf.sin_phi);
}
