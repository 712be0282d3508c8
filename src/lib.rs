//! lamina: layered BRDF models for rendering research.
//!
//! Layout: `optics` (Fresnel, microfacet distributions, diffuse lobes) → `bsdf` (single rough interfaces) →
//! `stack` (the layer stack description) → `models` (one module per model) → `reference` (the Monte Carlo ground
//! truth, with `sampling`) → `python` (the NumPy bindings).
//! Conventions are stated once in docs/conventions.md.

pub mod bsdf;
pub mod error;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod models;
pub mod optics;
pub mod quadrature;
pub mod reference;
pub mod render;
pub mod sampling;
pub mod stack;
pub mod tables;

#[cfg(feature = "python")]
mod python;

/// A fingerprint of the sources this build was made from (build.rs): part of every on-disk cache key, so that a
/// table or reference cached by another build of lamina is never read back.
pub const SOURCE_HASH: &str = env!("LAMINA_SOURCE_HASH");
