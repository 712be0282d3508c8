//! A model's GPU half, as its catalogue entry holds it (`ModelInfo::gpu`): its WGSL, the rule of which options run
//! there, and the kernel it builds from its own prepared model. A kernel is plain data, its `Params` a `#[repr(C)]`
//! struct that mirrors the model's WGSL struct field by field (each half's unit test holds the two together, through
//! naga); src/gpu uploads and dispatches it. Adding a model to the GPU: its WGSL file, its GPU module, one catalogue
//! field.

use crate::error::Result;
use crate::models::Args;
use crate::optics::distribution::{Distribution, G2Form, Microfacet};
use crate::optics::fresnel::FresnelForm;
use crate::stack::Stack;
use bytemuck::{Pod, Zeroable};

/// What the GPU needs of a model.
pub struct GpuHalf {
    /// The model's WGSL, in composition order (after the primitives and sampling, src/gpu/mod.rs `compose`).
    pub shader: &'static [&'static str],
    /// Why the GPU does not run the model with these options (None: it does).
    pub refusal: fn(&Args) -> Option<String>,
    /// The model's kernel for a stack: its parameters, arrays and shared tables.
    pub kernel: fn(&Stack, &Args) -> Result<Kernel>,
}

/// A model prepared for the GPU: the words of its `Params` (the element count set per dispatch at `count_word`), the
/// stack's read-only arrays (layers, per-channel constants, tables of its own), each with the word that holds its
/// offset when stacks are batched, the tables every stack shares, and the channel count. `shader` names the catalogue
/// entry whose pipelines run it.
pub struct Kernel {
    pub shader: &'static str,
    pub words: Vec<u32>,
    pub count_word: usize,
    pub arrays: Vec<(Vec<f32>, usize)>,
    pub tables: Vec<&'static [f32]>,
    pub channels: usize,
    /// lamina's correction transport_fit, when the stack has it (TransportFit::gpu_values, fit.wgsl).
    pub fit: Option<Vec<f32>>,
}

/// Declares a model's `Params`: a `#[repr(C)]` Pod struct that its WGSL struct of the same name mirrors, and (in tests)
/// `Params::FIELDS`, its fields as (name, byte offset) in order, which the model's unit test holds against the WGSL
/// (`gpu::tests::assert_mirrors`).
macro_rules! params {
    ($(#[$meta:meta])* $($field:ident: $ty:ty,)*) => {
        $(#[$meta])*
        #[repr(C)]
        #[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
        pub struct Params {
            $(pub $field: $ty,)*
        }

        #[cfg(test)]
        impl Params {
            pub const FIELDS: &'static [(&'static str, usize)] =
                &[$((stringify!($field), std::mem::offset_of!(Params, $field)),)*];
        }
    };
}
pub(crate) use params;

/// The word of a `Params` field: its byte offset / 4.
macro_rules! word {
    ($ty:ty, $field:ident) => {
        std::mem::offset_of!($ty, $field) / 4
    };
}
pub(crate) use word;

/// The words of a `Params` value.
pub fn words<P: Pod>(params: &P) -> Vec<u32> {
    bytemuck::cast_slice(std::slice::from_ref(params)).to_vec()
}

/// optics.wgsl's `Microfacet`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuMicrofacet {
    pub dist: u32,
    pub smooth_: u32,
    pub alpha_x: f32,
    pub alpha_y: f32,
    pub cos_phi: f32,
    pub sin_phi: f32,
}

impl From<&Microfacet> for GpuMicrofacet {
    fn from(mf: &Microfacet) -> Self {
        let (cos_phi, sin_phi) = mf.frame();
        GpuMicrofacet {
            dist: dist_code(mf.dist),
            smooth_: mf.is_smooth() as u32,
            alpha_x: mf.alpha_x as f32,
            alpha_y: mf.alpha_y as f32,
            cos_phi: cos_phi as f32,
            sin_phi: sin_phi as f32,
        }
    }
}

/// optics.wgsl's code of a masking-shadowing form.
pub fn g2_code(g2: G2Form) -> u32 {
    match g2 {
        G2Form::Separable => 0,
        G2Form::HeightCorrelated => 1,
        G2Form::VCavity => 2,
    }
}

/// optics.wgsl's code of a Fresnel form.
pub fn fresnel_code(form: FresnelForm) -> u32 {
    match form {
        FresnelForm::Exact => 0,
        FresnelForm::Schlick => 1,
        FresnelForm::Lazanyi => 2,
    }
}

/// optics.wgsl's code of a distribution.
pub fn dist_code(dist: Distribution) -> u32 {
    match dist {
        Distribution::Ggx => 0,
        Distribution::Beckmann => 1,
    }
}

/// The single-pass layers (layers.wgsl), the walk (single_pass.wgsl) and their layers' packing, shared by Steinberg,
/// Weidlich–Wilkie and albedo scaling.
pub const LAYERS: &str = include_str!("../../gpu/shaders/layers.wgsl");
pub const SINGLE_PASS: &str = include_str!("../../gpu/shaders/single_pass.wgsl");
