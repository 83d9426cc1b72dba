//! The ideal pinhole: `x_d = X / Z`, `y_d = Y / Z` (no coefficients; the Brown map with every
//! coefficient zero, so that its derivatives are those of the Brown map).

use std::f64::consts::FRAC_PI_2;

use super::{brown, Distorted, LensModel, Unprojection};

/// The ideal pinhole.
#[derive(Clone, Copy, Debug)]
pub struct Pinhole;

impl LensModel for Pinhole {
    const NAME: &'static str = "none";
    const ALIASES: &'static [&'static str] = &[];
    const COEFFICIENTS: &'static [&'static str] = &[];
    const FAMILY: &'static str = "pinhole";
    const CALIBRATED: bool = false;
    const FIELD_LIMIT_RAD: f64 = FRAC_PI_2;

    fn distort(_: &[f64], p: [f64; 3]) -> Result<Distorted, &'static str> {
        brown::distort(&[0.0; 8], p)
    }

    fn one_to_one_at(_: &[f64], _: f64) -> bool {
        true
    }

    fn unproject_normalized(_: &[f64], xd: [f64; 2], _: [f64; 2]) -> Result<[f64; 2], Unprojection> {
        Ok(xd)
    }
}
