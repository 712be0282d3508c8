//! The batch renderer: material balls (and swatches) of layer stacks under directional, point and environment
//! lights, shaded by any model of the catalogue or by the Monte Carlo reference. One ray per pixel centre; rayon
//! over rows. Returns linear RGB radiance.
//!
//! Camera contract (orthographic, the default): the viewer looks along −z from +z; the image spans [−1, 1]², pixel
//! (i, j) has its centre at x = (i + ½)/W·2 − 1, y = 1 − (j + ½)/H·2. On the unit sphere the shading frame is
//! n = the surface point, t = normalize(ŷ × n), b = n × t, so anisotropic layers streak horizontally. Directions
//! are passed to the models in that frame (docs/conventions.md).
//!
//! Integrator: directional and point lights are evaluated exactly, Σ f(l, v) max(0, n·l) E, without noise. An
//! environment adds `spp` samples per pixel, each one light sample (`env.rs`) and one BSDF sample (models/common/mixture.rs)
//! combined by the power heuristic (Veach 1997 §9.2), plus the model's Dirac reflection of the map. The reference
//! estimates f by `reference::estimate_f` for each light and the environment by random walks from the viewer.

pub mod env;
pub mod io;
pub mod mesh;

use crate::error::Result;
use crate::models::common::mixture::{mixture_pdf, sample_mixture, weight_factor};
use crate::models::{eval_fan, Model, MAX_INPUTS};
use crate::optics::reflect;
use crate::reference::{estimate_f, trace, Exit};
use crate::sampling::{power_heuristic, Rng};
use crate::transport::ChannelStack;
use env::Environment;
use glam::DVec3;
use mesh::Mesh;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// What the camera looks at.
pub enum Shape {
    /// The unit sphere at the origin.
    Sphere,
    /// The square [−1, 1]² of the plane z = 0, facing +z, tangent x̂.
    Plane,
    /// A user's triangle mesh.
    Mesh(Mesh),
}

#[derive(Clone, Copy, Debug)]
pub enum Camera {
    /// The contract above.
    Orthographic,
    /// A pinhole at `origin` looking at `target` with +y up and vertical field of view `fov` (radians).
    Perspective { origin: DVec3, target: DVec3, fov: f64 },
}

#[derive(Clone, Copy, Debug)]
pub enum Light {
    /// Towards the light (unit), and the irradiance it gives a surface facing it.
    Directional { direction: DVec3, irradiance: [f64; 3] },
    /// Position and radiant intensity: irradiance intensity / r² at distance r.
    Point { position: DVec3, intensity: [f64; 3] },
}

/// How a lookup outside [0, 1)² reads a texture.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Border {
    Clamp,
    Wrap,
}

impl Border {
    /// The names `from_str` reads, in the order of `ALL`.
    pub const NAMES: [&'static str; 2] = ["clamp", "wrap"];
    pub const ALL: [Border; 2] = [Border::Clamp, Border::Wrap];
}

impl std::str::FromStr for Border {
    type Err = crate::error::Error;
    fn from_str(s: &str) -> Result<Self> {
        crate::error::parse_choice("border", s, &Self::NAMES, &Self::ALL)
    }
}

/// Values over the surface, looked up by uv: u along the columns, v along the rows (row 0 at v = 0), texel (i, j)
/// centred at ((i + ½)/W, (j + ½)/H).
pub struct Texture {
    pub width: usize,
    pub height: usize,
    /// 1 or 3 values per texel, row-major.
    pub comps: usize,
    pub data: Vec<f64>,
}

impl Texture {
    /// The nearest texel, wrapping (per-element inputs of the models).
    fn lookup(&self, uv: [f64; 2]) -> [f64; 3] {
        let i = ((uv[0].rem_euclid(1.0) * self.width as f64) as usize).min(self.width - 1);
        let j = ((uv[1].rem_euclid(1.0) * self.height as f64) as usize).min(self.height - 1);
        self.texel(i, j)
    }

    fn texel(&self, i: usize, j: usize) -> [f64; 3] {
        let k = (j * self.width + i) * self.comps;
        std::array::from_fn(|c| if c < self.comps { self.data[k + c] } else { 0.0 })
    }

    /// Bilinear interpolation between the four nearest texel centres.
    pub fn bilinear(&self, uv: [f64; 2], border: Border) -> [f64; 3] {
        let index = |x: f64, n: usize| -> ([usize; 2], f64) {
            let f = x * n as f64 - 0.5;
            let (i, t) = (f.floor(), f - f.floor());
            let at = |i: f64| match border {
                Border::Clamp => i.clamp(0.0, (n - 1) as f64) as usize,
                Border::Wrap => i.rem_euclid(n as f64) as usize % n,
            };
            ([at(i), at(i + 1.0)], t)
        };
        let ([i0, i1], tx) = index(uv[0], self.width);
        let ([j0, j1], ty) = index(uv[1], self.height);
        let (a, b, c, d) = (self.texel(i0, j0), self.texel(i1, j0), self.texel(i0, j1), self.texel(i1, j1));
        std::array::from_fn(|k| (1.0 - ty) * ((1.0 - tx) * a[k] + tx * b[k]) + ty * ((1.0 - tx) * c[k] + tx * d[k]))
    }
}

/// A surface that shades itself from the scene's directional and point lights by its own technique (Oat 2006's
/// gooey layers, src/oat): the radiance towards the viewer (wo_world, world frame) at a hit.
pub trait Surface: Send + Sync {
    fn shade(&self, lights: &[Light], hit: &Hit, wo_world: DVec3) -> [f64; 3];
}

/// How a material is shaded: a prepared model with its per-element inputs as textures (in the order of the
/// model's inputs), the reference (one walk setup per RGB channel), or a surface of its own technique.
pub enum Shader {
    Model { model: Arc<dyn Model>, textures: Vec<Option<Texture>> },
    Reference(Vec<ChannelStack>),
    Surface(Arc<dyn Surface>),
}

pub struct Scene {
    pub shape: Shape,
    pub camera: Camera,
    pub lights: Vec<Light>,
    pub env: Option<Environment>,
    pub width: usize,
    pub height: usize,
    pub spp: usize,
    pub seed: u64,
}

/// A surface point: position, shading normal and tangent, and texture coordinates.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    pub p: DVec3,
    pub n: DVec3,
    pub t: DVec3,
    pub uv: [f64; 2],
}

impl Scene {
    /// The camera ray through the centre of pixel (i, j): origin and unit direction.
    pub fn ray(&self, i: usize, j: usize) -> (DVec3, DVec3) {
        let x = (i as f64 + 0.5) / self.width as f64 * 2.0 - 1.0;
        let y = 1.0 - (j as f64 + 0.5) / self.height as f64 * 2.0;
        match self.camera {
            Camera::Orthographic => (DVec3::new(x, y, 10.0), DVec3::NEG_Z),
            Camera::Perspective { origin, target, fov } => {
                let [forward, right, up] = pinhole(origin, target, fov, self.width as f64 / self.height as f64);
                (origin, (forward + x * right + y * up).normalize())
            }
        }
    }

    /// The first surface point along the ray, if any.
    pub fn intersect(&self, o: DVec3, d: DVec3) -> Option<Hit> {
        match &self.shape {
            Shape::Mesh(mesh) => mesh.intersect(o, d),
            Shape::Sphere => {
                // |o + s d|² = 1 with |d| = 1: the nearer root in front of the origin.
                let b = o.dot(d);
                let disc = b * b - (o.length_squared() - 1.0);
                if disc < 0.0 {
                    return None;
                }
                let s = [-b - disc.sqrt(), -b + disc.sqrt()].into_iter().find(|&s| s > 1e-9)?;
                let n = (o + s * d).normalize();
                let t = DVec3::Y.cross(n).try_normalize().unwrap_or(DVec3::X);
                let uv =
                    [0.5 + n.x.atan2(n.z) / std::f64::consts::TAU, n.y.clamp(-1.0, 1.0).acos() / std::f64::consts::PI];
                Some(Hit { p: n, n, t, uv })
            }
            Shape::Plane => {
                if d.z.abs() < 1e-12 {
                    return None;
                }
                let s = -o.z / d.z;
                let p = o + s * d;
                (s > 1e-9 && p.x.abs() <= 1.0 && p.y.abs() <= 1.0).then_some(Hit {
                    p,
                    n: DVec3::Z,
                    t: DVec3::X,
                    uv: [0.5 * (p.x + 1.0), 0.5 * (1.0 - p.y)],
                })
            }
        }
    }
}

/// A pinhole camera's forward, right and up vectors (+y up), right and up scaled by tan(fov/2) times the aspect and
/// by tan(fov/2): the ray through image point (x, y) ∈ [−1, 1]² is normalize(forward + x right + y up).
pub fn pinhole(origin: DVec3, target: DVec3, fov: f64, aspect: f64) -> [DVec3; 3] {
    let forward = (target - origin).normalize();
    let right = forward.cross(DVec3::Y).normalize();
    let h = (0.5 * fov).tan();
    [forward, right * h * aspect, right.cross(forward) * h]
}

/// The lights' directions and irradiances at the point p (towards the light, world frame).
pub(crate) fn incident(lights: &[Light], p: DVec3) -> impl Iterator<Item = (DVec3, [f64; 3])> + '_ {
    lights.iter().map(move |l| match *l {
        Light::Directional { direction, irradiance } => (direction, irradiance),
        Light::Point { position, intensity } => {
            let r2 = (position - p).length_squared().max(1e-12);
            ((position - p).normalize(), intensity.map(|i| i / r2))
        }
    })
}

/// Radiance towards the viewer at a hit: wo_world points to the viewer.
fn shade(scene: &Scene, shader: &Shader, hit: &Hit, wo_world: DVec3, rng: &mut Rng) -> [f64; 3] {
    let b = hit.n.cross(hit.t);
    let local = |d: DVec3| DVec3::new(d.dot(hit.t), d.dot(b), d.dot(hit.n));
    let world = |l: DVec3| l.x * hit.t + l.y * b + l.z * hit.n;
    let wo = local(wo_world);
    let mut radiance = [0.0; 3];
    if wo.z <= 0.0 {
        return radiance;
    }
    let spp = scene.spp.max(1) as f64;
    match shader {
        Shader::Model { model, textures } => {
            let inputs: Vec<Option<[f64; 3]>> = textures.iter().map(|t| t.as_ref().map(|t| t.lookup(hit.uv))).collect();
            debug_assert!(inputs.len() <= MAX_INPUTS);
            // Every direction to evaluate f at, with what multiplies f there (light, cosine, MIS weight / pdf); then
            // one evaluation of them all, in blocks.
            let mut wis: Vec<DVec3> = Vec::with_capacity(scene.lights.len() + 2 * scene.spp);
            let mut scales: Vec<[f64; 3]> = Vec::with_capacity(wis.capacity());
            let mut push = |wi: DVec3, light: [f64; 3], scale: f64| {
                wis.push(wi);
                scales.push(light.map(|l| l * scale));
            };
            for (l, e) in incident(&scene.lights, hit.p) {
                let wi = local(l);
                if wi.z > 0.0 {
                    push(wi, e, wi.z);
                }
            }
            if let Some(env) = &scene.env {
                let mut spec = [0.0; 3];
                model.specular(wo, &mut spec);
                let l = env.radiance(world(reflect(wo, DVec3::Z)));
                (0..3).for_each(|c| radiance[c] += spec[c] * l[c]);
                let lobes = model.proposals(wo);
                for _ in 0..scene.spp.max(1) {
                    let (d, l, p_light) = env.sample(rng.uniform(), rng.uniform());
                    let wi = local(d);
                    if wi.z > 0.0 && p_light > 0.0 {
                        let w = power_heuristic(p_light, mixture_pdf(&lobes, wi, wo));
                        push(wi, l, wi.z * w / (p_light * spp));
                    }
                    let (wi, p_bsdf) = sample_mixture(&lobes, wo, [rng.uniform(), rng.uniform(), rng.uniform()]);
                    if p_bsdf > 0.0 {
                        let d = world(wi);
                        let w = power_heuristic(p_bsdf, env.pdf(d));
                        push(wi, env.radiance(d), weight_factor(wi, p_bsdf) * w / spp);
                    }
                }
            }
            let mut f = vec![[0.0; 3]; wis.len()];
            eval_fan(&**model, wo, &inputs, &wis, &mut f);
            for (f, s) in f.iter().zip(&scales) {
                (0..3).for_each(|c| radiance[c] += f[c] * s[c]);
            }
        }
        Shader::Surface(surface) => return surface.shade(&scene.lights, hit, wo_world),
        Shader::Reference(channels) => {
            let mut targets = Vec::new();
            for (l, e) in incident(&scene.lights, hit.p) {
                let wi = local(l);
                if wi.z <= 0.0 {
                    continue;
                }
                for (c, s) in channels.iter().enumerate() {
                    let sum: f64 = (0..scene.spp.max(1)).filter_map(|_| estimate_f(s, wi, wo, rng, &mut targets)).sum();
                    radiance[c] += sum / spp * wi.z * e[c];
                }
            }
            let Some(env) = &scene.env else { return radiance };
            for (c, s) in channels.iter().enumerate() {
                for _ in 0..scene.spp.max(1) {
                    if let Exit::Escaped { dir, weight } = trace(s, wo, rng) {
                        radiance[c] += weight * env.radiance(world(dir))[c] / spp;
                    }
                }
            }
        }
    }
    radiance
}

/// Renders image rows `first..first + out.len() / (shaders.len() · 3 W)` of every material: `out` holds, per shader,
/// those rows of W pixels of RGB. Pixel streams are seeded by (seed, i, j) only, so every material sees the same
/// light samples and the result does not depend on the thread count or the row range. Interrupted when asked to stop
/// (interrupt.rs), checked row by row.
pub fn render_rows(scene: &Scene, shaders: &[Shader], first: usize, out: &mut [f32]) -> Result<()> {
    let w = scene.width;
    let rows = out.len() / (shaders.len().max(1) * 3 * w);
    let stopped = AtomicBool::new(false);
    out.par_chunks_mut(3 * w).enumerate().for_each(|(r, line)| {
        if crate::interrupt::requested() {
            stopped.store(true, Ordering::Relaxed); // rows are missing: the render is Interrupted
            return;
        }
        let (k, j) = (r / rows, first + r % rows);
        for (i, px) in line.chunks_exact_mut(3).enumerate() {
            let (o, d) = scene.ray(i, j);
            let rgb = match scene.intersect(o, d) {
                Some(hit) => {
                    let mut rng = Rng::new(Rng::seed_for(scene.seed, &[i as f64, j as f64]), 0);
                    shade(scene, &shaders[k], &hit, -d, &mut rng)
                }
                None => scene.env.as_ref().map_or([0.0; 3], |e| e.radiance(d)),
            };
            px.iter_mut().zip(rgb).for_each(|(p, v)| *p = v as f32);
        }
    });
    if stopped.load(Ordering::Relaxed) {
        return Err(crate::error::Error::Interrupted);
    }
    Ok(())
}
