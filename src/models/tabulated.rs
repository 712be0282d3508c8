//! `model="tabulated"`: lamina's near-exact model, paid for by a precomputation. Preparing it solves the stack's
//! transport by Fourier-series adding-doubling (tables/adding_doubling.rs: the reference walk's boundaries and slabs,
//! after Jakob et al. 2014) and tabulates f at (N_THETA + 1)² zenith nodes × N_PHI azimuths; evaluating it adds the
//! top boundary's own reflection, exact, to the interpolation of the table (all light that entered the stack). Below a
//! smooth top the table holds f divided at both nodes by what enters through the top and its clear slab (Fresnel and
//! Beer–Lambert, steep near grazing angles, where they vanish), and the interpolation is multiplied by the exact
//! values (`entering`). Tables are cached on disk, keyed by the stack and the options (tables::cached).
//!
//! | Parameter      | Type   | Default             | Description                                                    |
//! |----------------|--------|---------------------|----------------------------------------------------------------|
//! | `distribution` | string | `ggx`               | microfacet distribution of every rough boundary, as the reference's |
//! | `g2`           | string | `height_correlated` | masking-shadowing, as the reference's                          |
//!
//! Gradients (`Stack.eval_grad`): the adding-doubling solved in Duals (tables/adding_doubling.rs is generic over
//! `Real`: every projection, energy, product and solve carries the derivatives; a stack that `eval` has not prepared
//! is solved in Duals alone, `prepare_gradient`, without the float64 table), exact for a coat's thickness,
//! σa, σs and g, a smooth coat's IOR, the conductor base's η, κ and roughness and the diffuse base's albedo and σ. A
//! rough coat's IOR and roughness by central differences of the solve at 2% of the parameter (`differenced` says
//! why); a roughness on one axis, and a conductor's under Beckmann or the V-cavity, are refused (`refused`).
//!
//! A table holds (N_THETA + 1)² N_PHI f32 per channel, each reciprocal pair once (0.81 MiB for RGB). Anisotropic
//! stacks (Yamaguchi et al. 2019: anisotropic roughness, a tangent angle per layer) are solved on a grid that keeps
//! both azimuths (tables/anisotropic.rs: 32 zenith cells × 96 azimuth bins) and tabulated at 33² zenith nodes × 49
//! azimuths of wi × 96 of wo (58.6 MiB for RGB), interpolated at 16 corners (eight rows of two adjacent records, a
//! block's rows prefetched; float32 lanes compute the coordinates in float64; no gradients or GPU kernel yet: the GPU
//! and the gradient raise a ValueError). Sampling: the top's visible normals and the inner rough
//! boundaries' lobes (each at least as rough as the layers above it), weighted by their energies, and the cosine.
//! Below a smooth top, the mirror reflections of smooth boundaries seen through smooth ones (a clear coat over a
//! smooth interface or a polished metal) are Dirac lobes that cells would blur: the table leaves them out and
//! `specular` adds them exactly, with the top's (`ChannelStack::dirac_reflectance`).

use super::common::block::{eval_rows, simd_columns, BLOCK};
use super::common::mixture::defensive_mixture;
use super::common::mixture_lanes::{self, LaneMixture, Proposals, MAX_TERMS};
use super::common::options::{microsurface, DISTRIBUTION, G2};
use super::{
    microfacet, per_pair, Differentiable, Field, Gradient, InputSpec, Model, ModelInfo, OptionSpec, Properties,
    Proposal, Seed,
};
use crate::bsdf::rough_dielectric;
use crate::dual::Real;
use crate::engine::{self, per_lane, Floats, Rows, LANES, V3};
use crate::error::{value_error, Result};
use crate::models::FitLanes;
use crate::optics::distribution::{Distribution, G2Form, Microfacet};
use crate::optics::fresnel::{self, FresnelForm};
use crate::optics::lanes::{self, Ggx, Visible};
use crate::stack::{Layer, Stack};
use crate::tables::adding_doubling::{
    channel_key, clear_depth, node_values, pair, tabulate, Cells, NODES, N_PHI, N_THETA, ORDERS, PAIRS,
};
use crate::tables::{anisotropic, cached, node, node_lanes};
use crate::transport::{ChannelStack, Interface, Microsurface};
use glam::DVec3;
use std::hash::{DefaultHasher, Hash, Hasher};

pub const INFO: ModelInfo = ModelInfo {
    name: "tabulated",
    summary: "lamina's near-exact model: the stack solved by Fourier adding-doubling once, then interpolated",
    options: &[DISTRIBUTION, G2] as &[OptionSpec],
    inputs: &[] as &[InputSpec],
    properties: Properties { reciprocal: true, energy_conserving: true, anisotropic: true, spectral: true },
    gradients: &Field::NAMES,
    prepare: |stack, args| prepare(stack, microsurface(args)?),
    prepare_gradient: Some(|stack, args| prepare_gradient(stack, microsurface(args)?)),
    #[cfg(feature = "gpu")]
    gpu: Some(&gpu::HALF),
};

pub struct Prepared {
    /// f less the top's reflection: tables::adding_doubling::tabulate's layout, or tables::anisotropic::tabulate's
    /// for an anisotropic stack.
    table: Vec<f32>,
    anisotropic: bool,
    /// Below a smooth top (isotropic tables), the clear slab's optical depth per channel (`clear_depth`): the table
    /// holds f / (Āi Āo) (`node_values`), which `eval` multiplies by the exact `entering`.
    clear: Option<Vec<f64>>,
    /// The top interface: its microfacets (None when smooth), masking-shadowing and relative IOR per channel.
    top: Option<Microfacet>,
    g2: G2Form,
    eta: Vec<f64>,
    /// The stack per channel, for the Dirac reflection (`specular`).
    channels: Vec<ChannelStack>,
    /// Sampling: the rough boundaries' microfacets below the top (each at least as rough as those above it), and
    /// the table's albedo per zenith node.
    lobes: Vec<Microfacet>,
    albedo_below_top: Vec<f64>,
    /// What the table was solved for, which the gradient solves again in Duals.
    stack: Stack,
    surface: Microsurface,
}

/// The file name of the cached table of `stack` on `surface` (a hash of everything the table depends on).
fn cache_name(stack: &Stack, surface: Microsurface) -> String {
    let mut h = DefaultHasher::new();
    // "diffuse": the table without the Dirac part below a smooth top (before, it blurred that part into cells);
    // "refraction": smooth refractions integrated in the outside cosine (before, at each overlap's midpoint);
    // "transmitted": below a smooth top, f / (Āi Āo) (before, f).
    let grid = match anisotropic::is_anisotropic(stack, surface) {
        true => format!("anisotropic {}x{}", anisotropic::NZ, anisotropic::NA),
        false => format!("{N_THETA}x{ORDERS}x{N_PHI}"),
    };
    format!("{stack:?}|{:?}|{:?}|{grid}|diffuse|trapped|refraction|transmitted", surface.distribution, surface.g2)
        .hash(&mut h);
    format!("tabulated-{:016x}.f32", h.finish())
}

/// The model of `stack` with rough boundaries of `surface`: a single opaque boundary is its own top, which
/// `microfacet` evaluates exactly, with nothing to tabulate; a layered stack is tabulated.
pub fn prepare(stack: &Stack, surface: Microsurface) -> Result<Box<dyn Model>> {
    match stack.layers.len() {
        1 => Ok(Box::new(single(stack, surface)?)),
        _ => Ok(Box::new(tabulate_stack(stack, surface, true)?)),
    }
}

/// What `Stack.eval_grad` differentiates (`ModelInfo::prepare_gradient`): a layered stack without its float64 table,
/// which the gradient's solve in Duals gives again with its derivatives.
fn prepare_gradient(stack: &Stack, surface: Microsurface) -> Result<Box<dyn Differentiable>> {
    match stack.layers.len() {
        1 => Ok(Box::new(single(stack, surface)?)),
        _ => Ok(Box::new(Unsolved(tabulate_stack(stack, surface, false)?))),
    }
}

/// A single opaque boundary: `microfacet`'s exact model, on the same microsurface.
fn single(stack: &Stack, surface: Microsurface) -> Result<microfacet::Prepared> {
    let opts = microfacet::Options { distribution: surface.distribution, g2: surface.g2, fresnel: FresnelForm::Exact };
    microfacet::prepare(stack, &opts)
}

/// The tabulated model of a layered stack; with `solved` false, without its table (and so without the sampling
/// albedo), for `Unsolved`.
fn tabulate_stack(stack: &Stack, surface: Microsurface, solved: bool) -> Result<Prepared> {
    let anisotropic = anisotropic::is_anisotropic(stack, surface);
    let table = match (solved, anisotropic) {
        (false, _) => Vec::new(),
        (true, true) => cached(&cache_name(stack, surface), anisotropic::LEN * stack.channels, || {
            anisotropic::tabulate(stack, surface)
        })?,
        (true, false) => {
            cached(&cache_name(stack, surface), PAIRS * N_PHI * stack.channels, || tabulate(stack, surface))?
        }
    };
    let top = stack.layers[0].microfacet(surface.distribution).filter(|m| !m.is_smooth());
    // Sampling proposes each inner rough boundary's lobe as seen through the layers above it, at least as rough as
    // the roughest of them (Elek's m₂ ≥ m₁): a glossy metal under a rough coat reflects a lobe as wide as the coat's.
    let mut rougher = 0.0f64;
    let mut lobes = Vec::new();
    for (i, mf) in stack.layers.iter().enumerate().filter_map(|(i, l)| Some((i, l.microfacet(surface.distribution)?))) {
        if i > 0 && !mf.is_smooth() {
            lobes.push(mf.with_alpha(mf.alpha_x.max(rougher), mf.alpha_y.max(rougher)));
        }
        if !mf.is_smooth() {
            rougher = rougher.max(mf.alpha_x);
        }
    }
    let cells = Cells::new();
    let eta = stack.interfaces().swap_remove(0).eta;
    let channels: Vec<ChannelStack> = (0..stack.channels).map(|c| ChannelStack::new(stack, c, surface)).collect();
    let clear = (top.is_none() && !anisotropic).then(|| channels.iter().map(clear_depth).collect::<Vec<_>>());
    // ∫ f cos θo dωo: over θo by `Cells::node_integral`, over the full circle by trapezoids over the nodes'
    // φ ∈ [0, π], twice; mean of the channels.
    let ch = stack.channels;
    let mu = |k: usize| 1.0 - (k as f64 / N_THETA as f64).powi(2);
    let t = |k: usize, c: usize| clear.as_ref().map_or(1.0, |d| entering(mu(k), eta[c], d[c]));
    let value = |i: usize, o: usize, p: usize| {
        let k = (pair(i, o) * N_PHI + p) * ch;
        (0..ch).map(|c| table[k + c] as f64 * t(i, c) * t(o, c)).sum::<f64>() / ch as f64
    };
    let phi: Vec<f64> = (0..N_PHI).map(|p| 2.0 * (p as f64 / (N_PHI - 1) as f64).asin()).collect();
    let albedo_below_top = match (solved, anisotropic) {
        (false, _) => Vec::new(),
        (true, true) => anisotropic::albedo(&table, ch),
        (true, false) => (0..NODES)
            .map(|i| {
                let over_theta = |p: usize| 2.0 * cells.node_integral(|o| value(i, o, p));
                (0..N_PHI - 1).map(|p| 0.5 * (over_theta(p) + over_theta(p + 1)) * (phi[p + 1] - phi[p])).sum()
            })
            .collect(),
    };
    let (g2, stack) = (surface.g2, stack.clone());
    Ok(Prepared { table, anisotropic, clear, top, g2, eta, channels, lobes, albedo_below_top, stack, surface })
}

/// What of the light at zenith cosine z crosses a smooth top of relative IOR `eta` and the clear slab of optical depth
/// `depth` below it: T(z) e^(−depth / cos θt) (Fresnel, Snell, Beer–Lambert), what the table is divided by at its
/// nodes below a smooth top (adding_doubling::node_values); 1 for a top less dense than the outside (not factored).
#[inline(always)]
fn entering<T: Real>(z: f64, eta: T, depth: T) -> T {
    if eta.value() < 1.0 {
        return T::from(1.0);
    }
    let cos_t = (T::from(1.0) - (T::from(1.0) - z * z) / (eta * eta)).max_c(1e-12).sqrt();
    fresnel::dielectric_transmittance(z, eta) * (-depth / cos_t).exp()
}

/// `entering` in float32 lanes.
#[inline(always)]
fn entering_lanes(z: Floats, eta: f64, depth: f64) -> Floats {
    if eta < 1.0 {
        return Floats::splat(1.0);
    }
    let t = lanes::dielectric_transmittance(z, eta);
    if depth == 0.0 {
        return t;
    }
    let cos2_t = z.mul_add(z, Floats::splat((eta * eta - 1.0) as f32)) * ((1.0 / (eta * eta)) as f32);
    t * (Floats::splat(-depth as f32) / cos2_t.max(Floats::splat(1e-12)).sqrt()).exp()
}

/// The table coordinate x = √(1 − cos θ) of zenith cosine z.
#[inline(always)]
pub(crate) fn zenith(z: f64) -> f64 {
    (1.0 - z).max(0.0).sqrt()
}

/// The table's coordinates of the pair (wi, wo): for θi, θo and the azimuth between the travel directions
/// (y = sin(φ/2) = √((1 − cos φ)/2), cos φ = −cos(φi − φo)), the node below and the weight of the one above.
#[inline(always)]
fn coordinates(wi: DVec3, wo: DVec3) -> [(usize, f64); 3] {
    let d = ((wi.x * wi.x + wi.y * wi.y) * (wo.x * wo.x + wo.y * wo.y)).sqrt();
    let cos_phi = if d > 0.0 { -(wi.x * wo.x + wi.y * wo.y) / d } else { 1.0 };
    [node(zenith(wi.z), NODES), node(zenith(wo.z), NODES), node((0.5 * (1.0 - cos_phi)).max(0.0).sqrt(), N_PHI)]
}

impl Prepared {
    /// f for a block of rows (`Model::eval_block`): the top's exact reflection plus the interpolated table. The
    /// first passes (the top's reflection channel by channel, the table coordinates) run in vector lanes; the last
    /// gathers the table's corners.
    #[inline(always)]
    fn eval_columns(&self, wi: [&[f64]; 3], wo: [&[f64]; 3], out: &mut [f64]) {
        let n = wi[0].len();
        let ch = self.eta.len();
        let ([ix, iy, iz], [ox, oy, oz]) = (wi.map(|c| &c[..n]), wo.map(|c| &c[..n]));
        // The top's reflection (models/microfacet.rs `geometry`, then the Fresnel factor channel by channel, a
        // branch-free loop; channels of equal IOR computed once).
        if let Some(mf) = &self.top {
            let (mut geo, mut cos_h, mut f) = ([0.0; BLOCK], [0.0; BLOCK], [0.0; BLOCK]);
            let (geo, cos_h, f) = (&mut geo[..n], &mut cos_h[..n], &mut f[..n]);
            microfacet::geometry(mf, self.g2, wi, wo, geo, cos_h);
            for (c, &eta) in self.eta.iter().enumerate() {
                if c == 0 || eta != self.eta[c - 1] {
                    for r in 0..n {
                        f[r] = geo[r] * fresnel::dielectric(cos_h[r], eta);
                    }
                }
                for (o, &x) in out.chunks_exact_mut(ch).zip(f.iter()) {
                    o[c] = x;
                }
            }
        }
        if self.anisotropic {
            // The coordinates of the block, then its rows interpolated.
            let mut at = [None; BLOCK];
            for (r, at) in at[..n].iter_mut().enumerate() {
                *at = anisotropic::coordinates(DVec3::new(ix[r], iy[r], iz[r]), DVec3::new(ox[r], oy[r], oz[r]));
            }
            self.interpolate_anisotropic(&at[..n], |r, c, v| out[r * ch + c] += v as f64);
            return;
        }
        // Table coordinates, in vector lanes: the node below each coordinate and the weight of the one above; rows
        // below the horizon get no weight.
        let ([mut i, mut o, mut p], [mut fi, mut fo, mut fp]) = ([[0usize; BLOCK]; 3], [[0.0; BLOCK]; 3]);
        for r in 0..n {
            let at = coordinates(DVec3::new(ix[r], iy[r], iz[r]), DVec3::new(ox[r], oy[r], oz[r]));
            ((i[r], fi[r]), (o[r], fo[r]), (p[r], fp[r])) = (at[0], at[1], at[2]);
        }
        // The corners, gathered: the channel count a constant for RGB, so that each record is a fixed-size read.
        let corners = Corners { i, o, p, fi, fo, fp };
        match ch {
            3 => self.gather::<3>(&corners, iz, oz, out),
            _ => self.gather::<0>(&corners, iz, oz, out),
        }
        // Below a smooth top (which reflects nothing here), what enters through it and its clear slab.
        if let Some(depth) = &self.clear {
            for (r, out) in out.chunks_exact_mut(ch).enumerate() {
                for ((f, &eta), &d) in out.iter_mut().zip(&self.eta).zip(depth) {
                    *f *= entering(iz[r], eta, d) * entering(oz[r], eta, d);
                }
            }
        }
    }

    /// Adds the trilinear interpolation of the table at `corners` to `out` (C channels, or any number when C = 0).
    #[inline(always)]
    fn gather<const C: usize>(&self, corners: &Corners, iz: &[f64], oz: &[f64], out: &mut [f64]) {
        let ch = if C == 0 { self.eta.len() } else { C };
        let Corners { i, o, p, fi, fo, fp } = corners;
        for (r, out) in out.chunks_exact_mut(ch).enumerate() {
            let above = if iz[r] > 0.0 && oz[r] > 0.0 { 1.0 } else { 0.0 };
            let (wp0, wp1) = (above * (1.0 - fp[r]), above * fp[r]);
            for (di, wi_) in [(0, 1.0 - fi[r]), (1, fi[r])] {
                for (dj, wo_) in [(0, 1.0 - fo[r]), (1, fo[r])] {
                    let k = (pair(i[r] + di, o[r] + dj) * N_PHI + p[r]) * ch;
                    let (a, b) = (&self.table[k..k + ch], &self.table[k + ch..k + 2 * ch]);
                    let (wa, wb) = (wi_ * wo_ * wp0, wi_ * wo_ * wp1);
                    for ((o, &a), &b) in out.iter_mut().zip(a).zip(b) {
                        *o += wa * a as f64 + wb * b as f64;
                    }
                }
            }
        }
    }
}

impl Prepared {
    /// An anisotropic table's interpolation at the coordinates `at` of a group of rows (None: below the horizon),
    /// row by row and channel by channel into `add(r, c, f)`: every row's corners requested first, then read (one and
    /// three channels with their records' lengths known to the compiler).
    #[inline(always)]
    fn interpolate_anisotropic(&self, at: &[Option<anisotropic::At>], mut add: impl FnMut(usize, usize, f32)) {
        let ch = self.eta.len();
        at.iter().flatten().for_each(|at| anisotropic::prefetch(&self.table, at, ch));
        for (r, at) in at.iter().enumerate() {
            let Some(at) = at else { continue };
            let add = |c: usize, f: f32| add(r, c, f);
            match ch {
                1 => anisotropic::interpolate_at::<1>(&self.table, at, 1, add),
                3 => anisotropic::interpolate_at::<3>(&self.table, at, 3, add),
                _ => anisotropic::interpolate_at::<0>(&self.table, at, ch, add),
            }
        }
    }

    /// The table's trilinear interpolation in float32 at the lower nodes `at` (θi, θo, φ) with the upper nodes'
    /// weights `w`: channels c0..c0 + C.
    #[inline(always)]
    fn interpolate<const C: usize>(&self, at: [usize; 3], w: [f32; 3], c0: usize) -> [f32; C] {
        let ch = self.eta.len();
        let mut f = [0.0f32; C];
        for (di, wi) in [(0, 1.0 - w[0]), (1, w[0])] {
            for (dj, wo) in [(0, 1.0 - w[1]), (1, w[1])] {
                let k = (pair(at[0] + di, at[1] + dj) * N_PHI + at[2]) * ch + c0;
                let (w0, w1) = (wi * wo * (1.0 - w[2]), wi * wo * w[2]);
                let (a, b) = (&self.table[k..k + C], &self.table[k + ch..k + ch + C]);
                for c in 0..C {
                    f[c] = a[c].mul_add(w0, b[c].mul_add(w1, f[c]));
                }
            }
        }
        f
    }
}

/// The tabulated model in float32 lanes: the top's reflection and the table's coordinates in lanes, the corners
/// gathered lane by lane.
struct Lanes<'a> {
    p: &'a Prepared,
    top: Option<Ggx>,
}

impl Prepared {
    /// The kernel, where the lanes cover the top (a GGX or smooth top with a Smith G2).
    fn lanes(&self) -> Option<Lanes<'_>> {
        let top = match &self.top {
            Some(mf) => Some(Ggx::new(mf, self.g2)?),
            None => None,
        };
        Some(Lanes { p: self, top })
    }
}

/// The kernel with what its sampling mixture needs in lanes: the inner lobes' visible normals and the albedo below
/// the top per zenith node in float32.
struct Sampled<'a> {
    lanes: Lanes<'a>,
    lobes: Vec<Visible>,
    below: Vec<f32>,
}

impl engine::Kernel for Sampled<'_> {
    #[inline(always)]
    fn eval(&self, wi: V3, wo: V3, out: &mut [Floats]) {
        self.lanes.eval(wi, wo, out)
    }
}

/// `Prepared::proposals` in lanes: the top's lobe by its Fresnel reflectance at cos θo, the albedo below it
/// (interpolated at θo) shared by the inner lobes (or the cosine without any), and the defensive share.
impl Proposals for Sampled<'_> {
    #[inline(always)]
    fn proposals(&self, wo: V3) -> LaneMixture {
        let (node, f) = zenith_node_lanes(wo, self.below.len());
        let at = |dk: usize| Floats(per_lane(|l| self.below[node[l] as usize + dk]));
        let below = (1.0 - f).mul_add(at(0), f * at(1));
        let mut mix = LaneMixture::new();
        if let Some(top) = self.lanes.top {
            mix.push(lanes::dielectric(wo.z, self.lanes.p.eta[0]), Some(Visible::Ggx(top)));
        }
        let share = below * (1.0 / self.lobes.len().max(1) as f32);
        for lobe in &self.lobes {
            mix.push(share, Some(*lobe));
        }
        if self.lobes.is_empty() {
            mix.push(below, None);
        }
        mix.add_defensive_share();
        mix
    }
}

/// `node(zenith(cos θ), n)` of a unit direction in lanes (either side; below the horizon as at it), as exact as float32
/// allows at both ends of the coordinate x = √(1 − cos θ): near the normal from x = √((x² + y²) / (1 + cos θ)) (no
/// cancellation), and near the horizon (x > ½) from the distance to the top node, t = (n − 1)(1 − x) with
/// 1 − x = cos θ / (1 + x); there x (n − 1) ≈ 63 is stored only to 3.8e-6 of a node in float32, which moved a table
/// whose records change steeply at grazing angles (transport_fit's) by 3e-5.
#[inline(always)]
pub(crate) fn zenith_node_lanes(w: V3, n: usize) -> ([u32; LANES], Floats) {
    let (zero, one) = (Floats::splat(0.0), Floats::splat(1.0));
    let z = w.z.max(zero);
    let x = (w.x.mul_add(w.x, w.y * w.y) / (1.0 + z)).sqrt().min(one);
    let top = Floats::splat((n - 1) as f32);
    let (s, t) = (x * top, z / (1.0 + x) * top);
    let near_top = x.gt(Floats::splat(0.5));
    let below = s.min(top - 1.0).floor();
    // ⌈t⌉, at least 1: the upper node counted from the top.
    let above = t.ceil().max(one).min(top);
    let (node, _) = Floats::select(near_top, top - above, below).floor_index();
    (node, Floats::select(near_top, above - t, s - below).max(zero).min(one))
}

impl engine::Kernel for Lanes<'_> {
    #[inline(always)]
    fn eval(&self, wi: V3, wo: V3, out: &mut [Floats]) {
        let zero = Floats::splat(0.0);
        match &self.top {
            Some(ggx) => {
                let (geo, cos_h) = lanes::ggx_reflection(ggx, wi, wo);
                let eta = &self.p.eta;
                for c in 0..eta.len() {
                    out[c] =
                        if c > 0 && eta[c] == eta[c - 1] { out[c - 1] } else { geo * lanes::dielectric(cos_h, eta[c]) };
                }
            }
            None => out.fill(zero),
        }
        if self.p.anisotropic {
            // The coordinates lane by lane in float64 (`anisotropic::coordinates`, as the float64 path computes
            // them).
            let mut at = [None; LANES];
            for (l, at) in at.iter_mut().enumerate() {
                let lane = |w: V3| DVec3::new(w.x.0[l] as f64, w.y.0[l] as f64, w.z.0[l] as f64);
                *at = anisotropic::coordinates(lane(wi), lane(wo));
            }
            self.p.interpolate_anisotropic(&at, |l, c, v| out[c].0[l] += v);
            return;
        }
        // The coordinates in forms without cancellation, as float32 needs them near their ends: the zenith
        // coordinate's node from its nearer end (`zenith_node_lanes`), and the azimuth between the travel
        // directions y = sin(φ/2) = √((1 − cos φ)/2) with cos φ = −cos(φi − φo), as |âi + âo| / 2 for the unit
        // tangent components â (0 where either direction is the normal).
        let (ri, ro) = (wi.x.mul_add(wi.x, wi.y * wi.y), wo.x.mul_add(wo.x, wo.y * wo.y));
        let ((i, fi), (o, fo)) = (zenith_node_lanes(wi, NODES), zenith_node_lanes(wo, NODES));
        let both = ri.gt(zero) & ro.gt(zero);
        let (si, so) = (1.0 / ri.sqrt(), 1.0 / ro.sqrt());
        let (ax, ay) = (wi.x.mul_add(si, wo.x * so), wi.y.mul_add(si, wo.y * so));
        let (p, fp) = node_lanes(Floats::and(both, 0.5 * ax.mul_add(ax, ay * ay).sqrt()), N_PHI);
        let above = wi.z.gt(zero) & wo.z.gt(zero);
        // The corners' records requested for every lane before any is read: the table (0.8 MiB for RGB) is read at
        // random, and the lanes' cache misses then overlap.
        #[cfg(target_arch = "x86_64")]
        for l in 0..LANES {
            for (di, dj) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                let k = (pair(i[l] as usize + di, o[l] as usize + dj) * N_PHI + p[l] as usize) * self.p.eta.len();
                let at = self.p.table[k..].as_ptr();
                // SAFETY: a prefetch reads nothing; the address is inside the table.
                unsafe { std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(at as *const i8) };
            }
        }
        for l in (0..LANES).filter(|&l| above.0[l] != 0) {
            let at = [i[l] as usize, o[l] as usize, p[l] as usize];
            let weights = [fi.0[l], fo.0[l], fp.0[l]];
            // RGB with its three channels in registers; any other count a channel at a time.
            if out.len() == 3 {
                let f = self.p.interpolate::<3>(at, weights, 0);
                (0..3).for_each(|c| out[c].0[l] += f[c]);
            } else {
                for (c, o) in out.iter_mut().enumerate() {
                    o.0[l] += self.p.interpolate::<1>(at, weights, c)[0];
                }
            }
        }
        // Below a smooth top (which reflects nothing here), what enters through it and its clear slab.
        if let Some(depth) = &self.p.clear {
            for (c, f) in out.iter_mut().enumerate() {
                let (eta, d) = (self.p.eta[c], depth[c]);
                *f = *f * entering_lanes(wi.z, eta, d) * entering_lanes(wo.z, eta, d);
            }
        }
    }
}

/// The table nodes below a block's coordinates (θi, θo, φ) and the weights of the nodes above.
struct Corners {
    i: [usize; BLOCK],
    o: [usize; BLOCK],
    p: [usize; BLOCK],
    fi: [f64; BLOCK],
    fo: [f64; BLOCK],
    fp: [f64; BLOCK],
}

impl Differentiable for Prepared {
    fn gradient(&self, seeds: &[Seed], n_params: usize) -> Result<Gradient<'_>> {
        gradient(self, seeds, n_params)
    }
}

/// A layered stack prepared for its gradient alone (`prepare_gradient`): its table empty.
struct Unsolved(Prepared);

impl Differentiable for Unsolved {
    fn gradient(&self, seeds: &[Seed], n_params: usize) -> Result<Gradient<'_>> {
        gradient(&self.0, seeds, n_params)
    }
}

impl Model for Prepared {
    fn eval_block(&self, wi: [&[f64]; 3], wo: [&[f64]; 3], _inputs: &super::Inputs, out: &mut [f64]) {
        simd_columns!(Prepared, self, wi, wo, out)
    }

    fn eval_f32(&self, wi: Rows, wo: Rows, fit: Option<&FitLanes>, out: &mut [f32]) -> bool {
        self.lanes().is_some_and(|k| engine::eval(&k, fit, self.eta.len(), wi, wo, out))
    }

    fn sample_f32(&self, wo: Rows, u: Rows, out: &mut [f32]) -> bool {
        let Some(lanes) = self.lanes() else { return false };
        // The inner lobes, all rough.
        let lobes: Vec<Visible> = self.lobes.iter().filter_map(Visible::new).collect();
        if lobes.len() + 3 > MAX_TERMS {
            return false;
        }
        let below = self.albedo_below_top.iter().map(|&a| a as f32).collect();
        mixture_lanes::sample(&Sampled { lanes, lobes, below }, self.eta.len(), wo, u, out)
    }

    fn proposals(&self, wo: DVec3) -> Vec<(f64, Proposal)> {
        let (node, f) = node(zenith(wo.z), self.albedo_below_top.len());
        let below = (1.0 - f) * self.albedo_below_top[node] + f * self.albedo_below_top[node + 1];
        let mut terms: Vec<(f64, Proposal)> =
            self.top.iter().map(|mf| (fresnel::dielectric(wo.z, self.eta[0]), Proposal::Reflection(*mf))).collect();
        let share = below / self.lobes.len().max(1) as f64;
        terms.extend(self.lobes.iter().map(|mf| (share, Proposal::Reflection(*mf))));
        if self.lobes.is_empty() {
            terms.push((below, Proposal::Cosine));
        }
        defensive_mixture(terms)
    }

    fn specular(&self, wo: DVec3, out: &mut [f64]) {
        out.fill(0.0);
        if wo.z > 0.0 && self.top.is_none() {
            out.iter_mut().zip(&self.channels).for_each(|(o, s)| *o = s.dirac_reflectance(0, wo.z));
        }
    }
}

/// Why the table's solve does not differentiate by these seeds, if it does not: a roughness on one axis (an
/// anisotropic perturbation of an isotropic table); a conductor's roughness under Beckmann (whose visible normals are
/// found by Newton's method) or the V-cavity masking (which `Microfacet::g2` does not differentiate by moving
/// directions).
fn refused(stack: &Stack, surface: Microsurface, seeds: &[Seed]) -> Option<String> {
    let axis = |f: Field| matches!(f, Field::RoughnessX | Field::RoughnessY);
    for s in seeds {
        let why = match (&stack.layers[s.layer], surface.distribution, surface.g2) {
            _ if axis(s.field) && !seeds.contains(&Seed { field: other_axis(s.field), ..*s }) => {
                "on one axis (an isotropic table)"
            }
            (Layer::Conductor { .. }, Distribution::Beckmann, _) if axis(s.field) => {
                "a conductor's, with distribution='beckmann'"
            }
            (Layer::Conductor { .. }, _, G2Form::VCavity) if axis(s.field) => "a conductor's, with g2='v_cavity'",
            _ => continue,
        };
        return Some(format!("{} of layer {} ({}): {why}", s.field.name(), s.layer, stack.layers[s.layer].name()));
    }
    None
}

/// The other roughness axis.
fn other_axis(f: Field) -> Field {
    if f == Field::RoughnessX {
        Field::RoughnessY
    } else {
        Field::RoughnessX
    }
}

/// Whether a seed is a rough coat's IOR or roughness, which the gradient takes by central differences of the solve
/// (`differences`): seen from below (η < 1), the coat's Fresnel term has a square-root cusp at the critical angle, and
/// as α or η moves, the lattice's visible normals cross it; the energy that the solve normalises columns to then
/// turns jagged on fine scales (one cell's derivative measured −1.76 at a step of 1e-6, −0.92 at 1e-5, −0.66 at
/// 1e-4 and −0.557 at 1e-2), and the exact derivative of the discrete solve is useless for fitting.
fn differenced(stack: &Stack, s: &Seed) -> bool {
    matches!(&stack.layers[s.layer], Layer::Dielectric { alpha, .. } if *alpha != (0.0, 0.0))
        && matches!(s.field, Field::Ior | Field::RoughnessX | Field::RoughnessY)
}

/// The central differences' step, relative to the parameter: f's differences at steps from 1e-5 to 3e-2 of a rough
/// coat's η and α scatter by a few percent on every scale below 1e-2 (the cusp above), and its curvature makes a
/// truncation error of order step² (4e-4).
const DIFFERENCE_STEP: f64 = 2e-2;

/// f of the table `at(k)` (f less the top's reflection at the nodes), the top interface and the clear slab's depth
/// per channel at (wi, wo), as `eval` interpolates the table, in f64 or in Duals.
fn lookup<T: Real>(
    p: &Prepared,
    at: impl Fn(usize) -> T,
    tops: &[Interface<T>],
    depths: &[T],
    wi: DVec3,
    wo: DVec3,
) -> Vec<T> {
    let ch = p.eta.len();
    let mut f = vec![T::from(0.0); ch];
    if wi.z > 0.0 && wo.z > 0.0 {
        if p.top.is_some() {
            for (f, top) in f.iter_mut().zip(tops) {
                *f = rough_dielectric(&top.mf, p.g2, top.eta, wi, wo);
            }
        }
        let [(i, fi), (o, fo), (k, fp)] = coordinates(wi, wo);
        for (c, (f, top)) in f.iter_mut().zip(tops).enumerate() {
            let mut table = T::from(0.0);
            for (di, wi_) in [(0, 1.0 - fi), (1, fi)] {
                for (dj, wo_) in [(0, 1.0 - fo), (1, fo)] {
                    let n = (pair(i + di, o + dj) * N_PHI + k) * ch + c;
                    table = table + at(n) * (wi_ * wo_ * (1.0 - fp)) + at(n + ch) * (wi_ * wo_ * fp);
                }
            }
            if p.clear.is_some() {
                table = table * entering(wi.z, top.eta, depths[c]) * entering(wo.z, top.eta, depths[c]);
            }
            *f = *f + table;
        }
    }
    f
}

/// The table's values at the nodes (clipped at 0 as `tabulate` clips them), the top interface and the clear slab's
/// depth (`clear_depth`) per channel, of the channel stacks `channel(c)`, those of equal `key(c)` solved once.
struct Solved<T> {
    table: Vec<T>,
    tops: Vec<Interface<T>>,
    depths: Vec<T>,
}

fn solve<T: Real, K: PartialEq>(
    p: &Prepared,
    channel: impl Fn(usize) -> ChannelStack<T>,
    key: impl Fn(usize) -> K,
) -> Result<Solved<T>> {
    let clip = |f: T| if f.value() > 0.0 { f } else { T::from(0.0) };
    let table = node_values(p.stack.channels, &channel, key)?.into_iter().map(clip).collect();
    let stacks: Vec<ChannelStack<T>> = (0..p.stack.channels).map(channel).collect();
    let (tops, depths) = stacks.iter().map(|s| (s.interfaces[0], clear_depth(s))).unzip();
    Ok(Solved { table, tops, depths })
}

/// A parameter's central difference: its step h and the solves at the parameter + h and − h.
struct Difference {
    param: usize,
    h: f64,
    sides: [Solved<f64>; 2],
}

/// The central differences of the solve by each parameter that feeds `seeds`: every seed of the parameter moved by
/// ± scale × h together (a coat's IOR also moves the next interface's relative IOR).
fn differences(p: &Prepared, seeds: &[Seed]) -> Result<Vec<Difference>> {
    let mut params: Vec<usize> = seeds.iter().map(|s| s.param).collect();
    params.sort();
    params.dedup();
    params
        .into_iter()
        .map(|param| {
            let own: Vec<Seed> = seeds.iter().filter(|s| s.param == param).copied().collect();
            // The step relative to the parameter's value: the value the model sees over the seed's scale.
            let first = own[0];
            let v = std::cell::Cell::new(0.0);
            ChannelStack::with_values(&p.stack, first.channel.unwrap_or(0), p.surface, |l, field, x| {
                if (l, field) == (first.layer, first.field) {
                    v.set(x);
                }
                x
            });
            let h = DIFFERENCE_STEP * (v.get() / first.scale).abs();
            let side = |sign: f64| {
                let moved = |l, field, c: usize, x: f64| {
                    let on = |s: &&Seed| (s.layer, s.field) == (l, field) && s.channel.is_none_or(|k| k == c);
                    x + sign * h * own.iter().filter(on).map(|s| s.scale).sum::<f64>()
                };
                let channel =
                    |c| ChannelStack::with_values(&p.stack, c, p.surface, |l, field, x| moved(l, field, c, x));
                let key = |c| {
                    let shifts: Vec<f64> = own.iter().map(|s| moved(s.layer, s.field, c, 0.0)).collect();
                    (channel_key(&p.stack, c), shifts)
                };
                solve(p, channel, key)
            };
            Ok(Difference { param, h, sides: [side(1.0)?, side(-1.0)?] })
        })
        .collect()
}

/// f and its gradient (`Differentiable::gradient`): exact (`solved`) by every field but a rough coat's IOR and
/// roughness, whose derivatives are central differences of the solve (`differenced`, `differences`).
fn gradient<'a>(p: &'a Prepared, seeds: &[Seed], n: usize) -> Result<Gradient<'a>> {
    if let Some(why) = refused(&p.stack, p.surface, seeds) {
        return value_error(format!("model 'tabulated' has no gradient by {why}"));
    }
    if p.anisotropic {
        return value_error("model 'tabulated' has no gradients for anisotropic stacks (their solve is float64 only)");
    }
    // Every seed of a parameter that feeds a rough coat's IOR or roughness goes to the differences, the rest to the
    // Duals, whose parameters are numbered 0.. among themselves.
    let differenced: Vec<usize> = seeds.iter().filter(|s| differenced(&p.stack, s)).map(|s| s.param).collect();
    let (by_difference, in_duals): (Vec<Seed>, Vec<Seed>) = seeds.iter().partition(|s| differenced.contains(&s.param));
    let mut exact: Vec<usize> = in_duals.iter().map(|s| s.param).collect();
    exact.sort();
    exact.dedup();
    let renumbered: Vec<Seed> =
        in_duals.iter().map(|s| Seed { param: exact.partition_point(|&j| j < s.param), ..*s }).collect();
    // f with the exact derivatives from the Duals' solve; without exact parameters, f from the table `eval` reads,
    // or from the solve in f64 where there is none (`Unsolved`).
    let source = match exact.len() {
        0 if p.table.is_empty() => {
            F::Plain(solve(p, |c| ChannelStack::new(&p.stack, c, p.surface), |c| channel_key(&p.stack, c))?)
        }
        0 => F::Plain(Solved {
            table: p.table.iter().map(|&f| f as f64).collect(),
            tops: p.channels.iter().map(|s| s.interfaces[0]).collect(),
            depths: p.clear.clone().unwrap_or_default(),
        }),
        m => F::Duals(super::dual_width!(m, solved(p, &renumbered))?),
    };
    let differences = differences(p, &by_difference)?;
    Ok(Box::new(move |wi, wo, out| {
        let ch = p.eta.len();
        out.fill(0.0);
        match &source {
            F::Duals(solved) => {
                // The Duals' block, its m parameters moved to their places among the n.
                let m = exact.len();
                let mut own = vec![0.0; wi[0].len() * ch * (m + 1)];
                solved(wi, wo, &mut own);
                for (o, own) in out.chunks_exact_mut(ch * (n + 1)).zip(own.chunks_exact(ch * (m + 1))) {
                    for c in 0..ch {
                        o[c * (n + 1)] = own[c * (m + 1)];
                        for (k, &j) in exact.iter().enumerate() {
                            o[c * (n + 1) + 1 + j] = own[c * (m + 1) + 1 + k];
                        }
                    }
                }
            }
            F::Plain(s) => eval_rows(wi, wo, out, |_, wi, wo, o| {
                let f = lookup(p, |k| s.table[k], &s.tops, &s.depths, wi, wo);
                (0..ch).for_each(|c| o[c * (n + 1)] = f[c]);
            }),
        }
        eval_rows(wi, wo, out, |_, wi, wo, o| {
            for d in &differences {
                let [fa, fb] = d.sides.each_ref().map(|s| lookup(p, |k| s.table[k], &s.tops, &s.depths, wi, wo));
                (0..ch).for_each(|c| o[c * (n + 1) + 1 + d.param] = (fa[c] - fb[c]) / (2.0 * d.h));
            }
        });
    }))
}

/// Where `gradient` takes f from: the Duals' solve (with the exact derivatives), or a plain one.
enum F<'a> {
    Duals(Gradient<'a>),
    Plain(Solved<f64>),
}

/// f and its exact gradient by the parameters of `seeds` (numbered 0..N): the table solved again in Duals
/// (forward-mode adding-doubling: every projection, energy, product and solve carries the derivatives), f64
/// throughout, interpolated as `eval` interpolates the table, plus the top's reflection in Duals.
fn solved<'a, const N: usize>(p: &'a Prepared, seeds: &[Seed]) -> Result<Gradient<'a>> {
    let stack = &p.stack;
    let channel = |c: usize| {
        ChannelStack::with_values(stack, c, p.surface, |l, field, v| super::seeded::<N>(seeds, l, field, c, v))
    };
    // Channels of equal constants and equal seeds share a solve.
    let key = |c: usize| {
        let own = seeds.iter().filter(|s| s.channel.is_none_or(|k| k == c)).map(|s| Seed { channel: None, ..*s });
        (channel_key(stack, c), own.collect::<Vec<Seed>>())
    };
    let Solved { table, tops, depths } = solve(p, channel, key)?;
    Ok(per_pair(move |wi, wo, out| {
        for (c, f) in lookup(p, |k| table[k], &tops, &depths, wi, wo).into_iter().enumerate() {
            super::store(out, c, f);
        }
    }))
}

/// The GPU half (shaders/tabulated.wgsl): the same table, interpolated in float32. A single opaque boundary is
/// `microfacet`'s, as on the CPU.
#[cfg(feature = "gpu")]
pub mod gpu {
    use super::{microsurface, tabulate_stack};
    use crate::error::{value_error, Result};
    use crate::models::common::gpu::{g2_code, params, word, words, GpuHalf, GpuMicrofacet, Kernel};
    use crate::models::{microfacet, Args, Value};
    use crate::optics::distribution::{Distribution, Microfacet};
    use crate::stack::Stack;

    pub const HALF: GpuHalf =
        GpuHalf { shader: &[include_str!("../gpu/shaders/tabulated.wgsl")], refusal: |_| None, kernel };

    params! {
        /// tabulated.wgsl's `Params`.
        n: u32,
        channels: u32,
        g2: u32,
        has_top: u32,
        top: GpuMicrofacet,
        lobes: u32,
        pad0: u32,
        values_base: u32,
        lobes_at: u32,
        albedo_at: u32,
        table_base: u32,
    }

    /// The kernel: the parameters, the stack's values (the top's η per channel, the inner lobes, the albedo below the
    /// top per node) and its table; a single boundary's is microfacet's.
    fn kernel(stack: &Stack, args: &Args) -> Result<Kernel> {
        if stack.layers.len() == 1 {
            // microfacet takes the same microsurface options (and its exact Fresnel by default).
            let given: Vec<(String, Value)> =
                ["distribution", "g2"].iter().filter_map(|k| Some((k.to_string(), args.get(k)?.clone()))).collect();
            return (microfacet::gpu::HALF.kernel)(stack, &Args::parse(&microfacet::INFO, &given)?);
        }
        let surface = microsurface(args)?;
        if crate::tables::anisotropic::is_anisotropic(stack, surface) {
            return value_error(
                "model 'tabulated' on the GPU takes isotropic stacks; evaluate anisotropic ones on the CPU (device='cpu')",
            );
        }
        let p = tabulate_stack(stack, surface, true)?;
        let smooth = Microfacet::new(Distribution::Ggx, 0.0, 0.0, 0.0);
        let mut values: Vec<f32> = p.eta.iter().map(|&e| e as f32).collect();
        // The clear slab's depth per channel (read where the top is smooth).
        values.extend((0..p.eta.len()).map(|c| p.clear.as_ref().map_or(0.0, |d| d[c]) as f32));
        let lobes_at = values.len();
        for mf in &p.lobes {
            let m = GpuMicrofacet::from(mf);
            values.extend([m.dist as f32, m.smooth_ as f32, m.alpha_x, m.alpha_y, m.cos_phi, m.sin_phi]);
        }
        let albedo_at = values.len();
        values.extend(p.albedo_below_top.iter().map(|&a| a as f32));
        let params = Params {
            n: 0,
            channels: p.eta.len() as u32,
            g2: g2_code(p.g2),
            has_top: p.top.is_some() as u32,
            top: p.top.as_ref().unwrap_or(&smooth).into(),
            lobes: p.lobes.len() as u32,
            pad0: 0,
            values_base: 0,
            lobes_at: lobes_at as u32,
            albedo_at: albedo_at as u32,
            table_base: 0,
        };
        Ok(Kernel {
            shader: "tabulated",
            words: words(&params),
            count_word: word!(Params, n),
            channels: p.eta.len(),
            arrays: vec![(values, word!(Params, values_base)), (p.table, word!(Params, table_base))],
            tables: vec![],
            fit: None,
        })
    }

    #[cfg(test)]
    #[test]
    fn params_mirror_the_wgsl_struct() {
        crate::gpu::tests::assert_mirrors("tabulated", Params::FIELDS, std::mem::size_of::<Params>());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::eval_one;
    use crate::models::microfacet::smooth_coat_lambert;
    use crate::optics::distribution::{Distribution, G2Form};
    use crate::quadrature::gauss_legendre;

    #[test]
    fn the_zenith_node_in_lanes_is_exact_to_float32_at_both_ends() {
        // Float32 unit directions from the normal to the horizon (and below it): the lanes' coordinate (node plus
        // fraction; at a node either side) against the float64 one, within 3e-7 of a node at grazing angles
        // (cos θ < 0.1), where x (n − 1) ≈ 63 alone is stored to 3.8e-6, and within 4e-6 elsewhere.
        let mut worst = [0.0f64; 2];
        for k in 0..=4096 {
            let z = 1.0 - k as f64 / 4096.0 - if k == 4096 { 0.01 } else { 0.0 };
            let z = z.clamp(-1.0, 1.0).max(1e-7 * (k % 3) as f64);
            let w = [(1.0 - z * z).max(0.0).sqrt() as f32, 0.0, z as f32];
            let v = V3::splat(w);
            let (i, f) = zenith_node_lanes(v, NODES);
            assert!(f.0[0] >= 0.0 && f.0[0] <= 1.0 && i[0] as usize <= NODES - 2);
            let len = (w.iter().map(|&c| c as f64 * c as f64).sum::<f64>()).sqrt();
            let (j, g) = node(zenith(w[2] as f64 / len), NODES);
            let err = (i[0] as f64 + f.0[0] as f64 - (j as f64 + g)).abs();
            let at = if z < 0.1 { 0 } else { 1 };
            worst[at] = worst[at].max(err);
        }
        // Measured: 2.3e-7 and 2.7e-6 (float32's rounding of x itself at x ≈ ½, times 64 nodes).
        assert!(worst[0] < 3e-7 && worst[1] < 4e-6, "{worst:?}");
    }

    fn dielectric(ior: f64, alpha: f64, thickness: f64, sigma_s: f64) -> Layer {
        Layer::Dielectric {
            ior: vec![ior],
            alpha: (alpha, alpha),
            angle: 0.0,
            thickness,
            sigma_a: vec![0.0],
            sigma_s: vec![sigma_s],
            g: 0.5,
        }
    }

    fn model(layers: Vec<Layer>) -> Prepared {
        tabulate_stack(&Stack::new(layers, 1.0).unwrap(), crate::models::reference_surface(), true).unwrap()
    }

    fn dir(theta_deg: f64, phi_deg: f64) -> DVec3 {
        let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
        DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
    }

    fn f(m: &Prepared, wi: DVec3, wo: DVec3) -> f64 {
        let mut out = [0.0];
        eval_one(m, wi, wo, &[], &mut out);
        out[0]
    }

    /// The largest relative difference from `exact` over θi, θo ∈ {0, 10, …, max}° and φ ∈ {0, 45, …, 180}°.
    fn worst(m: &Prepared, max: usize, exact: impl Fn(DVec3, DVec3) -> f64) -> f64 {
        let mut worst: f64 = 0.0;
        for ti in (0..=max).step_by(10) {
            for to in (0..=max).step_by(10) {
                for phi in (0..=180).step_by(45) {
                    let (wi, wo) = (dir(ti as f64, 0.0), dir(to as f64, phi as f64));
                    worst = worst.max((f(m, wi, wo) / exact(wi, wo) - 1.0).abs());
                }
            }
        }
        worst
    }

    #[test]
    fn smooth_coat_over_lambert_is_its_closed_form() {
        // Exact (the series of inter-reflections in closed form). Measured: 1.3e-5 up to 80° (the solve's internal
        // diffuse reflectance); 0.52% before the table held f / (Āi Āo) (the cells' average Fresnel, interpolated).
        let m = model(vec![dielectric(1.5, 0.0, 0.0, 0.0), Layer::Diffuse { albedo: vec![0.8], roughness: 0.0 }]);
        let f_int = fresnel::diffuse_reflectance(1.0 / 1.5);
        let e = worst(&m, 80, |wi, wo| smooth_coat_lambert(0.8, 1.5, f_int, wi.z, wo.z));
        assert!(e < 3e-5, "{e}");
    }

    #[test]
    fn an_absorbing_smooth_coat_over_lambert_is_its_closed_form_up_to_grazing() {
        // f = ρ Ti To e^(−τ/μti − τ/μto) / (π η² (1 − ρ r̄)), r̄ = ∫ F_inside(μ) e^(−2τ/μ) 2μ dμ (total internal
        // reflection below μc). What enters through the top and the clear slab is factored out of the table
        // (`entering`): measured 1.8e-6 up to 89° at τ = 1. Before, the cells' Fresnel and Beer–Lambert averages,
        // interpolated: 1.6% at θ 75–85° and 53% beyond at τ = 0.3; with the Fresnel alone factored out, 3.5% at
        // τ = 2 (the Beer–Lambert averages of inside cells, into each of which refraction packs many outside ones).
        let (eta, tau, rho) = (1.5, 1.0, 0.7);
        let mut coat = dielectric(eta, 0.0, 0.5, 0.0);
        if let Layer::Dielectric { sigma_a, .. } = &mut coat {
            sigma_a[0] = 2.0 * tau;
        }
        let m = model(vec![coat, Layer::Diffuse { albedo: vec![rho], roughness: 0.0 }]);
        let mu_c = (1.0 - 1.0 / (eta * eta)).sqrt();
        let returned = |mu: f64, fresnel: f64| 2.0 * mu * fresnel * (-2.0 * tau / mu).exp();
        let r_bar = crate::quadrature::integrate(|mu| returned(mu, 1.0), 0.0, mu_c, 8)
            + crate::quadrature::integrate(|mu| returned(mu, fresnel::dielectric(mu, 1.0 / eta)), mu_c, 1.0, 8);
        let entering = |z: f64| {
            let mu_t = (1.0 - (1.0 - z * z) / (eta * eta)).sqrt();
            fresnel::dielectric_transmittance(z, eta) * (-tau / mu_t).exp()
        };
        let exact = |wi: DVec3, wo: DVec3| {
            rho * entering(wi.z) * entering(wo.z) / (std::f64::consts::PI * eta * eta * (1.0 - rho * r_bar))
        };
        let mut e: f64 = 0.0;
        for ti in [0.0, 30.0, 60.0, 75.0, 80.0, 85.0, 87.0, 89.0] {
            for to in [0.0, 45.0, 70.0, 78.0, 83.0, 86.0, 88.0, 89.0] {
                let (wi, wo) = (dir(ti, 0.0), dir(to, 135.0));
                e = e.max((f(&m, wi, wo) / exact(wi, wo) - 1.0).abs());
            }
        }
        assert!(e < 2e-5, "{e}");
    }

    #[test]
    fn an_index_matched_coat_shows_its_base() {
        // A coat of η = 1 does nothing: f is the rough conductor's (α = 0.3). Measured: 0.48% up to 70°; 4.3% at
        // θi = θo = 80° away from the mirror plane, where f is small and steep (interpolation).
        let base = Layer::Conductor { ior: vec![0.2], k: vec![3.0], alpha: (0.3, 0.3), angle: 0.0 };
        let m = model(vec![dielectric(1.0, 0.0, 0.0, 0.0), base.clone()]);
        let mf = base.microfacet(Distribution::Ggx).unwrap();
        let exact = |wi, wo| crate::bsdf::rough_conductor(&mf, G2Form::HeightCorrelated, 0.2, 3.0, wi, wo);
        let (e70, e80) = (worst(&m, 70, exact), worst(&m, 80, exact));
        assert!(e70 < 0.006 && e80 < 0.05, "{e70} {e80}");
    }

    #[test]
    fn a_smooth_coat_under_an_index_matched_one_is_a_dirac_lobe_and_its_closed_form() {
        // A smooth top of η = 1 over a smooth coat of η = 1.5 over Lambert is that coat alone: the coat's mirror
        // reflection is a Dirac lobe (`specular`, exact), and f is the closed form even in the mirror direction,
        // which the table once blurred the Dirac lobe into. Measured: 0.52%, as the coat alone.
        let lambert = Layer::Diffuse { albedo: vec![0.8], roughness: 0.0 };
        let m = model(vec![dielectric(1.0, 0.0, 0.0, 0.0), dielectric(1.5, 0.0, 0.0, 0.0), lambert]);
        let f_int = fresnel::diffuse_reflectance(1.0 / 1.5);
        let e = worst(&m, 80, |wi, wo| smooth_coat_lambert(0.8, 1.5, f_int, wi.z, wo.z));
        assert!(e < 0.006, "{e}");
        for t in [0.0, 40.0, 80.0] {
            let mut dirac = [0.0];
            m.specular(dir(t, 0.0), &mut dirac);
            assert!((dirac[0] - fresnel::dielectric(dir(t, 0.0).z, 1.5)).abs() < 1e-12, "{t}°: {dirac:?}");
        }
    }

    #[test]
    fn the_dirac_reflection_sums_the_inter_reflections_between_smooth_boundaries() {
        // A lossless clear coat over a perfect mirror returns everything as a Dirac lobe, total internal reflection
        // included (η = 0.8 below 1.5); an absorbing coat attenuates the mirror's reflection e^{−2τ/μt} per bounce.
        let mirror = Layer::Conductor { ior: vec![1.0], k: vec![1e9], alpha: (0.0, 0.0), angle: 0.0 };
        let lossless = model(vec![dielectric(1.5, 0.0, 1.0, 0.0), dielectric(1.2, 0.0, 1.0, 0.0), mirror.clone()]);
        let mut absorbing = dielectric(1.0, 0.0, 0.5, 0.0);
        if let Layer::Dielectric { sigma_a, .. } = &mut absorbing {
            sigma_a[0] = 0.4;
        }
        let attenuated = model(vec![absorbing, mirror]);
        for t in [0.0, 30.0, 60.0, 85.0] {
            let (mut r, mut a) = ([0.0], [0.0]);
            lossless.specular(dir(t, 0.0), &mut r);
            attenuated.specular(dir(t, 0.0), &mut a);
            let mu = dir(t, 0.0).z;
            assert!((r[0] - 1.0).abs() < 1e-8, "{t}°: {r:?}");
            assert!((a[0] - (-2.0 * 0.2 / mu).exp()).abs() < 1e-8, "{t}°: {a:?}");
        }
    }

    #[test]
    fn a_lossless_stack_reflects_everything() {
        // Over a white Lambertian base, lossless stacks reflect all they receive: the light albedo ∫ f cos θo dωo
        // plus the Dirac reflection (`specular`) is 1. A smooth coat over a scattering slab (doubling and adding
        // conserve energy), and two smooth coats of η 1.488 over 1.4, between which light beyond 70° in the upper
        // one is trapped by total internal reflection at both (its table was once 0: NaN clipped).
        let white = || Layer::Diffuse { albedo: vec![1.0], roughness: 0.0 };
        let stacks = [
            vec![dielectric(1.5, 0.0, 1.0, 2.0), white()],
            vec![dielectric(1.488, 0.0, 1.0, 0.0), dielectric(1.4, 0.0, 1.0, 0.0), white()],
        ];
        let (gl, n_phi) = (gauss_legendre(48), 96);
        for layers in stacks {
            let m = model(layers);
            for ti in [0.0, 30.0, 60.0, 80.0] {
                let wi = dir(ti, 0.0);
                let mut albedo = [0.0];
                m.specular(wi, &mut albedo);
                for &(x, w) in &gl {
                    let mu: f64 = 0.5 * (x + 1.0);
                    for p in 0..n_phi {
                        let phi = (p as f64 + 0.5) * 360.0 / n_phi as f64;
                        let wo = dir(mu.acos().to_degrees(), phi);
                        albedo[0] += 0.5 * w * mu * f(&m, wi, wo) * std::f64::consts::TAU / n_phi as f64;
                    }
                }
                // Measured: 0.9986 to 1.0003 (the coat over the slab), 0.9994 to 1.0003 (the two coats).
                assert!((albedo[0] - 1.0).abs() < 0.004, "θi = {ti}°: {}", albedo[0]);
            }
        }
    }

    /// Σ|a − b| / Σ|a| over θo ∈ {0, 5, …, 80}°, φo ∈ {0, 15, …, 345}° at wi = (θi, 20°), of a pair of functions.
    fn lobe_error(ti: f64, both: impl Fn(DVec3, DVec3) -> (f64, f64)) -> f64 {
        let (mut diff, mut total) = (0.0, 0.0);
        for to in (0..=80).step_by(5) {
            for phi in (0..360).step_by(15) {
                let (a, b) = both(dir(ti, 20.0), dir(to as f64, phi as f64));
                (diff, total) = (diff + (a - b).abs(), total + a.abs());
            }
        }
        diff / total
    }

    fn aniso_conductor(alpha: (f64, f64), angle: f64) -> Layer {
        Layer::Conductor { ior: vec![1.2], k: vec![6.9], alpha, angle }
    }

    fn aniso_coat(alpha: (f64, f64), angle: f64) -> Layer {
        let (ior, sigma_a, sigma_s) = (vec![1.5], vec![0.0], vec![0.0]);
        Layer::Dielectric { ior, alpha, angle, thickness: 0.0, sigma_a, sigma_s, g: 0.0 }
    }

    #[test]
    fn the_anisotropic_solver_in_the_isotropic_limit_is_the_isotropic_one() {
        // Isotropic stacks through tables::anisotropic (its coarser grid: 32 cells, 96 azimuth bins) against the
        // isotropic solver, lobe error of the table part at θi ∈ {0, 10, 30, 60, 80}°: every boundary from the
        // isotropic solver (coat over Lambert, measured 0.02-0.13%; smooth coat over a rough conductor, 0.25-0.84%),
        // and a coat of roughness (0.3, 0.3003), projected on the grid (0.05-0.27%).
        let lambert = || Layer::Diffuse { albedo: vec![0.6], roughness: 0.0 };
        let rough_conductor = Layer::Conductor { ior: vec![0.2], k: vec![3.0], alpha: (0.3, 0.3), angle: 0.0 };
        let cases = [
            (vec![dielectric(1.5, 0.3, 0.0, 0.0), lambert()], 0.002),
            (vec![dielectric(1.5, 0.0, 0.0, 0.0), rough_conductor], 0.01),
            (vec![aniso_coat((0.3, 0.3003), 0.4), lambert()], 0.004),
        ];
        for (layers, bound) in cases {
            let stack = Stack::new(layers, 1.0).unwrap();
            let iso = stack.layers.iter().map(|l| match l {
                Layer::Dielectric { alpha, .. } if alpha.0 != alpha.1 => dielectric(1.5, alpha.0, 0.0, 0.0),
                l => l.clone(),
            });
            let iso =
                tabulate_stack(&Stack::new(iso.collect(), 1.0).unwrap(), crate::models::reference_surface(), true);
            let (iso, surface) = (iso.unwrap(), crate::models::reference_surface());
            let table = anisotropic::tabulate(&stack, surface).unwrap();
            let both = |wi, wo| {
                let top = iso.top.map_or(0.0, |mf| rough_dielectric(&mf, iso.g2, iso.eta[0], wi, wo));
                let mut a = 0.0;
                anisotropic::interpolate(&table, wi, wo, |_, v| a += v as f64, 1);
                (f(&iso, wi, wo) - top, a)
            };
            for ti in [0.0, 10.0, 30.0, 60.0, 80.0] {
                let e = lobe_error(ti, both);
                assert!(e < bound, "{:?}, θi = {ti}: {e}", stack.layers[1]);
            }
        }
    }

    #[test]
    fn an_index_matched_coat_over_an_anisotropic_conductor_shows_the_conductor() {
        // A smooth coat of η = 1 does nothing: f is the anisotropic rough conductor's (α = (0.4, 0.15) along 29°), as
        // the grid resolves it. Measured lobe error: 1.3% at θi = 0, 0.7% at 10° and 30°, 2.2% at 60°, 5.0% at 80°
        // (its azimuth bins of 3.75° against a lobe 0.15 wide; 6.6% and 12% with 5.6° bins).
        let base = aniso_conductor((0.4, 0.15), 0.5);
        let m = model(vec![dielectric(1.0, 0.0, 0.0, 0.0), base.clone()]);
        assert!(m.anisotropic);
        let mf = base.microfacet(Distribution::Ggx).unwrap();
        let exact = |wi, wo| crate::bsdf::rough_conductor(&mf, G2Form::HeightCorrelated, 1.2, 6.9, wi, wo);
        for (ti, bound) in [(0.0, 0.015), (10.0, 0.01), (30.0, 0.01), (60.0, 0.025), (80.0, 0.055)] {
            let e = lobe_error(ti, |wi, wo| (exact(wi, wo), f(&m, wi, wo)));
            assert!(e < bound, "θi = {ti}: {e}");
        }
    }

    #[test]
    fn a_rotated_anisotropic_stack_is_the_stack_seen_from_rotated_directions() {
        // Turning every layer's tangent frame by three azimuth bins turns the table by three bins: f of the turned
        // stack at turned directions is f, to float32 (measured 2e-7).
        let layers = |turn: f64| vec![aniso_coat((0.1, 0.4), 0.5 + turn), aniso_conductor((0.35, 0.08), -0.4 + turn)];
        let (a, b) = (model(layers(0.0)), model(layers(3.0 * anisotropic::DPHI)));
        let turn = |w: DVec3| glam::DQuat::from_rotation_z(3.0 * anisotropic::DPHI) * w;
        let mut worst: f64 = 0.0;
        for k in 0..500 {
            let (wi, wo) =
                (dir((k * 37 % 85) as f64, (k * 71 % 360) as f64), dir((k * 13 % 85) as f64, (k * 7) as f64));
            let (x, y) = (f(&a, wi, wo), f(&b, turn(wi), turn(wo)));
            worst = worst.max((x - y).abs() / x.abs().max(1e-3));
        }
        assert!(worst < 2e-6, "{worst}");
    }

    #[test]
    fn anisotropic_tables_are_reciprocal() {
        // f(wi, wo) = f(wo, wi), to float32: the table is stored reciprocal, and its interpolation keeps it so
        // (measured 1.2e-7 relative). A rough anisotropic coat over Lambert, directions over the whole hemisphere.
        let lambert = Layer::Diffuse { albedo: vec![0.8], roughness: 0.0 };
        let m = model(vec![aniso_coat((0.08, 0.3), 0.7), lambert]);
        for k in 0..2000 {
            let (wi, wo) =
                (dir((k * 37 % 89) as f64, (k * 71 % 360) as f64), dir((k * 13 % 89) as f64, (k * 7) as f64));
            let (x, y) = (f(&m, wi, wo), f(&m, wo, wi));
            assert!((x - y).abs() <= 1e-6 * x.abs().max(1e-2), "{wi} {wo}: {x} {y}");
        }
    }
}
