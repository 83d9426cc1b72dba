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

use nalgebra::Complex;

/// The oscillating modes among a continuous state matrix's eigenvalues: `(|s| / 2 pi` in Hz,
/// damping ratio `-Re s / |s|)` of each pole pair (the member with `Im s > 0`), lowest first.
pub fn continuous_modes(eigenvalues: impl IntoIterator<Item = Complex<f64>>) -> Vec<(f64, f64)> {
    let mut m: Vec<(f64, f64)> = eigenvalues
        .into_iter()
        .filter(|s| s.im > 0.0)
        .map(|s| (s.norm() / std::f64::consts::TAU, -s.re / s.norm()))
        .collect();
    m.sort_by(|x, y| x.0.total_cmp(&y.0));
    m
}
