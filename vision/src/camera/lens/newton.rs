//! The one Newton iteration behind every lens model's inverse: damped steps, halved until the
//! pixel residual drops, with the stopping and acceptance thresholds every model shares.

use super::Unprojection;

/// Pixel residual below which the iterative inverse stops.
pub(super) const UNPROJECT_STOP_PX: f64 = 1e-12;
/// Pixel residual above which the iterative inverse reports failure.
pub(super) const UNPROJECT_ACCEPT_PX: f64 = 1e-10;
/// Maximum Newton iterations of the inverse.
pub(super) const UNPROJECT_MAX_ITERATIONS: usize = 60;

/// Where a converged inverse ended.
pub(super) struct Solved<X, S> {
    /// The unknown.
    pub x: X,
    /// What the model evaluated there.
    pub state: S,
    /// Pixel residual left.
    pub res_px: f64,
    /// Newton iterations run.
    pub iterations: usize,
}

/// Damped Newton from `x` (where `eval` gave `state` and `res_px`): while the residual is above
/// [`UNPROJECT_STOP_PX`] (at most [`UNPROJECT_MAX_ITERATIONS`] times) the full step `d` is
/// `direction(state)` (or the reason it has none) and the candidates `advance(x, d, s)` with
/// `s = 1, 1/2, ...` (40 at most) are evaluated until one lowers the residual; the iteration
/// ends when none does. A residual left above [`UNPROJECT_ACCEPT_PX`] fails with `not_reached`.
pub(super) fn damped_newton<X: Copy, S, D>(
    start: (X, S, f64),
    eval: impl Fn(X) -> Option<(S, f64)>,
    direction: impl Fn(&S) -> Result<D, &'static str>,
    advance: impl Fn(X, &D, f64) -> X,
    not_reached: &'static str,
) -> Result<Solved<X, S>, Unprojection> {
    let fail = |iterations, residual_px, reason| Unprojection { iterations, residual_px, reason };
    let (mut x, mut state, mut res_px) = start;
    let mut iterations = 0;
    while res_px > UNPROJECT_STOP_PX && iterations < UNPROJECT_MAX_ITERATIONS {
        iterations += 1;
        let d = direction(&state).map_err(|reason| fail(iterations, res_px, reason))?;
        let mut step = 1.0;
        let mut accepted = false;
        for _ in 0..40 {
            let cand = advance(x, &d, step);
            if let Some((next, nres)) = eval(cand) {
                if nres < res_px || nres <= UNPROJECT_STOP_PX {
                    x = cand;
                    state = next;
                    res_px = nres;
                    accepted = true;
                    break;
                }
            }
            step *= 0.5;
        }
        if !accepted {
            break;
        }
    }
    if res_px > UNPROJECT_ACCEPT_PX || !res_px.is_finite() {
        return Err(fail(iterations, res_px, not_reached));
    }
    Ok(Solved { x, state, res_px, iterations })
}
