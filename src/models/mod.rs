//! The BRDF models behind `Stack.eval(model=...)`. Each model is a pure function of the stack, its options and
//! one pair of directions; it writes one value per channel.

pub mod microfacet;

use crate::optics::fresnel::FresnelForm;
use crate::optics::microfacet::{Distribution, G2Form};
use crate::stack::{value_error, Result, Stack};
use glam::DVec3;

/// Names accepted by `model=`, in the order `lamina.MODELS` lists them.
pub const MODELS: &[&str] = &["microfacet"];

#[derive(Clone, Copy, Debug)]
pub struct Options {
    pub distribution: Distribution,
    pub g2: G2Form,
    pub fresnel: FresnelForm,
}

impl Default for Options {
    fn default() -> Self {
        Options { distribution: Distribution::Ggx, g2: G2Form::HeightCorrelated, fresnel: FresnelForm::Exact }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Model {
    Microfacet,
}

impl Model {
    pub fn parse(name: &str) -> Result<Model> {
        match name {
            "microfacet" => Ok(Model::Microfacet),
            _ => value_error(format!("model must be one of {MODELS:?}, got {name:?}")),
        }
    }

    /// Rejects stacks the model cannot represent, with a message naming the reason.
    pub fn check(self, stack: &Stack) -> Result<()> {
        match self {
            Model::Microfacet => microfacet::check(stack),
        }
    }

    /// f(wi, wo) for every channel into `out` (length = stack.channels). Unit directions, local frame.
    pub fn eval(self, stack: &Stack, opts: &Options, wi: DVec3, wo: DVec3, out: &mut [f64]) {
        match self {
            Model::Microfacet => microfacet::eval(stack, opts, wi, wo, out),
        }
    }
}
