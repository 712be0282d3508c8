//! lamina's corrections of the published models, each an option of the models it applies to: `transport_fit` (what
//! `variant="improved"` switches on) and the inter-reflections of the single-pass models (`interreflection`,
//! `conductor_interreflection`). The third, `microfacet_transmission`, is a table (tables/steinberg.rs, `T`).

pub mod interreflection;
pub mod transport_fit;
