//! lamina: layered BRDF models for rendering research.
//!
//! Layout, each module using only those before it (tests/test_layout.py checks that no `use crate::` closes a cycle):
//! - `error`, `interrupt` (Ctrl-C in long work), `cache` (the checked on-disk cache), `dual` (forward-mode derivatives), `quadrature`, `sampling` (random numbers, direction sampling, MIS), `engine` (the float32 lane engine), `optics` (Fresnel, microfacet
//!   distributions, diffuse lobes, Jacobians), `bsdf` (single rough interfaces), `stack` (the layer stack);
//! - `transport`: a stack's boundaries and slabs as light transport sees them, one channel at a time;
//! - `tables`: lamina's precomputed tables (FGD, Steinberg's, Elek's) and the adding-doubling solver;
//! - `models`: the catalogue, one module per model, their shared machinery (`models/common`) and lamina's
//!   corrections (`models/corrections`);
//! - `reference`: the Monte Carlo ground truth;
//! - `render`: the CPU renderer (scene, lights, environments, meshes, image files); `gpu`: the wgpu path (models and
//!   renderer as WGSL compute shaders); `oat`: Oat 2006's gooey layers on both; `device`: which of them a call uses;
//! - `python`: the thin NumPy bindings.
//!
//! Conventions are stated once in docs/conventions.md.

pub mod bsdf;
pub mod cache;
pub mod device;
pub mod dual;
pub mod engine;
pub mod error;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod interrupt;
pub mod models;
pub mod oat;
pub mod optics;
pub mod quadrature;
pub mod reference;
pub mod render;
pub mod sampling;
pub mod stack;
pub mod tables;
pub mod transport;

#[cfg(feature = "python")]
mod python;

/// A fingerprint of the sources this build was made from (build.rs): part of every on-disk cache key, so that a
/// table or reference cached by another build of lamina is never read back.
pub const SOURCE_HASH: &str = env!("LAMINA_SOURCE_HASH");
