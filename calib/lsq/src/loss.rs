//! The one robust-loss type of the project.

use serde::{Deserialize, Serialize};

/// A robust loss `rho(s)` applied to the squared norm `s` of each whitened residual block (so its
/// thresholds are in standard deviations). Ceres uses the same definitions, so a problem gives the
/// same cost on either back end.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Loss {
    /// Plain least squares, `rho(s) = s`.
    #[default]
    Squared,
    /// Huber: quadratic up to `delta` (in whitened units, i.e. standard deviations), linear beyond.
    Huber {
        /// Threshold in standard deviations.
        delta: f64,
    },
    /// Cauchy: `delta^2 log(1 + s / delta^2)`.
    Cauchy {
        /// Scale in standard deviations.
        delta: f64,
    },
}

impl Loss {
    /// The loss of a block's squared norm `s`, and its derivative `rho'(s)` (the IRLS weight).
    pub fn rho(&self, s: f64) -> (f64, f64) {
        match *self {
            Loss::Squared => (s, 1.0),
            Loss::Huber { delta } => {
                let d2 = delta * delta;
                if s <= d2 {
                    (s, 1.0)
                } else {
                    let r = s.sqrt();
                    (2.0 * delta * r - d2, delta / r)
                }
            }
            Loss::Cauchy { delta } => {
                let d2 = delta * delta;
                (d2 * (1.0 + s / d2).ln(), 1.0 / (1.0 + s / d2))
            }
        }
    }

    /// Checks the loss's parameter (a positive, finite threshold).
    pub fn validate(&self) -> crate::Result<()> {
        match *self {
            Loss::Squared => Ok(()),
            Loss::Huber { delta } | Loss::Cauchy { delta } if delta.is_finite() && delta > 0.0 => Ok(()),
            other => Err(crate::LsqError::Setup(format!("{other:?}: the threshold must be positive and finite"))),
        }
    }

    /// The same loss as a Ceres loss function (`None` for plain least squares).
    pub fn to_ceres(&self) -> Option<ceres_solver::LossFunction> {
        match *self {
            Loss::Squared => None,
            Loss::Huber { delta } => Some(ceres_solver::LossFunction::huber(delta)),
            Loss::Cauchy { delta } => Some(ceres_solver::LossFunction::cauchy(delta)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_are_the_derivative_of_the_loss() {
        for loss in [Loss::Squared, Loss::Huber { delta: 1.5 }, Loss::Cauchy { delta: 0.7 }] {
            for s in [0.01, 0.5, 2.0, 9.0, 100.0] {
                let h = 1e-6 * s;
                let numeric = (loss.rho(s + h).0 - loss.rho(s - h).0) / (2.0 * h);
                assert!((numeric - loss.rho(s).1).abs() < 1e-6, "{loss:?} at {s}");
            }
        }
        assert!(Loss::Huber { delta: -1.0 }.validate().is_err());
        assert!(Loss::Cauchy { delta: f64::NAN }.validate().is_err());
    }
}
