//! The simulated recordings of the diagnose tests and study: `ferrocal_datasets::sim::scenario`
//! (in the library, so that the demo shows the same cases).
#![allow(unused_imports)]

pub use ferrocal_datasets::sim::scenario::*;
