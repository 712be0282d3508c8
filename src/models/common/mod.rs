//! What the models share and none of them is: their options (`options`), importance sampling by a mixture of their
//! lobes (`mixture`; in float32 lanes `mixture_lanes`), the single-pass layer walk of Steinberg, Weidlich–Wilkie and
//! albedo scaling (`single_pass`; in float32 lanes `walk_lanes`), the evaluation of blocks of rows (`block`), and what
//! a model's GPU half is (`gpu`).

pub mod block;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod mixture;
pub mod mixture_lanes;
pub mod options;
pub mod single_pass;
#[cfg(test)]
pub mod testing;
pub mod walk_lanes;
