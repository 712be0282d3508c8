//! The wgpu path: BRDF evaluation as WGSL compute shaders, in float32. The WGSL primitives (`shaders/optics.wgsl`)
//! mirror the Rust optics core function by function; each model's shader is composed after them (`compose`).
//! `cargo test` validates every composed shader with naga, without a GPU; tests/test_gpu.py checks parity with the
//! CPU on a real adapter (lavapipe in CI).
//!
//! Models on the GPU: `microfacet`, `steinberg`, `weidlich_wilkie` and `albedo_scaling` (every option but
//! `transport_fit`; the last three read shaders/layers.wgsl's layers, the single-pass models walk them in
//! shaders/single_pass.wgsl) and `belcour` (interpolated, every other option but `transport_fit`); `refusal` says
//! what does not run here. Per-element inputs (car-paint flakes, the patina mask) run on the CPU
//! only. A model is prepared once per stack and options and kept, with its arrays on the device (`cached_kernel`); the tables
//! that every stack shares are uploaded once (`table`). Inputs of any length are split into dispatches of at most
//! CHUNK pairs. A batch of stacks renders in one dispatch (`batched`). The renderer (`render`, shaders/scene.wgsl and render.wgsl) renders stacks
//! (and src/oat/gpu.rs Oat 2006's gooey layers) on the sphere, the plane and meshes (shaders/mesh.wgsl,
//! rasterized by raster.wgsl) under directional and point lights; stacks also under an environment (env.wgsl, with
//! the models' sampling mixtures of sample.wgsl). Device errors come back as values.

use crate::error::{value_error, Error, Result};
use crate::models::common::single_pass::{SpLayer, INTERREFLECTION_NODES};
use crate::models::{albedo_scaling, belcour, microfacet, steinberg, weidlich_wilkie, Args, Value};
use crate::optics::distribution::{Distribution, G2Form, Microfacet};
use crate::optics::fresnel::FresnelForm;
use crate::stack::Stack;
use crate::tables::elek::{beckmann_table, FRESNEL_SAMPLES};
use std::sync::atomic::{AtomicBool, AtomicI64, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use wgpu::util::DeviceExt;

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
/// The per-element kernels (eval, sample, pdf), composed after each model.
pub const QUERIES: &str = include_str!("shaders/queries.wgsl");
/// Triangle meshes, composed after SCENE.
pub const MESH: &str = include_str!("shaders/mesh.wgsl");
/// The mesh's rasterization into visibility targets, composed after MESH.
pub const RASTER: &str = include_str!("shaders/raster.wgsl");
/// The models' shaders, by model name: each is composed after OPTICS.
pub const MODELS: &[(&str, &str)] = &[
    ("microfacet", include_str!("shaders/microfacet.wgsl")),
    ("belcour", include_str!("shaders/belcour.wgsl")),
    (
        "steinberg",
        concat!(
            include_str!("shaders/layers.wgsl"),
            include_str!("shaders/single_pass.wgsl"),
            include_str!("shaders/steinberg.wgsl")
        ),
    ),
    (
        "weidlich_wilkie",
        concat!(
            include_str!("shaders/layers.wgsl"),
            include_str!("shaders/single_pass.wgsl"),
            include_str!("shaders/weidlich_wilkie.wgsl")
        ),
    ),
    ("albedo_scaling", concat!(include_str!("shaders/layers.wgsl"), include_str!("shaders/albedo_scaling.wgsl"))),
];

/// A model's complete shader source: the primitives and sampling, the model, and its per-element kernels.
pub fn compose(model: &str) -> Option<String> {
    MODELS.iter().find(|(name, _)| *name == model).map(|(_, src)| format!("{OPTICS}\n{SAMPLE}\n{src}\n{QUERIES}"))
}

/// Whether a model has a GPU implementation.
pub fn supports(model: &str) -> bool {
    MODELS.iter().any(|(name, _)| *name == model)
}

/// Pairs per dispatch: 2^21 (32768 workgroups of 64, within every adapter's dispatch limit).
const CHUNK: usize = 1 << 21;

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

/// The render kernels: for the sphere or plane and for a mesh, deterministic, then under an environment.
const RENDER_KERNELS: [&str; 4] = ["render", "render_mesh", "render_env", "render_mesh_env"];

/// The adapter, its device, per model (in the order of MODELS) its per-element pipelines (Query) and its render
/// pipelines (RENDER_KERNELS), each compiled on first use (drivers take seconds per kernel), the mesh's
/// rasterization in uv space and through the camera, and what lives on this device: the prepared kernels with
/// their arrays, the shared tables, Oat's pipelines (src/oat/gpu.rs). A device that is lost takes all of it along;
/// `gpu()` then creates the next one.
pub struct Gpu {
    pub info: wgpu::AdapterInfo,
    pub(crate) device: wgpu::Device,
    queue: wgpu::Queue,
    pipelines: Vec<[OnceLock<wgpu::ComputePipeline>; 3]>,
    renderers: Vec<[OnceLock<wgpu::ComputePipeline>; 4]>,
    pub(crate) raster: [wgpu::RenderPipeline; 2],
    kernels: Mutex<Vec<(String, Arc<Uploaded>)>>,
    tables: Mutex<Vec<((usize, usize), wgpu::Buffer)>>,
    pub(crate) oat: OnceLock<Vec<wgpu::ComputePipeline>>,
    /// Set by the device-lost callback.
    lost: Arc<AtomicBool>,
    /// Fault injection for lamina's tests: dispatches left before the device is destroyed (negative: never).
    lose_after: AtomicI64,
}

/// The visibility targets' format: (triangle, b1, b2, covered) per texel.
const VISIBILITY: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
const DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// The rasterization pipeline of `entry` (raster.wgsl): no culling, the nearest fragment by depth where `depth`.
fn raster_pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    entry: &str,
    depth: bool,
) -> wgpu::RenderPipeline {
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(entry),
        layout: None,
        vertex: wgpu::VertexState {
            module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: depth.then(|| wgpu::DepthStencilState {
            format: DEPTH,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Less),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some("visibility"),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::ColorTargetState {
                format: VISIBILITY,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// How to get an adapter, for the error when there is none.
const NO_ADAPTER: &str = "no GPU adapter found through wgpu (Vulkan). Install a Vulkan driver for your GPU; on a \
    machine without one, Mesa's lavapipe (Debian/Ubuntu: apt install mesa-vulkan-drivers) is a CPU adapter";

/// The process's GPU, created on first use (the best adapter: a discrete or integrated GPU before a CPU one) and again
/// after it is lost. Without an adapter, the error says how to get one, and stays (adapters do not appear); a device
/// the adapter refused is asked for again on the next call.
pub fn gpu() -> Result<Arc<Gpu>> {
    static GPU: Mutex<Option<std::result::Result<Arc<Gpu>, String>>> = Mutex::new(None);
    let mut slot = GPU.lock().unwrap_or_else(|e| e.into_inner());
    match &*slot {
        Some(Ok(g)) if !g.lost.load(Ordering::Relaxed) => return Ok(g.clone()),
        Some(Err(why)) => return Err(Error::Device(why.clone())),
        _ => {}
    }
    let created = pollster::block_on(create()).map(Arc::new);
    match &created {
        Err(why) if why != NO_ADAPTER => *slot = None,
        _ => *slot = Some(created.clone()),
    }
    created.map_err(Error::Device)
}

/// Fault injection for lamina's tests (tests/faults.py): the current device destroys itself after `dispatches` more
/// dispatches, as a lost device would stop.
pub fn lose_after(dispatches: i64) -> Result<()> {
    gpu()?.lose_after.store(dispatches, Ordering::Relaxed);
    Ok(())
}

async fn create() -> std::result::Result<Gpu, String> {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::VULKAN,
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    let mut adapters = instance.enumerate_adapters(wgpu::Backends::VULKAN).await;
    // Hardware first: discrete, integrated, virtual, then CPU (lavapipe).
    let rank = |t: wgpu::DeviceType| match t {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Cpu => 3,
        wgpu::DeviceType::Other => 4,
    };
    adapters.sort_by_key(|a| rank(a.get_info().device_type));
    let adapter = adapters.into_iter().next().ok_or_else(|| NO_ADAPTER.to_string())?;
    let limits = adapter.limits();
    let (device, queue) = adapter
        .request_device(&wgpu::DeviceDescriptor {
            label: Some("lamina"),
            required_limits: limits,
            ..Default::default()
        })
        .await
        .map_err(|e| format!("the GPU adapter refused a device: {e}"))?;
    let pipelines = MODELS.iter().map(|_| std::array::from_fn(|_| OnceLock::new())).collect();
    let renderers = MODELS.iter().map(|_| std::array::from_fn(|_| OnceLock::new())).collect();
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("raster"),
        source: wgpu::ShaderSource::Wgsl(compose_raster().into()),
    });
    let raster = [("uv_vertex", false), ("camera_vertex", true)].map(|(e, d)| raster_pipeline(&device, &module, e, d));
    let lost = Arc::new(AtomicBool::new(false));
    let flag = lost.clone();
    device.set_device_lost_callback(move |_, _| flag.store(true, Ordering::Relaxed));
    Ok(Gpu {
        info: adapter.get_info(),
        device,
        queue,
        pipelines,
        renderers,
        raster,
        kernels: Mutex::new(Vec::new()),
        tables: Mutex::new(Vec::new()),
        oat: OnceLock::new(),
        lost,
        lose_after: AtomicI64::new(-1),
    })
}

pub(crate) fn compute_module(device: &wgpu::Device, name: &str, source: String) -> wgpu::ShaderModule {
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(name),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    })
}

pub(crate) fn compute_pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    entry: &str,
) -> wgpu::ComputePipeline {
    layout_pipeline(device, module, entry, None)
}

/// A pipeline with the given layout, or (None) the one its entry point's bindings imply.
fn layout_pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    entry: &str,
    layout: Option<&wgpu::PipelineLayout>,
) -> wgpu::ComputePipeline {
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(entry),
        layout,
        module,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    })
}

impl Gpu {
    /// Model k's (MODELS order) pipeline for `query`, compiled on first use, with one layout for all three queries
    /// (what eval binds: the parameters, the model's `arrays` read-only arrays, the pairs and the output), so that one
    /// bind group serves each though pdf reads fewer.
    fn query_pipeline(&self, k: usize, query: Query, arrays: usize) -> &wgpu::ComputePipeline {
        self.pipelines[k][query as usize].get_or_init(|| {
            let (name, _) = MODELS[k];
            let entry = |binding: u32, ty: wgpu::BufferBindingType| wgpu::BindGroupLayoutEntry {
                binding,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Buffer { ty, has_dynamic_offset: false, min_binding_size: None },
                count: None,
            };
            let read = wgpu::BufferBindingType::Storage { read_only: true };
            let entries: Vec<wgpu::BindGroupLayoutEntry> = (0..=arrays as u32 + 1)
                .map(|b| entry(b, read))
                .chain([entry(arrays as u32 + 2, wgpu::BufferBindingType::Storage { read_only: false })])
                .collect();
            let group = self
                .device
                .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: None, entries: &entries });
            let layout = self.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(query.entry()),
                bind_group_layouts: &[Some(&group)],
                immediate_size: 0,
            });
            let module = compute_module(&self.device, name, compose(name).expect("listed"));
            layout_pipeline(&self.device, &module, query.entry(), Some(&layout))
        })
    }

    /// Model k's render pipeline RENDER_KERNELS[kernel], compiled on first use.
    fn render_pipeline(&self, k: usize, kernel: usize) -> &wgpu::ComputePipeline {
        self.renderers[k][kernel].get_or_init(|| {
            let (name, _) = MODELS[k];
            let module = compute_module(&self.device, name, compose_render(name).expect("listed"));
            compute_pipeline(&self.device, &module, RENDER_KERNELS[kernel])
        })
    }
}

/// A model prepared for the GPU: its shader's parameters (the words of its `Params`; the pair count is set per
/// dispatch at `count_word`), the stack's read-only arrays (layers, per-channel constants, Belcour's table), each with
/// the word that holds its offset when stacks are batched, the tables every stack shares, and the channel count.
pub struct Kernel {
    pub model: &'static str,
    pub words: Vec<u32>,
    pub count_word: usize,
    pub arrays: Vec<(Vec<f32>, usize)>,
    pub tables: Vec<&'static [f32]>,
    pub channels: usize,
}

fn g2_code(g2: G2Form) -> u32 {
    match g2 {
        G2Form::Separable => 0,
        G2Form::HeightCorrelated => 1,
        G2Form::VCavity => 2,
    }
}

fn fresnel_code(form: FresnelForm) -> u32 {
    match form {
        FresnelForm::Exact => 0,
        FresnelForm::Schlick => 1,
        FresnelForm::Lazanyi => 2,
    }
}

fn dist_code(dist: Distribution) -> u32 {
    match dist {
        Distribution::Ggx => 0,
        Distribution::Beckmann => 1,
    }
}

/// Lobes of a sampling mixture on the GPU (MAX_LOBES in shaders/sample.wgsl).
const MAX_LOBES: usize = 16;

/// Whether the GPU's sampling mixture holds every lobe a model proposes for `stack`: at most two per layer (a
/// single-pass model's dielectric: its reflection and its slab's cosine term).
fn fits_the_mixture(stack: &Stack) -> Result<()> {
    if 2 * stack.layers.len() > MAX_LOBES {
        return value_error(format!(
            "sampling on the GPU (sample, pdf, environment lights) takes stacks of at most {} layers, got {}; use \
             device='cpu'",
            MAX_LOBES / 2,
            stack.layers.len()
        ));
    }
    Ok(())
}

/// The single-pass layers as single_pass.wgsl reads them, and the nodes per Fresnel table (0: none): per layer 9
/// values (kind: 0 dielectric, 1 conductor, 2 diffuse; the microfacet's distribution, smooth flag, αx, αy, cos φ,
/// sin φ; thickness; Oren–Nayar σ), then per channel 5 (η, κ, σt, albedo, gain), a conductor base's inter-reflection
/// albedo at INTERREFLECTION_NODES cosines (zeros without) and Elek's Fresnel table, if any,
/// as (F, 1 − F) per node.
fn single_pass_layers(layers: &[SpLayer], channels: usize) -> (Vec<f32>, u32) {
    let samples =
        if layers.iter().filter_map(SpLayer::interface).any(|i| !i.table.is_empty()) { FRESNEL_SAMPLES } else { 0 };
    let smooth = Microfacet::new(Distribution::Ggx, 0.0, 0.0, 0.0);
    let zeros = vec![0.0; channels];
    let mut out = Vec::new();
    for layer in layers {
        let (kind, mf, thickness, sigma, [eta, kappa, sigma_t, albedo, gain]) = match layer {
            SpLayer::Dielectric { iface, thickness, sigma_t, albedo } => {
                (0, &iface.mf, *thickness, 0.0, [&iface.eta, &iface.kappa, sigma_t, albedo, &zeros])
            }
            SpLayer::Conductor { iface, .. } => {
                (1, &iface.mf, 0.0, 0.0, [&iface.eta, &iface.kappa, &zeros, &zeros, &zeros])
            }
            SpLayer::Diffuse { albedo, sigma, gain } => {
                (2, &smooth, 0.0, *sigma, [&zeros, &zeros, &zeros, albedo, gain])
            }
        };
        let (cos_phi, sin_phi) = mf.frame();
        let header = [kind as f64, dist_code(mf.dist) as f64, mf.is_smooth() as u8 as f64, mf.alpha_x, mf.alpha_y];
        out.extend(header.into_iter().chain([cos_phi, sin_phi, thickness, sigma]).map(|x| x as f32));
        let interreflected = match layer {
            SpLayer::Conductor { diffuse, .. } if !diffuse.is_empty() => &diffuse[..],
            _ => &[],
        };
        for c in 0..channels {
            out.extend([eta[c], kappa[c], sigma_t[c], albedo[c], gain[c]].map(|x| x as f32));
            let nodes = interreflected.get(c * INTERREFLECTION_NODES..(c + 1) * INTERREFLECTION_NODES);
            out.extend((0..INTERREFLECTION_NODES).map(|j| nodes.map_or(0.0, |n| n[j] as f32)));
            let table = layer.interface().and_then(|i| i.table.get(c)).map_or(&[][..], |t| t.samples());
            out.extend(table.iter().copied().chain(std::iter::repeat(0.0)).take(2 * samples));
        }
    }
    (out, samples as u32)
}

/// The Steinberg kernel: 16 words in the layout of `Params` in steinberg.wgsl, the layers and the tables.
pub fn steinberg_kernel(p: &steinberg::Prepared) -> Kernel {
    use crate::tables::steinberg::{steinberg, ETA_MAX, ETA_MIN, N_ALPHA, N_ETA, N_MU};
    let walk = &p.walk;
    let (table, fits) = steinberg().gpu_data();
    let (layers, fresnel_samples) = single_pass_layers(&walk.layers, p.channels);
    let words = vec![
        0,
        p.channels as u32,
        walk.layers.len() as u32,
        g2_code(walk.g2),
        fresnel_code(walk.fresnel),
        walk.eta2 as u32,
        p.opts.fitted as u32,
        N_MU as u32,
        N_ALPHA as u32,
        N_ETA as u32,
        (ETA_MIN as f32).to_bits(),
        (ETA_MAX as f32).to_bits(),
        fresnel_samples,
        0, // the layers' offset
        p.opts.microfacet_transmission as u32,
        0,
    ];
    Kernel {
        model: "steinberg",
        words,
        count_word: 0,
        arrays: vec![(layers, 13)],
        tables: vec![table, fits],
        channels: p.channels,
    }
}

/// The microfacet kernel: 16 words in the layout of `Params` in microfacet.wgsl, and per channel (eta, k, albedo,
/// f_int).
pub fn microfacet_kernel(p: &microfacet::Prepared) -> Kernel {
    use microfacet::Prepared;
    let smooth = Microfacet::new(Distribution::Ggx, 0.0, 0.0, 0.0);
    let (kind, mf, g2, fresnel, sigma, channels): (u32, &Microfacet, G2Form, FresnelForm, f64, Vec<[f64; 4]>) = match p
    {
        Prepared::Conductor { mf, g2, fresnel, eta, k } => {
            (0, mf, *g2, *fresnel, 0.0, eta.iter().zip(k).map(|(e, k)| [*e, *k, 0.0, 0.0]).collect())
        }
        Prepared::Diffuse { albedo, sigma } => {
            let rows = albedo.iter().map(|a| [0.0, 0.0, *a, 0.0]).collect();
            (1, &smooth, G2Form::Separable, FresnelForm::Exact, *sigma, rows)
        }
        Prepared::CoatLambert { albedo, eta, f_int } => {
            let rows = (0..albedo.len()).map(|c| [eta[c], 0.0, albedo[c], f_int[c]]).collect();
            (2, &smooth, G2Form::Separable, FresnelForm::Exact, 0.0, rows)
        }
    };
    let (cos_phi, sin_phi) = mf.frame();
    let f = |x: f64| (x as f32).to_bits();
    let words = vec![
        kind,
        g2_code(g2),
        fresnel_code(fresnel),
        channels.len() as u32,
        0,
        f(sigma),
        0,
        0,
        dist_code(mf.dist),
        mf.is_smooth() as u32,
        f(mf.alpha_x),
        f(mf.alpha_y),
        f(cos_phi),
        f(sin_phi),
        0, // the channel rows' offset
        0,
    ];
    let c = channels.len();
    Kernel {
        model: "microfacet",
        words,
        count_word: 4,
        arrays: vec![(channels.into_iter().flatten().map(|x| x as f32).collect(), 14)],
        tables: vec![],
        channels: c,
    }
}

/// The Belcour kernel: 16 words in the layout of `Params` in belcour.wgsl, the table and the diffuse base.
pub fn belcour_kernel(p: &belcour::Prepared) -> Result<Kernel> {
    let Some(d) = p.gpu_data() else {
        return value_error("model 'belcour' with interpolated=False runs on the CPU only; use device='cpu'");
    };
    let [lobes, nodes, azimuths, width, channels] = d.shape.map(|x| x as u32);
    let (diffuse, eta) = d.diffuse.unwrap_or((vec![], 1.0));
    let f32s = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
    let words = vec![
        0,
        channels,
        lobes,
        nodes,
        azimuths,
        width,
        g2_code(d.g2),
        d.symmetric as u32,
        !diffuse.is_empty() as u32,
        (eta as f32).to_bits(),
        0,
        0,
        0, // the offsets of record, t_down, t_up and diffuse
        0,
        0,
        0,
    ];
    let diffuse: Vec<f32> = diffuse.iter().flatten().map(|&x| x as f32).collect();
    Ok(Kernel {
        model: "belcour",
        words,
        count_word: 0,
        arrays: vec![(f32s(d.record), 12), (f32s(d.t_down), 13), (f32s(d.t_up), 14), (diffuse, 15)],
        tables: vec![],
        channels: channels as usize,
    })
}

/// The Weidlich–Wilkie kernel: 12 words in the layout of `Params` in weidlich_wilkie.wgsl, the layers (with Elek's
/// Fresnel tables when precomputed) and Elek's Beckmann table (one unused value when not precomputed).
pub fn weidlich_wilkie_kernel(p: &weidlich_wilkie::Prepared) -> Kernel {
    use crate::tables::elek::D_SIZE;
    let (layers, fresnel_samples) = single_pass_layers(&p.walk.layers, p.channels);
    let beckmann: &'static [f32] = if p.precomputed { beckmann_table().samples() } else { &[0.0] };
    let words = vec![
        0,
        p.channels as u32,
        p.walk.layers.len() as u32,
        g2_code(p.walk.g2),
        fresnel_code(p.walk.fresnel),
        p.walk.eta2 as u32,
        fresnel_samples,
        p.precomputed as u32,
        D_SIZE as u32,
        0, // the layers' offset
        0,
        0,
    ];
    Kernel {
        model: "weidlich_wilkie",
        words,
        count_word: 0,
        arrays: vec![(layers, 9)],
        tables: vec![beckmann],
        channels: p.channels,
    }
}

/// The albedo-scaling kernel: 16 words in the layout of `Params` in albedo_scaling.wgsl, the layers and the FGD table.
pub fn albedo_scaling_kernel(p: &albedo_scaling::Prepared) -> Kernel {
    use crate::tables::fgd::{fgd, ETA_MAX, ETA_MIN, KAPPA_MAX, N_ALPHA, N_ETA, N_KAPPA, N_MU};
    let (layers, fresnel_samples) = single_pass_layers(&p.layers, p.channels);
    let f = |x: f64| (x as f32).to_bits();
    let words = vec![
        0,
        p.channels as u32,
        p.layers.len() as u32,
        g2_code(p.g2),
        p.reciprocal as u32,
        fresnel_code(FresnelForm::Exact),
        fresnel_samples,
        0,
        N_MU as u32,
        N_ALPHA as u32,
        N_ETA as u32,
        N_KAPPA as u32,
        f(ETA_MIN),
        f(ETA_MAX),
        f(KAPPA_MAX),
        0, // the layers' offset
    ];
    Kernel {
        model: "albedo_scaling",
        words,
        count_word: 0,
        arrays: vec![(layers, 15)],
        tables: vec![fgd().data()],
        channels: p.channels,
    }
}

/// Why `model` with `args` (and per-element inputs, when `inputs`) does not run on the GPU, or None when it does: the
/// one rule behind every `device=` choice (device.rs) and every GPU kernel.
pub fn refusal(model: &str, args: &Args, inputs: bool) -> Option<String> {
    if !supports(model) {
        return Some(unsupported(model).to_string());
    }
    if args.get("transport_fit") == Some(&Value::Flag(true)) {
        return Some(format!(
            "model '{model}' with transport_fit (variant='improved') runs on the CPU only; use device='cpu', or \
             transport_fit=False on the GPU"
        ));
    }
    if model == "belcour" && args.get("interpolated") == Some(&Value::Flag(false)) {
        return Some("model 'belcour' with interpolated=False runs on the CPU only; use device='cpu'".into());
    }
    if inputs {
        return Some(
            "per-element inputs run on the CPU only (textures, car-paint flakes, the patina mask); use device='cpu'"
                .into(),
        );
    }
    None
}

/// A prepared model's kernel, or why it does not run on the GPU.
pub fn kernel(model: &str, stack: &Stack, args: &Args) -> Result<Kernel> {
    if let Some(why) = refusal(model, args, false) {
        return value_error(why);
    }
    match model {
        "microfacet" => Ok(microfacet_kernel(&microfacet::prepare(stack, &microfacet::Options::parse(args)?)?)),
        "belcour" => belcour_kernel(&belcour::prepare(stack, &belcour::Options::parse(args)?)?),
        "steinberg" => Ok(steinberg_kernel(&steinberg::prepare(stack, &steinberg::Options::parse(args)?)?)),
        "weidlich_wilkie" => {
            let opts = weidlich_wilkie::Options::parse(args, stack.channels)?;
            Ok(weidlich_wilkie_kernel(&weidlich_wilkie::prepare(stack, &opts)?))
        }
        "albedo_scaling" => {
            Ok(albedo_scaling_kernel(&albedo_scaling::prepare(stack, &albedo_scaling::Options::parse(args)?)?))
        }
        _ => Err(unsupported(model)),
    }
}

/// The error for a model without a GPU implementation, naming those that have one.
fn unsupported(model: &str) -> Error {
    let names: Vec<&str> = MODELS.iter().map(|m| m.0).collect();
    let names = crate::error::py_list(&names);
    Error::Value(format!("model '{model}' has no GPU implementation yet (GPU models: {names}); use device='cpu'"))
}

/// A prepared kernel, and its arrays and tables on the device as `batched` binds them for it alone: uploaded on the
/// first per-element query and kept (a render batches the kernels of its stacks instead).
struct Uploaded {
    kernel: Kernel,
    arrays: OnceLock<Vec<wgpu::Buffer>>,
}

impl Uploaded {
    fn arrays(&self, gpu: &Gpu) -> &[wgpu::Buffer] {
        self.arrays.get_or_init(|| batched(gpu, &[&self.kernel]).1)
    }
}

/// One model's kernels for stacks that one dispatch serves: their `Params`, one after the other, each holding its
/// arrays' offsets; and group 0's read-only buffers: each array of every stack, concatenated, then the shared tables.
fn batched(gpu: &Gpu, kernels: &[&Kernel]) -> (Vec<u32>, Vec<wgpu::Buffer>) {
    let mut words = Vec::new();
    let mut arrays = vec![Vec::new(); kernels[0].arrays.len()];
    for kernel in kernels {
        let mut own = kernel.words.clone();
        for ((array, word), all) in kernel.arrays.iter().zip(&mut arrays) {
            own[*word] = all.len() as u32;
            all.extend_from_slice(array);
        }
        words.extend(own);
    }
    // Storage buffers may not be empty: an array that no stack has (Belcour's diffuse base) gets an unused value.
    let buffers = arrays
        .iter()
        .map(|a| init(gpu, "array", bytemuck::cast_slice(if a.is_empty() { &[0.0] } else { a }), STORAGE))
        .chain(kernels[0].tables.iter().map(|t| table(gpu, t)))
        .collect();
    (words, buffers)
}

/// A table that every stack shares (Steinberg's, the FGD, Elek's Beckmann table), uploaded once per device.
fn table(gpu: &Gpu, data: &'static [f32]) -> wgpu::Buffer {
    // Static data never moves: its address and length name it.
    let key = (data.as_ptr() as usize, data.len());
    let mut tables = gpu.tables.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((_, b)) = tables.iter().find(|(k, _)| *k == key) {
        return b.clone();
    }
    let b = init(gpu, "table", bytemuck::cast_slice(data), STORAGE);
    tables.push((key, b.clone()));
    b
}

const STORAGE: wgpu::BufferUsages = wgpu::BufferUsages::STORAGE;

const CACHED: usize = 16;

/// `model` prepared for `stack` and `args` for the GPU: kept for the next calls with equal arguments (as the CPU
/// keeps its prepared models), so that its tables are built once and, for per-element queries, uploaded once
/// (`Uploaded::arrays`).
fn cached_kernel(gpu: &Gpu, model: &str, stack: &Stack, args: &Args) -> Result<Arc<Uploaded>> {
    // Debug prints every f64 in its shortest round-trip form: equal keys mean equal arguments (models::prepare).
    let key = format!("{model}|{stack:?}|{args:?}");
    let mut cache = gpu.kernels.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(k) = cache.iter().position(|(k, _)| *k == key) {
        let entry = cache.remove(k);
        let found = entry.1.clone();
        cache.insert(0, entry);
        return Ok(found);
    }
    let up = Arc::new(Uploaded { kernel: kernel(model, stack, args)?, arrays: OnceLock::new() });
    cache.insert(0, (key, up.clone()));
    cache.truncate(CACHED);
    Ok(up)
}

/// One dispatch: its parameters and pairs on the device, its output buffer and their bind group.
struct Batch {
    bind: wgpu::BindGroup,
    out: wgpu::Buffer,
    pairs: usize,
}

/// Uploads the pairs (float32 rows of two vectors: wi and wo, or wo and u) of one dispatch of `up`'s kernel for
/// `query`.
fn batch(gpu: &Gpu, up: &Uploaded, pipeline: &wgpu::ComputePipeline, query: Query, pairs: &[f32]) -> Batch {
    let kernel = &up.kernel;
    let m = pairs.len() / 6;
    let mut words = kernel.words.clone();
    words[kernel.count_word] = m as u32;
    let params = init(gpu, "params", bytemuck::cast_slice(&words), STORAGE);
    let pair_buf = init(gpu, "pairs", bytemuck::cast_slice(pairs), STORAGE);
    let out = buffer(gpu, "f", (4 * m * query.width(kernel.channels)) as u64, STORAGE | wgpu::BufferUsages::COPY_SRC);
    let resources: Vec<(u32, Res)> = std::iter::once(&params)
        .chain(up.arrays(gpu))
        .chain([&pair_buf, &out])
        .enumerate()
        .map(|(k, b)| (k as u32, Res::Buffer(b)))
        .collect();
    Batch { bind: group(gpu, pipeline, 0, &resources), out, pairs: m }
}

/// Submits one dispatch of a batch, then (with `read`) the copy of its output into `read`.
fn dispatch_batch(gpu: &Gpu, pipeline: &wgpu::ComputePipeline, b: &Batch, read: Option<&wgpu::Buffer>) {
    gpu.count_dispatch();
    let mut encoder = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
    {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: None, timestamp_writes: None });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &b.bind, &[]);
        pass.dispatch_workgroups(b.pairs.div_ceil(64) as u32, 1, 1);
    }
    if let Some(read) = read {
        encoder.copy_buffer_to_buffer(&b.out, 0, read, 0, b.out.size());
    }
    gpu.queue.submit([encoder.finish()]);
}

impl Gpu {
    /// Counts a dispatch against the fault injection of `lose_after`, destroying the device when its count runs out.
    pub(crate) fn count_dispatch(&self) {
        if self.lose_after.fetch_sub(1, Ordering::Relaxed) == 0 {
            self.device.destroy();
        }
    }

    /// The error of work on this device that failed: it names the device and the work (with its size), and says
    /// what comes next.
    fn failure(&self, what: &str, why: &str) -> Error {
        let lost = self.lost.load(Ordering::Relaxed);
        let next = if lost { "the device was lost; the next call creates it again" } else { "the device is kept" };
        Error::Device(format!("the GPU ({}) failed while {what}: {why}; {next}", self.info.name))
    }
}

/// Runs `work` (`what`: the work and its size, for the message) with the device's validation and out-of-memory errors
/// caught, instead of wgpu's default handler, which panics (nothing may panic across the FFI boundary); an error, or
/// the device lost meanwhile, becomes a Device error (RuntimeError) naming the device and the work.
pub(crate) fn scoped<T>(gpu: &Gpu, what: &str, work: impl FnOnce() -> Result<T>) -> Result<T> {
    let memory = gpu.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let validation = gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
    let out = work();
    let errors = [pollster::block_on(validation.pop()), pollster::block_on(memory.pop())];
    if let Some(e) = errors.into_iter().flatten().next() {
        return Err(gpu.failure(what, &e.to_string()));
    }
    match out {
        Err(Error::Device(why)) => Err(gpu.failure(what, &why)),
        Ok(_) if gpu.lost.load(Ordering::Relaxed) => Err(gpu.failure(what, "the device was lost")),
        out => out,
    }
}

/// Waits for the submitted work; an error of the device's (lost) as a Device error.
pub(crate) fn wait(gpu: &Gpu) -> Result<()> {
    gpu.device.poll(wgpu::PollType::wait_indefinitely()).map(|_| ()).map_err(|e| Error::Device(e.to_string()))
}

/// A size in bytes as text: "3.0 GiB", "45.8 MiB", "12 KiB".
pub(crate) fn bytes(n: usize) -> String {
    match n {
        n if n >= 1 << 30 => format!("{:.1} GiB", n as f64 / (1u64 << 30) as f64),
        n if n >= 1 << 20 => format!("{:.1} MiB", n as f64 / (1u64 << 20) as f64),
        n => format!("{} KiB", n.div_ceil(1 << 10)),
    }
}

/// The model on the device, its pipeline, and the pairs per dispatch (CHUNK, or fewer where the adapter's
/// storage-buffer limit requires).
fn prepared<'g>(
    gpu: &'g Gpu,
    model: &str,
    stack: &Stack,
    args: &Args,
    query: Query,
    pairs: &[f32],
) -> Result<(Arc<Uploaded>, &'g wgpu::ComputePipeline, usize)> {
    if !pairs.len().is_multiple_of(6) {
        return value_error("pairs must be float32 (n, 6) rows of two vectors");
    }
    let up = cached_kernel(gpu, model, stack, args)?;
    let k = MODELS.iter().position(|m| m.0 == up.kernel.model).expect("a listed model");
    let limit = gpu.device.limits().max_storage_buffer_binding_size as usize;
    let chunk = CHUNK.min((limit / (4 * query.width(up.kernel.channels).max(6))).max(64));
    let pipeline = gpu.query_pipeline(k, query, up.arrays(gpu).len());
    Ok((up, pipeline, chunk))
}

/// `query` of `model` for n elements given as float32 rows of two unit vectors, (wi, wo) or for Sample (wo, u):
/// n·query.width(channels) float32 values.
pub fn run(query: Query, model: &str, stack: &Stack, args: &Args, pairs: &[f32]) -> Result<Vec<f32>> {
    let gpu = gpu()?;
    let n = pairs.len() / 6;
    let what = format!("running {model} on {n} elements ({})", bytes(4 * n * (6 + query.width(stack.channels))));
    scoped(&gpu, &what, || run_scoped(&gpu, query, model, stack, args, pairs))
}

fn run_scoped(gpu: &Gpu, query: Query, model: &str, stack: &Stack, args: &Args, pairs: &[f32]) -> Result<Vec<f32>> {
    if !matches!(query, Query::Eval) {
        fits_the_mixture(stack)?;
    }
    let (up, pipeline, chunk) = prepared(gpu, model, stack, args, query, pairs)?;
    let c = query.width(up.kernel.channels);
    let mut out = vec![0f32; pairs.len() / 6 * c];
    for (rows, dst) in pairs.chunks(6 * chunk).zip(out.chunks_mut(chunk * c)) {
        let b = batch(gpu, &up, pipeline, query, rows);
        let read = buffer(gpu, "readback", b.out.size(), wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST);
        dispatch_batch(gpu, pipeline, &b, Some(&read));
        dst.copy_from_slice(&read_back(gpu, &read)?);
    }
    Ok(out)
}

/// Seconds per evaluation of all the pairs with inputs and outputs resident on the device (uploaded once, nothing
/// read back): the mean over `repeats` rounds after a warm-up round. For benchmarks.
pub fn resident_seconds(model: &str, stack: &Stack, args: &Args, pairs: &[f32], repeats: usize) -> Result<f64> {
    let gpu = gpu()?;
    let what = format!("timing {model} on {} resident pairs", pairs.len() / 6);
    scoped(&gpu, &what, || {
        let gpu = &*gpu;
        let (up, pipeline, chunk) = prepared(gpu, model, stack, args, Query::Eval, pairs)?;
        let batches: Vec<Batch> =
            pairs.chunks(6 * chunk).map(|rows| batch(gpu, &up, pipeline, Query::Eval, rows)).collect();
        batches.iter().for_each(|b| dispatch_batch(gpu, pipeline, b, None));
        wait(gpu)?;
        let start = std::time::Instant::now();
        for _ in 0..repeats.max(1) {
            batches.iter().for_each(|b| dispatch_batch(gpu, pipeline, b, None));
            wait(gpu)?;
        }
        Ok(start.elapsed().as_secs_f64() / repeats.max(1) as f64)
    })
}

/// A light as scene.wgsl's `incident` reads it: two rows, (kind: 0 directional, 1 point; its direction or position)
/// and (its irradiance or intensity, 0).
pub fn light_rows(light: &crate::render::Light) -> [f32; 8] {
    use crate::render::Light;
    match *light {
        Light::Directional { direction: d, irradiance: e } => [0.0, d.x, d.y, d.z, e[0], e[1], e[2], 0.0],
        Light::Point { position: p, intensity: i } => [1.0, p.x, p.y, p.z, i[0], i[1], i[2], 0.0],
    }
    .map(|x| x as f32)
}

/// A scene for the GPU renderer: the image size, the shape (0 sphere, 1 plane, 2 the mesh), the mesh's arrays
/// (Mesh::gpu_arrays), the perspective camera's pinhole and its forward, right and up vectors (scaled as in
/// scene.wgsl; None: orthographic), and each light's rows (`light_rows`).
pub struct Scene {
    pub width: usize,
    pub height: usize,
    pub shape: u32,
    pub mesh: Option<(Vec<f32>, Vec<u32>)>,
    pub camera: Option<[[f32; 3]; 4]>,
    pub lights: Vec<[f32; 8]>,
    /// An environment light: EnvParams' words, the RGB radiance and the sampling distributions (Environment::gpu_data).
    pub env: Option<([u32; 8], Vec<f32>, Vec<f32>)>,
}

/// The scene's uniform parameters (RenderParams in scene.wgsl) for a dispatch rendering `stacks` images, and the
/// light rows, on the device.
pub(crate) fn scene_buffers(gpu: &Gpu, scene: &Scene, stacks: usize) -> (wgpu::Buffer, wgpu::Buffer) {
    let mut words = [0u32; 24];
    words[..6].copy_from_slice(&[
        scene.width as u32,
        scene.height as u32,
        scene.shape,
        scene.camera.is_some() as u32,
        scene.lights.len() as u32,
        stacks as u32,
    ]);
    for (r, v) in scene.camera.unwrap_or_default().iter().enumerate() {
        for (c, x) in v.iter().enumerate() {
            words[8 + 4 * r + c] = x.to_bits();
        }
    }
    let rows: Vec<f32> = if scene.lights.is_empty() { vec![0.0; 8] } else { scene.lights.concat() };
    (
        init(gpu, "render params", bytemuck::cast_slice(&words), wgpu::BufferUsages::UNIFORM),
        init(gpu, "lights", bytemuck::cast_slice(&rows), wgpu::BufferUsages::STORAGE),
    )
}

pub(crate) fn init(gpu: &Gpu, label: &str, contents: &[u8], usage: wgpu::BufferUsages) -> wgpu::Buffer {
    gpu.device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
}

pub(crate) fn buffer(gpu: &Gpu, label: &str, size: u64, usage: wgpu::BufferUsages) -> wgpu::Buffer {
    gpu.device.create_buffer(&wgpu::BufferDescriptor { label: Some(label), size, usage, mapped_at_creation: false })
}

/// The workgroups of 64 threads covering `threads`, as (x, y) within the per-dimension limit of 65535 (the
/// kernels' `thread_index`).
fn workgroups(threads: usize) -> (u32, u32) {
    let groups = threads.div_ceil(64).max(1);
    let x = groups.min(65535);
    (x as u32, groups.div_ceil(x) as u32)
}

/// A resource of a bind group.
#[derive(Clone, Copy)]
pub(crate) enum Res<'a> {
    Buffer(&'a wgpu::Buffer),
    View(&'a wgpu::TextureView),
}

/// A bind group of `layout_of`'s group `g` with the resources at their bindings (none: an unused group).
pub(crate) fn group(gpu: &Gpu, layout_of: &wgpu::ComputePipeline, g: u32, resources: &[(u32, Res)]) -> wgpu::BindGroup {
    group_of(gpu, &layout_of.get_bind_group_layout(g), resources)
}

/// A bind group of `layout` with the resources at their bindings.
fn group_of(gpu: &Gpu, layout: &wgpu::BindGroupLayout, resources: &[(u32, Res)]) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = resources
        .iter()
        .map(|(binding, r)| wgpu::BindGroupEntry {
            binding: *binding,
            resource: match r {
                Res::Buffer(b) => b.as_entire_binding(),
                Res::View(v) => wgpu::BindingResource::TextureView(v),
            },
        })
        .collect();
    gpu.device.create_bind_group(&wgpu::BindGroupDescriptor { label: None, layout, entries: &entries })
}

/// Records one dispatch of `pipeline` over `threads` with its bind groups 0, 1 and 2.
pub(crate) fn dispatch(
    encoder: &mut wgpu::CommandEncoder,
    pipeline: &wgpu::ComputePipeline,
    groups: &[&wgpu::BindGroup],
    threads: usize,
) {
    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: None, timestamp_writes: None });
    pass.set_pipeline(pipeline);
    for (g, bind) in groups.iter().enumerate() {
        pass.set_bind_group(g as u32, *bind, &[]);
    }
    let (x, y) = workgroups(threads);
    pass.dispatch_workgroups(x, y, 1);
}

/// A visibility target of `size` texels (and a depth buffer with `depth`), cleared, and the mesh rasterized into it
/// by `pipeline` with the mesh's bind group (and the scene's, for the camera).
pub(crate) fn rasterize(
    gpu: &Gpu,
    encoder: &mut wgpu::CommandEncoder,
    pipeline: &wgpu::RenderPipeline,
    size: [usize; 2],
    mesh: [&wgpu::Buffer; 2],
    triangles: usize,
    scene: Option<&wgpu::Buffer>,
) -> wgpu::TextureView {
    let texture = |format, usage| {
        gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("visibility"),
            size: wgpu::Extent3d { width: size[0] as u32, height: size[1] as u32, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        })
    };
    let target = texture(VISIBILITY, wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING);
    let view = target.create_view(&Default::default());
    let depth = scene.map(|_| texture(DEPTH, wgpu::TextureUsages::RENDER_ATTACHMENT).create_view(&Default::default()));
    let bind = |g: u32, resources: &[(u32, Res)]| group_of(gpu, &pipeline.get_bind_group_layout(g), resources);
    let groups = [
        bind(0, &[]),
        scene.map_or_else(|| bind(1, &[]), |rp| bind(1, &[(0, Res::Buffer(rp))])),
        bind(2, &[(0, Res::Buffer(mesh[0])), (1, Res::Buffer(mesh[1]))]),
    ];
    let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some("rasterize"),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: &view,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations { load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT), store: wgpu::StoreOp::Store },
        })],
        depth_stencil_attachment: depth.as_ref().map(|view| wgpu::RenderPassDepthStencilAttachment {
            view,
            depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
            stencil_ops: None,
        }),
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    });
    pass.set_pipeline(pipeline);
    for (g, b) in groups.iter().enumerate() {
        pass.set_bind_group(g as u32, b, &[]);
    }
    pass.draw(0..3 * triangles as u32, 0..1);
    drop(pass);
    view
}

/// Submits `encoder` and reads the float32 buffer `read` back.
pub(crate) fn finish(gpu: &Gpu, encoder: wgpu::CommandEncoder, read: &wgpu::Buffer) -> Result<Vec<f32>> {
    gpu.queue.submit([encoder.finish()]);
    read_back(gpu, read)
}

/// The float32 values of the mappable buffer `read`, once the submitted work has written them; a Device error when
/// they cannot be read (a lost device).
fn read_back(gpu: &Gpu, read: &wgpu::Buffer) -> Result<Vec<f32>> {
    let slice = read.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    wait(gpu)?;
    match rx.try_recv() {
        Ok(Ok(())) => {}
        Ok(Err(e)) => return Err(Error::Device(e.to_string())),
        Err(_) => return Err(Error::Device("the results were never mapped".into())),
    }
    let view = slice.get_mapped_range().map_err(|e| Error::Device(e.to_string()))?;
    Ok(bytemuck::cast_slice(&view).to_vec())
}

/// Renders each stack under the scene's lights (and environment): (stacks, height, width, 3) float32 radiance. One
/// dispatch renders every stack (`batched`), or as many as the adapter's storage-buffer limit holds.
pub fn render(model: &str, stacks: &[Stack], args: &Args, scene: &Scene) -> Result<Vec<f32>> {
    let gpu = gpu()?;
    let image = 12 * scene.width * scene.height;
    let what = format!(
        "rendering {} image(s) of {} x {} with {model} ({} each)",
        stacks.len(),
        scene.width,
        scene.height,
        bytes(image)
    );
    let limit = gpu.device.limits().max_storage_buffer_binding_size as usize;
    if image > limit {
        return Err(gpu.failure(
            &what,
            &format!("an image needs {}, over the adapter's storage-buffer limit of {}", bytes(image), bytes(limit)),
        ));
    }
    scoped(&gpu, &what, || render_scoped(&gpu, model, stacks, args, scene))
}

fn render_scoped(gpu: &Gpu, model: &str, stacks: &[Stack], args: &Args, scene: &Scene) -> Result<Vec<f32>> {
    let Some(k) = MODELS.iter().position(|m| m.0 == model) else { return Err(unsupported(model)) };
    let pipeline = gpu.render_pipeline(k, scene.mesh.is_some() as usize + 2 * scene.env.is_some() as usize);
    if scene.env.is_some() {
        stacks.iter().try_for_each(fits_the_mixture)?;
    }
    let ups = stacks.iter().map(|s| cached_kernel(gpu, model, s, args)).collect::<Result<Vec<_>>>()?;
    if ups.iter().any(|u| u.kernel.channels != 3) {
        return value_error("render takes RGB stacks (3 channels)");
    }
    let env = scene.env.as_ref().map(|(words, rgb, dists)| {
        let params = init(gpu, "env params", bytemuck::cast_slice(words), wgpu::BufferUsages::UNIFORM);
        [
            params,
            init(gpu, "env", bytemuck::cast_slice(rgb), STORAGE),
            init(gpu, "env dists", bytemuck::cast_slice(dists), STORAGE),
        ]
    });
    let mesh = scene.mesh.as_ref().map(|(rows, tris)| {
        [
            init(gpu, "vertices", bytemuck::cast_slice(rows), STORAGE),
            init(gpu, "triangles", bytemuck::cast_slice(tris), STORAGE),
        ]
    });
    // Per stack, its image and its scratch (3 channels each) and its arrays must fit the storage-buffer limit.
    let limit = gpu.device.limits().max_storage_buffer_binding_size as usize;
    let image_bytes = 12 * scene.width * scene.height;
    let array_bytes = ups.iter().flat_map(|u| u.kernel.arrays.iter().map(|(a, _)| 4 * a.len())).max().unwrap_or(0);
    let per_dispatch = (limit / image_bytes.max(array_bytes).max(1)).max(1);
    let mut image = Vec::with_capacity(stacks.len() * image_bytes / 4);
    for chunk in ups.chunks(per_dispatch) {
        let kernels: Vec<&Kernel> = chunk.iter().map(|u| &u.kernel).collect();
        image.extend(render_batch(gpu, pipeline, &kernels, scene, mesh.as_ref(), env.as_ref())?);
    }
    Ok(image)
}

/// One dispatch of the render `pipeline` over every pixel of each kernel's stack (a mesh rasterized once through the
/// camera first, its surface read back by each pixel): their images, one after the other.
fn render_batch(
    gpu: &Gpu,
    pipeline: &wgpu::ComputePipeline,
    kernels: &[&Kernel],
    scene: &Scene,
    mesh: Option<&[wgpu::Buffer; 2]>,
    env: Option<&[wgpu::Buffer; 3]>,
) -> Result<Vec<f32>> {
    let threads = kernels.len() * scene.width * scene.height;
    let (render_params, lights) = scene_buffers(gpu, scene, kernels.len());
    let (words, arrays) = batched(gpu, kernels);
    let params = init(gpu, "params", bytemuck::cast_slice(&words), STORAGE);
    let size = (4 * 3 * threads) as u64;
    let scratch = buffer(gpu, "f", size, STORAGE);
    let image = buffer(gpu, "image", size, STORAGE | wgpu::BufferUsages::COPY_SRC);
    let read = buffer(gpu, "readback", size, wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST);
    let mut encoder = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
    // Group 0 as the render entry points use it: the parameters, the model's arrays and `out` (not `pairs`).
    let n = arrays.len() as u32;
    let model_buffers: Vec<(u32, Res)> = std::iter::once((0, Res::Buffer(&params)))
        .chain(arrays.iter().enumerate().map(|(j, b)| (j as u32 + 1, Res::Buffer(b))))
        .chain([(n + 2, Res::Buffer(&scratch))])
        .collect();
    let scene_group = [(0, Res::Buffer(&render_params)), (1, Res::Buffer(&lights)), (2, Res::Buffer(&image))];
    let mut groups = vec![group(gpu, pipeline, 0, &model_buffers), group(gpu, pipeline, 1, &scene_group)];
    if let Some([vertices, triangles]) = mesh {
        let triangle_count = scene.mesh.as_ref().map_or(0, |(_, t)| t.len() / 3);
        let size = [scene.width, scene.height];
        let raster = &gpu.raster[1];
        let seen =
            rasterize(gpu, &mut encoder, raster, size, [vertices, triangles], triangle_count, Some(&render_params));
        let resources = [(0, Res::Buffer(vertices)), (1, Res::Buffer(triangles)), (2, Res::View(&seen))];
        groups.push(group(gpu, pipeline, 2, &resources));
    }
    if let Some(buffers) = env {
        if mesh.is_none() {
            // Groups are numbered: without a mesh, an empty group 2 keeps the environment at 3.
            groups.push(group(gpu, pipeline, 2, &[]));
        }
        let resources: Vec<(u32, Res)> = buffers.iter().enumerate().map(|(b, x)| (b as u32, Res::Buffer(x))).collect();
        groups.push(group(gpu, pipeline, 3, &resources));
    }
    dispatch(&mut encoder, pipeline, &groups.iter().collect::<Vec<_>>(), threads);
    encoder.copy_buffer_to_buffer(&image, 0, &read, 0, size);
    gpu.count_dispatch();
    finish(gpu, encoder, &read)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    #[test]
    fn every_shader_is_valid_wgsl() {
        let sources = MODELS
            .iter()
            .flat_map(|(name, _)| [(*name, compose(name).unwrap()), (*name, compose_render(name).unwrap())])
            .chain([("raster", compose_raster())]);
        for (name, src) in sources {
            validate(name, &src);
        }
    }

    /// Parses and validates a composed module with naga as wgpu would, without a GPU; panics with naga's message.
    pub(crate) fn validate(name: &str, src: &str) {
        let module =
            wgpu::naga::front::wgsl::parse_str(src).unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(src)));
        wgpu::naga::valid::Validator::new(
            wgpu::naga::valid::ValidationFlags::all(),
            wgpu::naga::valid::Capabilities::all(),
        )
        .validate(&module)
        .unwrap_or_else(|e| panic!("{name}: {e:?}"));
    }
}
