//! What the models share and none of them is: their options (`options`), importance sampling by a mixture of their
//! lobes (`mixture`), the single-pass layer walk of Steinberg, Weidlich–Wilkie and albedo scaling (`single_pass`),
//! and the evaluation of blocks of rows (`block`).

pub mod block;
pub mod mixture;
pub mod options;
pub mod single_pass;
#[cfg(test)]
pub mod testing;
