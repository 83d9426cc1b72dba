//! Motion identification and learning control on tool-side measurements (Dressler ch. 6-7):
//!
//! - [`identify`]: black-box output-error models of sampled records (Steiglitz-McBride, then
//!   Levenberg-Marquardt on the simulation error), their modes with standard deviations, and
//!   validation on separate data;
//! - [`physical`]: the physical `M s^2 + D s + K` chain fitted to the encoder and tool records;
//! - [`kalman`]: the tool position estimated from the encoder, the chain and a delayed camera;
//! - [`sync`]: the camera clock's offset (and rate) against the encoder, estimated from the data;
//! - [`ilc`]: norm-optimal iterative learning control in lifted form from an identified model.
//!
//! The simulated axis these are exercised on is `ferrocal_datasets::motion`; the experiments
//! are in `docs/motion.md`.

pub mod identify;
pub mod ilc;
pub mod kalman;
pub mod mimo_fit;
pub mod mimo_frf;
pub mod mimo_ilc;
pub mod physical;
pub mod sync;
