//! Oat 2006, "Rendering Gooey Materials with Multiple Layers" (SIGGRAPH 2006 course 26, ch. 4): a semi-transparent
//! outer layer over inner layers at a depth, with parallax, a texture-space light map and a growable Poisson disc.
//! Not physically based: it reproduces inter-layer occlusion, depth parallax and light diffusion (the chapter's
//! three cues). Diffuse lighting only, from the scene's directional and point lights.
//!
//! | parameter       | meaning                                                                              |
//! |-----------------|--------------------------------------------------------------------------------------|
//! | `outer_albedo`  | RGB texture of the outer layer                                                        |
//! | `outer_opacity` | the outer layer's opacity α ∈ [0, 1]; the chapter's `a` is its transparency 1 − α     |
//! | `outer_normal`  | tangent-space unit normals of the outer layer (x along +u, y along +v, z outwards)    |
//! | `inner`         | inner layers, outermost first: RGB albedo, opacity (every layer but the last), depth   |
//! | `depth`         | an inner layer's depth below the outer surface, in texels (the chapter's thickness d) |
//! | `technique`     | `Full`, `NormalFiltered` or `VertexNormal` (the chapter's §4.6 optimizations; Python's `variant`) |
//! | `shadowing`     | weight light reaching inner layers by the outer transparency (the chapter's future work) |
//! | `border`        | texture addressing: clamp or wrap                                                     |
//! | `texel`         | the size of a texel in uv, (1/W, 1/H) of the outer textures (the chapter's 1/1024)     |
//! | `dilate`        | the light map's dilation passes on a mesh, across its uv seams                         |
//!
//! Composite (Listing 3), from the deepest layer up: C = lerp(base_k · light_k, C_below, w_k), w_k = (1 − α_k) ·
//! saturate(n · v), n from the outer normal map; the outer layer's base is its albedo lit unblurred at uv; inner layer
//! k is seen at the parallax-shifted uv_k (Listing 1), lit by the light map blurred with radius d_k and coloured by
//! its albedo blurred with radius s_k, the transmission distance. Light is Σ E max(0, N·l) / π: the radiance of a
//! white Lambertian surface.

#[cfg(feature = "gpu")]
pub mod gpu;

use crate::optics::reflect;
use crate::render::{incident, Border, Hit, Light, Shape, Surface, Texture};
use glam::DVec3;
use rayon::prelude::*;

/// The 12 unit-disc positions of the growable Poisson disc (Oat 2006, Listing 2).
pub const POISSON_DISC: [[f64; 2]; 12] = [
    [-0.326212, -0.40581],
    [-0.840144, -0.07358],
    [-0.695914, 0.457137],
    [-0.203345, 0.620716],
    [0.96234, -0.194983],
    [0.473434, -0.480026],
    [0.519456, 0.767022],
    [0.185461, -0.893124],
    [0.507431, 0.064425],
    [0.89642, 0.412458],
    [-0.32194, -0.932615],
    [-0.791559, -0.59771],
];

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Technique {
    /// The chapter's technique: a texture-space light map, blurred for the inner layers.
    Full,
    /// §4.6, first optimization: the Poisson disc over the outer normal map, N·L per tap, averaged; no light map.
    NormalFiltered,
    /// §4.6, second optimization: inner layers lit by the interpolated vertex normal, with no filter at all.
    VertexNormal,
}

impl Technique {
    /// The names `from_str` reads (Python's `variant=` of lamina.oat.Material), in the order of `ALL`.
    pub const NAMES: [&'static str; 3] = ["full", "normal_filtered", "vertex_normal"];
    pub const ALL: [Technique; 3] = [Technique::Full, Technique::NormalFiltered, Technique::VertexNormal];
}

impl std::str::FromStr for Technique {
    type Err = crate::error::Error;
    fn from_str(s: &str) -> crate::error::Result<Self> {
        crate::error::parse_choice("variant", s, &Self::NAMES, &Self::ALL)
    }
}

pub struct InnerLayer {
    pub albedo: Texture,
    /// None for the deepest layer, which is opaque.
    pub opacity: Option<Texture>,
    /// In texels; a 1 x 1 texture for a constant depth.
    pub depth: Texture,
}

pub struct Material {
    pub outer_albedo: Texture,
    pub outer_opacity: Texture,
    pub outer_normal: Texture,
    pub inner: Vec<InnerLayer>,
    pub technique: Technique,
    pub shadowing: bool,
    pub border: Border,
    pub texel: [f64; 2],
    /// The light map's dilation passes on a mesh (`light_map`).
    pub dilate: usize,
}

/// A material ready to shade: with its light map for the technique `Full`.
pub struct Prepared {
    pub material: Material,
    pub light_map: Option<Texture>,
}

/// Oat 2006 Listing 1: the inner layer's uv and the transmission distance s for the view v and normal n (unit,
/// tangent space) over a layer `thickness` texels deep: r = reflect(−v, n), t = (r.x, r.y, −r.z), s = d/|t.z|,
/// uv_inner = uv + texel · s · t.xy. |t.z| is kept above 1e-6 at grazing views.
pub fn parallax(uv: [f64; 2], v: DVec3, n: DVec3, thickness: f64, texel: [f64; 2]) -> ([f64; 2], f64) {
    let r = reflect(v, n);
    let t = DVec3::new(r.x, r.y, -r.z);
    let s = thickness / t.z.abs().max(1e-6);
    ([uv[0] + texel[0] * s * t.x, uv[1] + texel[1] * s * t.y], s)
}

/// The 13 tap positions of the growable Poisson disc (Oat 2006, Listing 2): uv, then uv + texel · p_k · radius.
pub fn disc_taps(uv: [f64; 2], radius: f64, texel: [f64; 2]) -> [[f64; 2]; 13] {
    let mut taps = [uv; 13];
    for (tap, p) in taps[1..].iter_mut().zip(POISSON_DISC) {
        *tap = [uv[0] + texel[0] * p[0] * radius, uv[1] + texel[1] * p[1] * radius];
    }
    taps
}

/// Oat 2006 Listing 2: the mean of the 13 equally weighted bilinear taps of the disc of `radius` texels.
pub fn poisson_filter(image: &Texture, uv: [f64; 2], radius: f64, texel: [f64; 2], border: Border) -> [f64; 3] {
    mean(disc_taps(uv, radius, texel).map(|tap| image.bilinear(tap, border)))
}

fn mean(values: [[f64; 3]; 13]) -> [f64; 3] {
    let mut sum = [0.0; 3];
    values.iter().for_each(|v| (0..3).for_each(|c| sum[c] += v[c] / 13.0));
    sum
}

/// Lambert's radiance for a white surface of normal n at p: Σ E max(0, n·l) / π over the lights.
pub fn diffuse(lights: &[Light], p: DVec3, n: DVec3) -> [f64; 3] {
    let mut out = [0.0; 3];
    for (l, e) in incident(lights, p) {
        let c = n.dot(l).max(0.0) * std::f64::consts::FRAC_1_PI;
        (0..3).for_each(|k| out[k] += e[k] * c);
    }
    out
}

/// The point of the shape at texture coordinates uv, as a Hit (Sphere and Plane: the inverse of their uv maps).
fn chart_point(shape: &Shape, uv: [f64; 2]) -> Option<Hit> {
    match shape {
        Shape::Sphere => {
            let (phi, theta) = ((uv[0] - 0.5) * std::f64::consts::TAU, uv[1] * std::f64::consts::PI);
            let n = DVec3::new(theta.sin() * phi.sin(), theta.cos(), theta.sin() * phi.cos());
            let t = DVec3::Y.cross(n).try_normalize().unwrap_or(DVec3::X);
            Some(Hit { p: n, n, t, uv })
        }
        Shape::Plane => {
            let p = DVec3::new(2.0 * uv[0] - 1.0, 1.0 - 2.0 * uv[1], 0.0);
            Some(Hit { p, n: DVec3::Z, t: DVec3::X, uv })
        }
        Shape::Mesh(_) => None,
    }
}

/// The tangent frame (t, +v, n) of a hit, as tangent-to-world and world-to-tangent maps.
fn frame(hit: &Hit) -> (impl Fn(DVec3) -> DVec3, impl Fn(DVec3) -> DVec3) {
    let (t, b, n) = (hit.t, hit.t.cross(hit.n), hit.n);
    (move |v: DVec3| v.x * t + v.y * b + v.z * n, move |w: DVec3| DVec3::new(w.dot(t), w.dot(b), w.dot(n)))
}

fn normal_at(map: &Texture, uv: [f64; 2], border: Border) -> DVec3 {
    DVec3::from_array(map.bilinear(uv, border)).try_normalize().unwrap_or(DVec3::Z)
}

/// The texture-space light map (step 2): the shape rasterized in uv at the normal map's resolution, each covered
/// texel lit by `diffuse` with the normal map's normal at its world position; then `dilate_passes` passes of
/// dilation, each filling the empty texels next to covered ones with their covered neighbours' mean, so that taps
/// across uv seams read lit texels.
pub fn light_map(shape: &Shape, normal_map: &Texture, lights: &[Light], dilate_passes: usize) -> Texture {
    let (w, h) = (normal_map.width, normal_map.height);
    let points: Vec<Option<Hit>> = match shape {
        Shape::Mesh(mesh) => mesh.rasterize_uv(w, h),
        _ => (0..w * h)
            .into_par_iter()
            .map(|k| chart_point(shape, [((k % w) as f64 + 0.5) / w as f64, ((k / w) as f64 + 0.5) / h as f64]))
            .collect(),
    };
    let mut data = vec![0.0; w * h * 3];
    data.par_chunks_mut(3).zip(&points).enumerate().for_each(|(k, (texel, point))| {
        if let Some(hit) = point {
            let n = DVec3::from_array(std::array::from_fn(|c| normal_map.data[k * normal_map.comps + c]));
            let n = (frame(hit).0)(n.try_normalize().unwrap_or(DVec3::Z));
            texel.copy_from_slice(&diffuse(lights, hit.p, n));
        }
    });
    let mut covered: Vec<bool> = points.iter().map(Option::is_some).collect();
    for _ in 0..dilate_passes {
        if covered.iter().all(|&c| c) {
            break;
        }
        let (before, seen) = (data.clone(), covered.clone());
        for k in (0..w * h).filter(|&k| !seen[k]) {
            let (i, j) = ((k % w) as i64, (k / w) as i64);
            let mut sum = [0.0; 3];
            let mut count = 0.0;
            for (di, dj) in [(-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)] {
                let (a, b) = (i + di, j + dj);
                if a >= 0 && b >= 0 && (a as usize) < w && (b as usize) < h && seen[b as usize * w + a as usize] {
                    let q = (b as usize * w + a as usize) * 3;
                    (0..3).for_each(|c| sum[c] += before[q + c]);
                    count += 1.0;
                }
            }
            if count > 0.0 {
                (0..3).for_each(|c| data[k * 3 + c] = sum[c] / count);
                covered[k] = true;
            }
        }
    }
    Texture { width: w, height: h, comps: 3, data }
}

impl Surface for Prepared {
    fn shade(&self, lights: &[Light], hit: &Hit, wo_world: DVec3) -> [f64; 3] {
        shade(self, lights, hit, wo_world)
    }
}

/// Radiance towards the viewer (wo_world) at a hit: the composite above.
pub fn shade(prepared: &Prepared, lights: &[Light], hit: &Hit, wo_world: DVec3) -> [f64; 3] {
    let m = &prepared.material;
    let (to_world, to_tangent) = frame(hit);
    let (uv, border, texel) = (hit.uv, m.border, m.texel);
    let v = to_tangent(wo_world);
    let n = normal_at(&m.outer_normal, uv, border);
    let lit = |ts: DVec3| diffuse(lights, hit.p, to_world(ts));
    let light_map = prepared.light_map.as_ref();
    let outer_light = light_map.map_or_else(|| lit(n), |map| map.bilinear(uv, border));
    let transparency = |at: [f64; 2]| if m.shadowing { 1.0 - m.outer_opacity.bilinear(at, border)[0] } else { 1.0 };
    let cos = n.dot(v).clamp(0.0, 1.0);
    let mut below = [0.0; 3];
    for (k, layer) in m.inner.iter().enumerate().rev() {
        let d = layer.depth.bilinear(uv, border)[0];
        let (uv_k, s) = parallax(uv, v, n, d, texel);
        let taps = disc_taps(uv_k, d, texel);
        let scale = |mut c: [f64; 3], w: f64| {
            c.iter_mut().for_each(|x| *x *= w);
            c
        };
        let light = match (m.technique, light_map) {
            (Technique::Full, Some(map)) => mean(taps.map(|tap| scale(map.bilinear(tap, border), transparency(tap)))),
            (Technique::VertexNormal, _) => scale(diffuse(lights, hit.p, hit.n), transparency(uv_k)),
            _ => mean(taps.map(|tap| scale(lit(normal_at(&m.outer_normal, tap, border)), transparency(tap)))),
        };
        let base = match m.technique {
            Technique::VertexNormal => layer.albedo.bilinear(uv_k, border),
            _ => poisson_filter(&layer.albedo, uv_k, s, texel, border),
        };
        let colour: [f64; 3] = std::array::from_fn(|c| base[c] * light[c]);
        below = match &layer.opacity {
            Some(opacity) if k + 1 < m.inner.len() => {
                let w = (1.0 - opacity.bilinear(uv_k, border)[0]) * cos;
                std::array::from_fn(|c| colour[c] + w * (below[c] - colour[c]))
            }
            _ => colour,
        };
    }
    let albedo = m.outer_albedo.bilinear(uv, border);
    let w = (1.0 - m.outer_opacity.bilinear(uv, border)[0]) * cos;
    std::array::from_fn(|c| albedo[c] * outer_light[c] + w * (below[c] - albedo[c] * outer_light[c]))
}

/// Where light entering a plane-parallel slab at normal incidence leaves its bottom: a random walk with positions
/// (free paths ~ Exp(σt), Henyey–Greenstein scattering, absorption as a weight σs/σt per event, Russian roulette
/// below 1e-3), one path per sample, index-matched boundaries. Returns (exit radius in scene units, throughput) of
/// the transmitted paths; their radial profile is the sideways spread behind Oat's blur radius.
pub fn slab_exit(thickness: f64, sigma_s: f64, sigma_a: f64, g: f64, samples: usize, seed: u64) -> Vec<[f64; 2]> {
    let sigma_t = sigma_s + sigma_a;
    (0..samples)
        .into_par_iter()
        .filter_map(|k| {
            let mut rng = crate::sampling::Rng::new(seed, k as u64);
            let (mut p, mut d, mut weight) = (DVec3::ZERO, DVec3::NEG_Z, 1.0);
            for _ in 0..100_000 {
                let t = if sigma_t > 0.0 { -(1.0 - rng.uniform()).ln() / sigma_t } else { f64::INFINITY };
                let z = p.z + t * d.z;
                if z <= -thickness {
                    let q = p + (-thickness - p.z) / d.z * d;
                    return Some([q.x.hypot(q.y), weight]);
                }
                if z >= 0.0 {
                    return None;
                }
                p += t * d;
                weight *= sigma_s / sigma_t;
                if weight < 1e-3 {
                    if rng.uniform() >= 0.1 {
                        return None;
                    }
                    weight /= 0.1;
                }
                d = crate::sampling::sample_henyey_greenstein(d, g, rng.uniform(), rng.uniform());
            }
            None
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp() -> Texture {
        Texture { width: 4, height: 3, comps: 1, data: (0..12).map(|k| k as f64).collect() }
    }

    #[test]
    fn bilinear_reads_texel_centres_and_interpolates_between_them() {
        let t = ramp();
        for border in [Border::Clamp, Border::Wrap] {
            assert_eq!(t.bilinear([(2.0 + 0.5) / 4.0, (1.0 + 0.5) / 3.0], border)[0], 6.0);
            assert!((t.bilinear([2.0 / 4.0, 1.5 / 3.0], border)[0] - 5.5).abs() < 1e-12);
        }
        assert_eq!(t.bilinear([0.0, 0.5 / 3.0], Border::Clamp)[0], 0.0); // half a texel left of centre 0
        assert!((t.bilinear([0.0, 0.5 / 3.0], Border::Wrap)[0] - 1.5).abs() < 1e-12);
        // between texels 3 and 0
    }

    #[test]
    fn parallax_head_on_and_poisson_filter_of_a_constant() {
        let (uv, s) = parallax([0.25, 0.75], DVec3::Z, DVec3::Z, 5.0, [1.0 / 1024.0; 2]);
        assert_eq!((uv, s), ([0.25, 0.75], 5.0));
        let flat = Texture { width: 8, height: 8, comps: 3, data: vec![0.4; 192] };
        let v = poisson_filter(&flat, [0.3, 0.6], 7.0, [0.125; 2], Border::Wrap);
        assert!(v.iter().all(|&x| (x - 0.4).abs() < 1e-15));
    }

    #[test]
    fn slab_exit_scales_with_the_slab() {
        let a = slab_exit(1.0, 2.0, 0.2, 0.5, 2000, 3);
        let b = slab_exit(2.0, 1.0, 0.1, 0.5, 2000, 3);
        assert_eq!(a.len(), b.len());
        for (x, y) in a.iter().zip(&b) {
            assert!((2.0 * x[0] - y[0]).abs() <= 1e-9 * y[0].max(1.0) && (x[1] - y[1]).abs() < 1e-12);
        }
    }
}
