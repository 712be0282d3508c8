//! The wgpu path: the models and the renderer as WGSL compute shaders, in float32. The WGSL primitives
//! (`shaders/optics.wgsl`, `sample.wgsl`) mirror the Rust ones function by function. Each model's GPU half
//! (models/common/gpu.rs: its WGSL, its `Params` as a `#[repr(C)]` struct that mirrors the WGSL struct, the kernel it
//! builds from its own prepared model, the rule of which options run here) is found from its catalogue entry and
//! composed after them (`compose`). `cargo test` validates every composed shader with naga and holds each `Params` to
//! its WGSL struct, without a GPU; tests/test_gpu.py checks parity with the CPU on a real adapter (lavapipe in CI).
//!
//! - `device`: the adapter and its device (created on first use and again after it is lost), pipelines compiled on
//!   first use, what lives on the device, and errors as values that name the device and the work;
//! - `dispatch`: per-element queries (eval, sample, pdf) in dispatches of at most CHUNK pairs, each kernel prepared
//!   once per stack and options and kept with its arrays on the device, the shared tables uploaded once per device;
//! - `render`: a batch of stacks in one dispatch on the sphere, the plane and meshes (rasterized by raster.wgsl), under
//!   directional and point lights and environments (env.wgsl, with the models' sampling mixtures); src/oat/gpu.rs
//!   renders Oat's materials with the same helpers.
//!
//! `refusal` is the one rule of what does not run here.

mod device;
mod dispatch;
mod render;

pub use crate::models::common::gpu::Kernel;
pub(crate) use device::{
    buffer, bytes, compute_module, compute_pipeline, dispatch, finish, group, init, scoped, Gpu, Res,
};
pub use device::{gpu, lose_after};
pub use dispatch::{readback_seconds, resident_seconds, run};
pub use render::{light_rows, render, Scene};
pub(crate) use render::{rasterize, scene_buffers};

use crate::error::{value_error, Error, Result};
use crate::models::common::gpu::GpuHalf;
use crate::models::{Args, ModelInfo, Value, CATALOGUE};
use crate::stack::Stack;

/// The shared primitives.
pub const OPTICS: &str = include_str!("shaders/optics.wgsl");
/// The renderer's scene: camera, shapes and lights, composed before the kernels that render it.
pub const SCENE: &str = include_str!("shaders/scene.wgsl");
/// The renderer's deterministic kernels, composed after a model and SCENE.
pub const RENDER: &str = include_str!("shaders/render.wgsl");
/// The renderer's environment-lit kernels, composed after RENDER.
pub const ENV: &str = include_str!("shaders/env.wgsl");
/// Importance sampling (the models' mixtures), composed after OPTICS.
pub const SAMPLE: &str = include_str!("shaders/sample.wgsl");
/// The per-element inputs as textures, composed before each model.
pub const INPUTS: &str = include_str!("shaders/inputs.wgsl");
/// The per-element kernels (eval, sample, pdf), composed after each model.
pub const QUERIES: &str = include_str!("shaders/queries.wgsl");
/// lamina's correction transport_fit for every model, composed after the model.
pub const FIT: &str = include_str!("shaders/fit.wgsl");
/// Triangle meshes, composed after SCENE.
pub const MESH: &str = include_str!("shaders/mesh.wgsl");
/// The mesh's rasterization into visibility targets, composed after MESH.
pub const RASTER: &str = include_str!("shaders/raster.wgsl");
/// The render kernels (render.wgsl, env.wgsl): for the sphere or plane and for a mesh, deterministic, then under an
/// environment.
pub(crate) const RENDER_KERNELS: [&str; 4] = ["render", "render_mesh", "render_env", "render_mesh_env"];

/// The catalogue's entries with a GPU half, with their index in CATALOGUE (which indexes the pipelines).
fn halves() -> impl Iterator<Item = (usize, &'static ModelInfo, &'static GpuHalf)> {
    CATALOGUE.iter().enumerate().filter_map(|(k, m)| Some((k, *m, m.gpu?)))
}

/// The models with a GPU half, in catalogue order.
pub fn models() -> Vec<&'static str> {
    halves().map(|(_, m, _)| m.name).collect()
}

/// `model`'s catalogue index and GPU half, or the error naming the models that have one.
fn half(model: &str) -> Result<(usize, &'static GpuHalf)> {
    halves().find(|(_, m, _)| m.name == model).map(|(k, _, h)| (k, h)).ok_or_else(|| unsupported(model))
}

/// A model's complete shader source: the primitives and sampling, the model, and its per-element kernels.
pub fn compose(model: &str) -> Option<String> {
    let (_, h) = half(model).ok()?;
    Some(format!("{OPTICS}\n{SAMPLE}\n{INPUTS}\n{}\n{FIT}\n{QUERIES}", h.shader.join("\n")))
}

/// The rasterization shader: the primitives, the scene, the mesh and raster.wgsl.
pub fn compose_raster() -> String {
    format!("{OPTICS}\n{SCENE}\n{MESH}\n{RASTER}")
}

/// A model's render shader: the model, the scene, the mesh and the render kernels, deterministic and
/// environment-lit.
pub fn compose_render(model: &str) -> Option<String> {
    compose(model).map(|m| format!("{m}\n{SCENE}\n{MESH}\n{RENDER}\n{ENV}"))
}

/// What a per-element dispatch of a model computes (shaders/queries.wgsl): f(wi, wo) (`main`), a sample for (wo, u)
/// (`sample_main`) or the pdf of (wi, wo) (`pdf_main`).
#[derive(Clone, Copy)]
pub enum Query {
    Eval,
    Sample,
    Pdf,
}

impl Query {
    fn entry(self) -> &'static str {
        match self {
            Query::Eval => "main",
            Query::Sample => "sample_main",
            Query::Pdf => "pdf_main",
        }
    }

    /// Values written per element: f per channel; wi, the weight per channel and the pdf; the pdf.
    pub fn width(self, channels: usize) -> usize {
        match self {
            Query::Eval => channels,
            Query::Sample => channels + 4,
            Query::Pdf => 1,
        }
    }
}

/// Why `model` with `args` does not run on the GPU, or None when it does: the one rule behind every `device=` choice
/// (device.rs) and every GPU kernel.
pub fn refusal(model: &str, args: &Args) -> Option<String> {
    match half(model) {
        Ok((_, h)) => (h.refusal)(args),
        Err(e) => Some(e.to_string()),
    }
}

/// The catalogue's word on `model` on the GPU (the README's model table): "yes", "yes, but not" with the option
/// values its half refuses (found by asking `refusal` of each), or "no" (the Monte Carlo reference).
pub fn support(model: &str) -> String {
    let Ok((k, h)) = half(model) else {
        return "no".into();
    };
    let info = CATALOGUE[k];
    let shown = |v: &Value| match v {
        Value::Flag(b) => if *b { "True" } else { "False" }.to_string(),
        Value::Text(t) => format!("'{t}'"),
        other => format!("{other:?}"),
    };
    let refused: Vec<String> = info
        .options
        .iter()
        .flat_map(|o| o.others().into_iter().map(move |v| (o.name, v)))
        .filter(|(name, v)| {
            Args::parse(info, &[(name.to_string(), v.clone())]).is_ok_and(|args| (h.refusal)(&args).is_some())
        })
        .map(|(name, v)| format!("{name}={}", shown(&v)))
        .collect();
    if refused.is_empty() {
        "yes".into()
    } else {
        format!("yes, but not {}", refused.join(", "))
    }
}

/// A prepared model's kernel, or why it does not run on the GPU.
pub fn kernel(model: &str, stack: &Stack, args: &Args) -> Result<Kernel> {
    if let Some(why) = refusal(model, args) {
        return value_error(why);
    }
    let mut kernel = (half(model)?.1.kernel)(stack, args)?;
    if matches!(args.get("transport_fit"), Some(Value::Flag(true))) {
        // The correction is the CPU's own fit of the prepared model (None where it returns the model as it is).
        kernel.fit = crate::models::prepare(model, stack, args)?.transport_fit().map(|f| f.gpu_values());
    }
    Ok(kernel)
}

/// The error for a model without a GPU implementation, naming those that have one.
fn unsupported(model: &str) -> Error {
    let names = models();
    let names = crate::error::py_list(&names);
    Error::Value(format!("model '{model}' has no GPU implementation yet (GPU models: {names}); use device='cpu'"))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    #[test]
    fn every_shader_is_valid_wgsl() {
        let sources = models()
            .into_iter()
            .flat_map(|name| [(name, compose(name).unwrap()), (name, compose_render(name).unwrap())])
            .chain([("raster", compose_raster())]);
        for (name, src) in sources {
            validate(name, &src);
        }
    }

    /// Parses and validates a composed module with naga as wgpu would, without a GPU; panics with naga's message.
    pub(crate) fn validate(name: &str, src: &str) -> wgpu::naga::Module {
        let module =
            wgpu::naga::front::wgsl::parse_str(src).unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(src)));
        wgpu::naga::valid::Validator::new(
            wgpu::naga::valid::ValidationFlags::all(),
            wgpu::naga::valid::Capabilities::all(),
        )
        .validate(&module)
        .unwrap_or_else(|e| panic!("{name}: {e:?}"));
        module
    }

    /// The WGSL struct `Params` of `model`'s composed shader has the Rust struct's fields (names and offsets, in
    /// order) and size: the two mirror each other.
    pub(crate) fn assert_mirrors(model: &str, fields: &[(&str, usize)], size: usize) {
        let module = validate(model, &compose(model).expect("a GPU model"));
        let (ty, _) =
            module.types.iter().find(|(_, t)| t.name.as_deref() == Some("Params")).expect("the shader declares Params");
        let wgpu::naga::TypeInner::Struct { members, span } = &module.types[ty].inner else {
            panic!("{model}: Params is not a struct")
        };
        let wgsl: Vec<(&str, usize)> =
            members.iter().map(|m| (m.name.as_deref().unwrap_or(""), m.offset as usize)).collect();
        assert_eq!(wgsl, fields, "{model}: Params' fields (name, offset)");
        assert_eq!(*span as usize, size, "{model}: Params' size");
    }
}
