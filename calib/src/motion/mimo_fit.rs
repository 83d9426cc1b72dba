//! The physical model of a compliant 3-DOF parallel cell, linear about one pose, and its fit to
//! records of the three motor encoders and the measured tool (Dressler ch. 6, the `M s^2 + D s + K`
//! form, for the whole cell instead of one axis).
//!
//! Coordinates: the carts' displacements along their guideways `c` (3) and the tool's
//! displacement `T` (3). Each cart hangs on its motor through a drive train `k_d, d_d`; each arm's
//! link cluster is an axial spring `k_i, d_i` whose stretch is `G_i x = (u_i . v_i) c_i - u_i . T`
//! (`u_i` the link direction from the tool to the cart, `v_i` the guideway). So
//!
//! ```text
//! M x'' + D x' + K x = B_k a + B_d a'
//! M = diag(m_c I, m_p I),  K = diag(k_d I, 0) + sum_i k_i G_i^T G_i,  D likewise,
//! B_k = [k_d I; 0],  B_d = [d_d I; 0]
//! ```
//!
//! with the motor positions `a` as the input. Sampled exactly for a motor position that is a
//! straight line between samples (first-order hold). The masses are given (weighed); the three
//! link stiffnesses and dampings and the drive train's stiffness and damping (one for all three
//! carts) are fitted by Levenberg-Marquardt on the tool's simulation error, with the tool's rest
//! position as three more parameters.

use nalgebra::{Complex, DMatrix, DVector, SMatrix, SVector, Vector3};
use serde::Serialize;

use super::identify::Mode;
use crate::error::{CalibError, Result};

/// Number of mechanical states (positions and velocities of 3 carts and the tool).
const NS: usize = 12;
/// Fitted structural parameters: 3 link stiffnesses, 3 link dampings, drive stiffness, drive damping.
const NP: usize = 8;

/// The cell's directions at the pose the model is linear about.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CellGeometry {
    /// Unit guideway directions `v_i`, base frame.
    pub guideway: [Vector3<f64>; 3],
    /// Unit link directions `u_i` from the tool to the cart joint, base frame.
    pub link: [Vector3<f64>; 3],
}

/// The cell's masses, stiffnesses and dampings.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CellStructure {
    /// Platform and tool mass, kg (given).
    pub platform_kg: f64,
    /// Cart mass, kg (given).
    pub cart_kg: f64,
    /// Drive-train stiffness, N/m.
    pub drive_n_m: f64,
    /// Drive-train damping, N s/m.
    pub drive_n_s_m: f64,
    /// Axial link-cluster stiffnesses, N/m.
    pub link_n_m: [f64; 3],
    /// Axial link-cluster dampings, N s/m.
    pub link_n_s_m: [f64; 3],
}

type A12 = SMatrix<f64, NS, NS>;
type B12 = SMatrix<f64, NS, 3>;

impl CellStructure {
    fn free(&self) -> [f64; NP] {
        let [k1, k2, k3] = self.link_n_m;
        let [d1, d2, d3] = self.link_n_s_m;
        [k1, k2, k3, d1, d2, d3, self.drive_n_m, self.drive_n_s_m]
    }

    fn with_free(&self, p: &[f64; NP]) -> Self {
        Self {
            link_n_m: [p[0], p[1], p[2]],
            link_n_s_m: [p[3], p[4], p[5]],
            drive_n_m: p[6],
            drive_n_s_m: p[7],
            ..*self
        }
    }

    /// Names of the fitted parameters, in the order of [`CellFit::std`].
    pub fn parameter_names() -> [&'static str; NP] {
        ["k1_n_m", "k2_n_m", "k3_n_m", "d1_n_s_m", "d2_n_s_m", "d3_n_s_m", "drive_n_m", "drive_n_s_m"]
    }

    /// Mass, damping and stiffness matrices over `(c, T)`.
    pub fn mdk(&self, g: &CellGeometry) -> [SMatrix<f64, 6, 6>; 3] {
        let mut m = SMatrix::<f64, 6, 6>::zeros();
        let mut d = SMatrix::<f64, 6, 6>::zeros();
        let mut k = SMatrix::<f64, 6, 6>::zeros();
        for i in 0..3 {
            m[(i, i)] = self.cart_kg;
            m[(3 + i, 3 + i)] = self.platform_kg;
            k[(i, i)] = self.drive_n_m;
            d[(i, i)] = self.drive_n_s_m;
            let mut row = SVector::<f64, 6>::zeros();
            row[i] = g.link[i].dot(&g.guideway[i]);
            for j in 0..3 {
                row[3 + j] = -g.link[i][j];
            }
            let gg = row * row.transpose();
            k += gg * self.link_n_m[i];
            d += gg * self.link_n_s_m[i];
        }
        [m, d, k]
    }

    /// Continuous state matrix over `(c, T, c', T')` and the inputs of `a` and `a'`.
    fn continuous(&self, g: &CellGeometry) -> (A12, B12, B12) {
        let [m, d, k] = self.mdk(g);
        let minv = SMatrix::<f64, 6, 6>::from_diagonal(&m.diagonal().map(|v| 1.0 / v));
        let mut a = A12::zeros();
        a.fixed_view_mut::<6, 6>(0, 6).copy_from(&SMatrix::<f64, 6, 6>::identity());
        a.fixed_view_mut::<6, 6>(6, 0).copy_from(&(-minv * k));
        a.fixed_view_mut::<6, 6>(6, 6).copy_from(&(-minv * d));
        let mut bk = B12::zeros();
        let mut bd = B12::zeros();
        for i in 0..3 {
            bk[(6 + i, i)] = self.drive_n_m / self.cart_kg;
            bd[(6 + i, i)] = self.drive_n_s_m / self.cart_kg;
        }
        (a, bk, bd)
    }

    /// The modes with the motors held, lowest first (`(Hz, damping)`).
    pub fn modes(&self, g: &CellGeometry) -> Vec<(f64, f64)> {
        let (a, _, _) = self.continuous(g);
        let mut m: Vec<(f64, f64)> = a
            .complex_eigenvalues()
            .iter()
            .filter(|s| s.im > 0.0)
            .map(|s| (s.norm() / std::f64::consts::TAU, -s.re / s.norm()))
            .collect();
        m.sort_by(|x, y| x.0.total_cmp(&y.0));
        m
    }

    /// Frequency response from the motor positions to the tool (3 x 3, m/m) at `f_hz`.
    pub fn frequency_response(&self, g: &CellGeometry, f_hz: f64) -> [[Complex<f64>; 3]; 3] {
        let s = Complex::new(0.0, std::f64::consts::TAU * f_hz);
        let [m, d, k] = self.mdk(g);
        let z = DMatrix::<Complex<f64>>::from_fn(6, 6, |r, c| {
            Complex::new(k[(r, c)], 0.0) + s * d[(r, c)] + s * s * m[(r, c)]
        });
        let mut rhs = DMatrix::<Complex<f64>>::zeros(6, 3);
        for i in 0..3 {
            rhs[(i, i)] = Complex::new(self.drive_n_m, 0.0) + s * self.drive_n_s_m;
        }
        let x = z.lu().solve(&rhs).unwrap_or_else(|| DMatrix::from_element(6, 3, Complex::new(f64::NAN, 0.0)));
        [0, 1, 2].map(|r| [0, 1, 2].map(|c| x[(3 + r, c)]))
    }

    /// The tool's displacement from rest driven by the motors' displacements from rest (both
    /// sampled at `dt_s`, the motors a straight line between samples), from rest.
    pub fn simulate(&self, g: &CellGeometry, motor_m: &[[f64; 3]], dt_s: f64) -> Vec<[f64; 3]> {
        let (phi, g0, g1) = self.discrete(g, dt_s);
        let mut x = SVector::<f64, NS>::zeros();
        let mut out = Vec::with_capacity(motor_m.len());
        for k in 0..motor_m.len() {
            out.push([x[3], x[4], x[5]]);
            let a = Vector3::from(motor_m[k]);
            let next = motor_m.get(k + 1).map(|v| Vector3::from(*v)).unwrap_or(a);
            x = phi * x + g0 * a + g1 * ((next - a) / dt_s);
        }
        out
    }

    /// Exact first-order-hold sampling: `x+ = Phi x + G0 a_k + G1 (a_(k+1) - a_k) / dt`.
    fn discrete(&self, g: &CellGeometry, dt_s: f64) -> (A12, B12, B12) {
        let (a, bk, bd) = self.continuous(g);
        // z = (x, a, a'): x' = A x + Bk a + Bd a', a' = a', a'' = 0.
        let mut aug = SMatrix::<f64, 18, 18>::zeros();
        aug.fixed_view_mut::<NS, NS>(0, 0).copy_from(&(a * dt_s));
        aug.fixed_view_mut::<NS, 3>(0, NS).copy_from(&(bk * dt_s));
        aug.fixed_view_mut::<NS, 3>(0, NS + 3).copy_from(&(bd * dt_s));
        for i in 0..3 {
            aug[(NS + i, NS + 3 + i)] = dt_s;
        }
        let e = aug.exp();
        (
            e.fixed_view::<NS, NS>(0, 0).into_owned(),
            e.fixed_view::<NS, 3>(0, NS).into_owned(),
            e.fixed_view::<NS, 3>(0, NS + 3).into_owned(),
        )
    }
}

/// The result of [`fit_cell`].
#[derive(Clone, Debug)]
pub struct CellFit {
    /// The fitted structure (masses as given).
    pub structure: CellStructure,
    /// Standard deviations of the fitted parameters, in [`CellStructure::parameter_names`] order.
    pub std: [f64; NP],
    /// The tool's rest position, m, and its standard deviation.
    pub rest_m: [[f64; 2]; 3],
    /// The modes with standard deviations, lowest first.
    pub modes: Vec<Mode>,
    /// Standard deviation of the tool's simulation error per axis, m.
    pub residual_std_m: f64,
    /// Levenberg-Marquardt iterations.
    pub iterations: usize,
}

/// Fits the structure's stiffnesses and dampings (masses of `start` kept) to records of the motor
/// encoders and the measured tool (both m, base frame, sample time `dt_s`, starting at rest), at
/// the pose described by `geometry`. The model's modes are kept below the Nyquist frequency.
pub fn fit_cell(
    geometry: &CellGeometry,
    encoder_m: &[[f64; 3]],
    tool_m: &[[f64; 3]],
    dt_s: f64,
    start: &CellStructure,
) -> Result<CellFit> {
    let n = encoder_m.len();
    if n != tool_m.len() || n < 200 {
        return Err(CalibError::TooFew(format!(
            "cell fit: {n} encoder and {} tool samples; equal counts of at least 200 needed",
            tool_m.len()
        )));
    }
    if let Some(k) = encoder_m.iter().chain(tool_m).position(|r| r.iter().any(|v| !v.is_finite())) {
        return Err(CalibError::Data(format!("cell fit: sample {} is not finite", k % n)));
    }
    if !(dt_s > 0.0 && dt_s.is_finite()) {
        return Err(CalibError::Data(format!("cell fit: sample time {dt_s} s")));
    }
    let s0 = start.free();
    if !(start.platform_kg > 0.0 && start.cart_kg > 0.0) || s0.iter().any(|v| !(*v > 0.0 && v.is_finite())) {
        return Err(CalibError::Data(format!("cell fit: the start needs positive masses and parameters: {start:?}")));
    }
    let a0 = encoder_m[0];
    let motors: Vec<[f64; 3]> = encoder_m.iter().map(|r| [r[0] - a0[0], r[1] - a0[1], r[2] - a0[2]]).collect();
    let skip = 10usize;
    let m = 3 * (n - skip);
    // Parameters: logs of the structure's free values, then the rest position (m).
    let residual = |p: &[f64; NP + 3]| -> DVector<f64> {
        let s = start.with_free(&std::array::from_fn(|i| p[i].exp()));
        let sim = s.simulate(geometry, &motors, dt_s);
        DVector::from_iterator(
            m,
            (skip..n).flat_map(|k| (0..3).map(move |j| (k, j))).map(|(k, j)| tool_m[k][j] - p[NP + j] - sim[k][j]),
        )
    };
    type P = [f64; NP + 3];
    let mut p: P = [0.0; NP + 3];
    for i in 0..NP {
        p[i] = s0[i].ln();
    }
    for j in 0..3 {
        p[NP + j] = tool_m[..skip.max(1)].iter().map(|r| r[j]).sum::<f64>() / skip.max(1) as f64;
    }
    // The Jacobian's columns `cols` (log parameters by forward differences; the rest position's
    // columns are exact).
    let jacobian = |p: &P, r0: &DVector<f64>, cols: &[usize]| -> DMatrix<f64> {
        let mut jac = DMatrix::zeros(m, cols.len());
        for (k, &c) in cols.iter().enumerate() {
            if c < NP {
                let h = 1e-6;
                let mut q = *p;
                q[c] += h;
                jac.set_column(k, &((residual(&q) - r0) / h));
            } else {
                for r in (c - NP..m).step_by(3) {
                    jac[(r, k)] = -1.0;
                }
            }
        }
        jac
    };
    // A mode above the Nyquist frequency cannot be told from its alias below it: while the drive
    // is fitted the model's modes are kept below it (a step that puts one above is refused).
    let nyquist_hz = 0.5 / dt_s;
    let below_nyquist = |p: &P| {
        let s = start.with_free(&std::array::from_fn(|i| p[i].exp()));
        s.modes(geometry).iter().all(|m| m.0 < nyquist_hz)
    };
    let all: Vec<usize> = (0..NP + 3).collect();
    let lm = |mut p: P, max_iterations: usize, cols: &[usize], nyquist: bool| -> (P, f64, DVector<f64>, usize) {
        let mut r = residual(&p);
        let mut cost = r.norm_squared();
        let mut mu = 1e-3;
        let mut iterations = 0;
        for it in 0..max_iterations {
            iterations = it + 1;
            let jac = jacobian(&p, &r, cols);
            let jtj = jac.transpose() * &jac;
            let grad = -(jac.transpose() * &r);
            let mut improved = false;
            for _ in 0..12 {
                let mut h = jtj.clone();
                for i in 0..cols.len() {
                    h[(i, i)] += mu * jtj[(i, i)].max(1e-30);
                }
                let Some(step) = h.cholesky().map(|c| c.solve(&grad)) else {
                    mu *= 10.0;
                    continue;
                };
                let mut q = p;
                for (k, &i) in cols.iter().enumerate() {
                    // Bound a log step to a factor of e^0.5 per iteration.
                    q[i] += if i < NP { step[k].clamp(-0.5, 0.5) } else { step[k] };
                }
                if nyquist && !below_nyquist(&q) {
                    mu *= 10.0;
                    continue;
                }
                let rq = residual(&q);
                let cq = rq.norm_squared();
                if cq.is_finite() && cq < cost {
                    let rel = (cost - cq) / cost;
                    p = q;
                    r = rq;
                    cost = cq;
                    mu = (mu * 0.3).max(1e-9);
                    improved = rel > 1e-10;
                    break;
                }
                mu *= 10.0;
            }
            if !improved {
                break;
            }
        }
        (p, cost, r, iterations)
    };
    // Stage 1: the links and the rest position with the drive trains rigid (their modes far
    // above the band): the platform's modes, which the record determines best.
    let mut q = p;
    q[6] = (start.cart_kg * (std::f64::consts::TAU * 20.0 * nyquist_hz).powi(2)).ln();
    q[7] = (2.0 * 0.05 * (q[6].exp() * start.cart_kg).sqrt()).ln();
    let links: Vec<usize> = (0..6).chain(NP..NP + 3).collect();
    let (stage1, _, _, _) = lm(q, 30, &links, false);
    // Stage 2: the carts' three near-equal modes are weakly excited through the servos and give
    // the cost local minima in the drive's stiffness and damping: a few iterations from a grid of
    // cart modes (20 % to 95 % of the Nyquist frequency; damping ratio 2 %, 8 %), then the best
    // one to the end, the modes kept below the Nyquist frequency (a 10 s record otherwise settled
    // on carts at 156 Hz, the alias of the true 101 Hz).
    let mut best: Option<(P, f64)> = None;
    for frac in [0.2, 0.35, 0.5, 0.65, 0.8, 0.95] {
        for zeta in [0.02, 0.08] {
            let kd = start.cart_kg * (std::f64::consts::TAU * frac * nyquist_hz).powi(2);
            let mut q = stage1;
            q[6] = kd.ln();
            q[7] = (2.0 * zeta * (kd * start.cart_kg).sqrt()).ln();
            if !below_nyquist(&q) {
                continue;
            }
            let (q, c, _, _) = lm(q, 6, &all, true);
            if best.as_ref().is_none_or(|b| c < b.1) {
                best = Some((q, c));
            }
        }
    }
    let Some((best, _)) = best else {
        return Err(CalibError::Data(format!(
            "cell fit: every start puts a mode above the Nyquist frequency {nyquist_hz:.1} Hz; the links are too stiff \
             for this sample time"
        )));
    };
    let (p, cost, r, iterations) = lm(best, 60, &all, true);
    let structure = start.with_free(&std::array::from_fn(|i| p[i].exp()));
    let dof = (m - (NP + 3)).max(1) as f64;
    let s2 = cost / dof;
    let jac = jacobian(&p, &r, &all);
    let cov = (jac.transpose() * &jac)
        .try_inverse()
        .ok_or_else(|| CalibError::Numeric("cell fit: the normal matrix is singular".into()))?
        * s2;
    let free = structure.free();
    let std: [f64; NP] = std::array::from_fn(|i| free[i] * cov[(i, i)].max(0.0).sqrt());
    let rest_m = [0, 1, 2].map(|j| [p[NP + j], cov[(NP + j, NP + j)].max(0.0).sqrt()]);
    // Mode standard deviations by central differences in the log parameters.
    let base = structure.modes(geometry);
    let mut grads = vec![[[0.0; 2]; NP]; base.len()];
    for c in 0..NP {
        let h: f64 = 1e-5;
        let mut up = free;
        up[c] *= h.exp();
        let mut dn = free;
        dn[c] *= (-h).exp();
        let mu_ = structure.with_free(&up).modes(geometry);
        let md = structure.with_free(&dn).modes(geometry);
        if mu_.len() != base.len() || md.len() != base.len() {
            continue;
        }
        for (k, g) in grads.iter_mut().enumerate() {
            g[c] = [(mu_[k].0 - md[k].0) / (2.0 * h), (mu_[k].1 - md[k].1) / (2.0 * h)];
        }
    }
    let modes = base
        .iter()
        .zip(&grads)
        .map(|(&(f, z), g)| {
            let var = |w: usize| {
                let mut v = 0.0;
                for a in 0..NP {
                    for b in 0..NP {
                        v += g[a][w] * cov[(a, b)] * g[b][w];
                    }
                }
                v.max(0.0).sqrt()
            };
            Mode { frequency_hz: f, frequency_std_hz: var(0), damping: z, damping_std: var(1) }
        })
        .collect();
    Ok(CellFit { structure, std, rest_m, modes, residual_std_m: s2.sqrt(), iterations })
}

/// Percentage fit `100 (1 - |y - yhat| / |y - mean y|)` over the three axes together.
pub fn fit_percent_3(y: &[[f64; 3]], yhat: &[[f64; 3]]) -> f64 {
    let mut num = 0.0;
    let mut den = 0.0;
    for j in 0..3 {
        let mean = y.iter().map(|r| r[j]).sum::<f64>() / y.len().max(1) as f64;
        for (a, b) in y.iter().zip(yhat) {
            num += (a[j] - b[j]).powi(2);
            den += (a[j] - mean).powi(2);
        }
    }
    100.0 * (1.0 - (num / den.max(f64::MIN_POSITIVE)).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn geometry() -> CellGeometry {
        let x = Vector3::x();
        CellGeometry {
            guideway: [x, x, x],
            link: [
                Vector3::new(-0.87, 0.4, 0.3).normalize(),
                Vector3::new(-0.9, -0.2, 0.39).normalize(),
                Vector3::new(-0.87, 0.29, -0.41).normalize(),
            ],
        }
    }

    fn truth() -> CellStructure {
        CellStructure {
            platform_kg: 8.0,
            cart_kg: 4.0,
            drive_n_m: 1.5e6,
            drive_n_s_m: 150.0,
            link_n_m: [1.0e5, 1.2e5, 0.9e5],
            link_n_s_m: [40.0, 45.0, 35.0],
        }
    }

    #[test]
    fn the_static_gain_moves_the_tool_with_the_rigid_kinematics() {
        // Stiff everything: the tool follows the links' closure `u_i . dT = (u_i . v_i) da_i`.
        let g = geometry();
        let s = CellStructure { drive_n_m: 1e9, link_n_m: [1e9; 3], ..truth() };
        let h = s.frequency_response(&g, 1e-3);
        let u = nalgebra::Matrix3::from_rows(&[g.link[0].transpose(), g.link[1].transpose(), g.link[2].transpose()]);
        let w = nalgebra::Matrix3::from_diagonal(&Vector3::from_fn(|i, _| g.link[i].dot(&g.guideway[i])));
        let rigid = u.try_inverse().unwrap() * w;
        for r in 0..3 {
            for c in 0..3 {
                assert!((h[r][c].re - rigid[(r, c)]).abs() < 1e-4, "{r},{c}: {} vs {}", h[r][c], rigid[(r, c)]);
            }
        }
    }

    #[test]
    fn a_fit_from_a_wrong_start_recovers_the_structure_that_made_the_record() {
        // Same family: the record comes from this module's own linear model (exact recovery).
        let g = geometry();
        let t = truth();
        let n = 3000;
        let mut seed = 12345u64;
        let mut lv = [0.001f64; 3];
        // From rest: the motors start at zero, as the fit assumes.
        let motors: Vec<[f64; 3]> = std::iter::once([0.0; 3])
            .chain(
                (1..n)
                    .map(|k| {
                        for l in lv.iter_mut() {
                            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                            if k % 2 == 0 && (seed >> 33) & 1 == 1 {
                                *l = -*l;
                            }
                        }
                        // A smoothed motor (the servo): first-order filter of the binary levels.
                        lv
                    })
                    .scan([0.0f64; 3], |s, l| {
                        for j in 0..3 {
                            s[j] += 0.5 * (l[j] - s[j]);
                        }
                        Some(*s)
                    }),
            )
            .collect();
        let tool: Vec<[f64; 3]> =
            t.simulate(&g, &motors, 0.004).iter().map(|r| [r[0] + 0.1, r[1] - 0.2, r[2] + 0.3]).collect();
        let start =
            CellStructure { drive_n_m: 0.8e6, drive_n_s_m: 300.0, link_n_m: [1.5e5; 3], link_n_s_m: [20.0; 3], ..t };
        let fit = fit_cell(&g, &motors, &tool, 0.004, &start).unwrap();
        eprintln!("iterations {} residual {:e} {:?}", fit.iterations, fit.residual_std_m, fit.structure);
        let truth_modes = t.modes(&g);
        for (m, tm) in fit.modes.iter().zip(&truth_modes) {
            assert!((m.frequency_hz / tm.0 - 1.0).abs() < 1e-4, "{m:?} vs {tm:?}");
        }
        assert!((fit.structure.link_n_m[1] / 1.2e5 - 1.0).abs() < 1e-3, "{:?}", fit.structure);
        assert!((fit.rest_m[2][0] - 0.3).abs() < 1e-9);
    }

    #[test]
    fn short_or_broken_records_are_refused() {
        let g = geometry();
        let e = fit_cell(&g, &[[0.0; 3]; 10], &[[0.0; 3]; 10], 0.004, &truth()).unwrap_err().to_string();
        assert!(e.contains("200"), "{e}");
        let mut tool = vec![[0.0; 3]; 300];
        tool[7][1] = f64::NAN;
        let e = fit_cell(&g, &[[0.0; 3]; 300], &tool, 0.004, &truth()).unwrap_err().to_string();
        assert!(e.contains("sample 7"), "{e}");
    }
}
