//! The physical `M s^2 + D s + K` form of a compliant axis, fitted to a record: two masses in a
//! chain (links `m1` on the carriage through `k1, d1`, platform and tool `m2` on the links
//! through `k2, d2`), excited at its base by the carriage position the encoder reads. The
//! platform mass is given (it is weighed or taken from CAD: the record fixes only the ratios of
//! mass, stiffness and damping); the other five are fitted by Levenberg-Marquardt on the tool's
//! simulation error, the chain integrated by Runge-Kutta with the encoder interpolated linearly
//! between samples. The start comes from the black-box modes. Standard deviations are first
//! order, from the fit's Jacobian and the residual.

use nalgebra::{DMatrix, DVector, Matrix4, Vector4};

use super::identify::{modes_with_std, Mode};
use crate::error::{CalibError, Result};

/// Masses, stiffnesses and dampers of the chain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChainParams {
    /// Link mass, kg.
    pub m1_kg: f64,
    /// Platform and tool mass, kg.
    pub m2_kg: f64,
    /// Carriage-to-links stiffness, N/m.
    pub k1_n_m: f64,
    /// Links-to-platform stiffness, N/m.
    pub k2_n_m: f64,
    /// Carriage-to-links damping, N s/m.
    pub d1_n_s_m: f64,
    /// Links-to-platform damping, N s/m.
    pub d2_n_s_m: f64,
}

impl ChainParams {
    fn free(&self) -> [f64; 5] {
        [self.m1_kg, self.k1_n_m, self.k2_n_m, self.d1_n_s_m, self.d2_n_s_m]
    }

    fn with_free(&self, v: &[f64]) -> Self {
        Self { m1_kg: v[0], k1_n_m: v[1], k2_n_m: v[2], d1_n_s_m: v[3], d2_n_s_m: v[4], ..*self }
    }

    /// `M`, `D`, `K` over `(x1, x2)`.
    pub fn mdk(&self) -> [[[f64; 2]; 2]; 3] {
        let (k1, k2, d1, d2) = (self.k1_n_m, self.k2_n_m, self.d1_n_s_m, self.d2_n_s_m);
        [[[self.m1_kg, 0.0], [0.0, self.m2_kg]], [[d1 + d2, -d2], [-d2, d2]], [[k1 + k2, -k2], [-k2, k2]]]
    }

    fn state_matrix(&self) -> Matrix4<f64> {
        let (m1, m2, k1, k2, d1, d2) = (self.m1_kg, self.m2_kg, self.k1_n_m, self.k2_n_m, self.d1_n_s_m, self.d2_n_s_m);
        Matrix4::new(
            0.0,
            1.0,
            0.0,
            0.0,
            -(k1 + k2) / m1,
            -(d1 + d2) / m1,
            k2 / m1,
            d2 / m1,
            0.0,
            0.0,
            0.0,
            1.0,
            k2 / m2,
            d2 / m2,
            -k2 / m2,
            -d2 / m2,
        )
    }

    /// The chain's modes with the carriage held: `(|s| / 2 pi` in Hz, damping ratio), lowest first.
    pub fn modes(&self) -> Vec<(f64, f64)> {
        let mut m: Vec<(f64, f64)> = self
            .state_matrix()
            .complex_eigenvalues()
            .iter()
            .filter(|s| s.im > 0.0)
            .map(|s| (s.norm() / std::f64::consts::TAU, -s.re / s.norm()))
            .collect();
        m.sort_by(|x, y| x.0.total_cmp(&y.0));
        m
    }

    /// The frequency response from the carriage to the platform at `f_hz`:
    /// `X2 / A = [(-w^2 M + j w D + K)^-1 (k1 + j w d1, 0)]_2`.
    pub fn frequency_response(&self, f_hz: f64) -> nalgebra::Complex<f64> {
        use nalgebra::Complex;
        let w = std::f64::consts::TAU * f_hz;
        let [m, d, k] = self.mdk();
        let z = |i: usize, j: usize| Complex::new(k[i][j] - w * w * m[i][j], w * d[i][j]);
        let (a, b, c, e) = (z(0, 0), z(0, 1), z(1, 0), z(1, 1));
        let det = a * e - b * c;
        let f = Complex::new(self.k1_n_m, w * self.d1_n_s_m);
        // x2 = (-c f) / det
        -c * f / det
    }

    /// The tool position for the encoder record (m, sample time `dt_s`), from rest at its first
    /// value; `substeps` Runge-Kutta steps per sample.
    pub fn simulate(&self, encoder_m: &[f64], dt_s: f64, substeps: usize) -> Vec<f64> {
        let Some(&a0) = encoder_m.first() else { return Vec::new() };
        let (m1, m2, k1, k2, d1, d2) = (self.m1_kg, self.m2_kg, self.k1_n_m, self.k2_n_m, self.d1_n_s_m, self.d2_n_s_m);
        let f = |x: &Vector4<f64>, a: f64, ad: f64| {
            let (x1, v1, x2, v2) = (x[0], x[1], x[2], x[3]);
            let spring2 = k2 * (x1 - x2) + d2 * (v1 - v2);
            Vector4::new(v1, (k1 * (a - x1) + d1 * (ad - v1) - spring2) / m1, v2, spring2 / m2)
        };
        let h = dt_s / substeps.max(1) as f64;
        let mut x = Vector4::new(a0, 0.0, a0, 0.0);
        let mut out = Vec::with_capacity(encoder_m.len());
        for k in 0..encoder_m.len() {
            out.push(x[2]);
            let a_k = encoder_m[k];
            let a_next = encoder_m.get(k + 1).copied().unwrap_or(a_k);
            let slope = (a_next - a_k) / dt_s;
            for j in 0..substeps.max(1) {
                let t = j as f64 * h;
                let a = |dt: f64| a_k + slope * (t + dt);
                let k1v = f(&x, a(0.0), slope);
                let k2v = f(&(x + k1v * (h / 2.0)), a(h / 2.0), slope);
                let k3v = f(&(x + k2v * (h / 2.0)), a(h / 2.0), slope);
                let k4v = f(&(x + k3v * h), a(h), slope);
                x += (k1v + k2v * 2.0 + k3v * 2.0 + k4v) * (h / 6.0);
            }
        }
        out
    }
}

/// A fitted chain with its uncertainty.
#[derive(Clone, Debug, PartialEq)]
pub struct PhysicalFit {
    /// The fitted parameters (`m2_kg` as given).
    pub params: ChainParams,
    /// Their standard deviations (`m2_kg` 0: given).
    pub std: ChainParams,
    /// The chain's modes with standard deviations.
    pub modes: Vec<Mode>,
    /// Standard deviation of the tool's simulation error, m.
    pub residual_std_m: f64,
}

const SUBSTEPS: usize = 8;

/// Fits the chain to an encoder record and the measured tool (m, sample time `dt_s`), the
/// platform mass given, started from two black-box modes (lowest first).
pub fn fit_chain(
    encoder_m: &[f64],
    tool_m: &[f64],
    dt_s: f64,
    m2_kg: f64,
    start_modes: &[Mode],
) -> Result<PhysicalFit> {
    if encoder_m.len() != tool_m.len() || encoder_m.len() < 100 {
        return Err(CalibError::TooFew(format!(
            "physical fit: {} encoder and {} tool samples; equal counts of at least 100 needed",
            encoder_m.len(),
            tool_m.len()
        )));
    }
    if let Some(i) = encoder_m.iter().chain(tool_m).position(|v| !v.is_finite()) {
        return Err(CalibError::Data(format!("physical fit: sample {} is not finite", i % encoder_m.len())));
    }
    if start_modes.len() < 2 || !(m2_kg > 0.0 && m2_kg.is_finite()) {
        return Err(CalibError::Data(format!(
            "physical fit: two black-box modes and a positive platform mass needed ({} modes, m2 {m2_kg} kg); \
             the lower-rate record may not see the second mode",
            start_modes.len()
        )));
    }
    let skip = 20usize;
    let residual = |p: &ChainParams| -> DVector<f64> {
        let sim = p.simulate(encoder_m, dt_s, SUBSTEPS);
        DVector::from_iterator(tool_m.len() - skip, (skip..tool_m.len()).map(|t| tool_m[t] - sim[t]))
    };
    // Starts: the two modes placed on a grid of link masses.
    let (w1, w2) =
        (start_modes[0].frequency_hz * std::f64::consts::TAU, start_modes[1].frequency_hz * std::f64::consts::TAU);
    let (s, pr) = (w1 * w1 + w2 * w2, w1 * w1 * w2 * w2);
    let mut best: Option<(f64, ChainParams)> = None;
    for i in 0..13 {
        let m1 = m2_kg * 0.05 * 2f64.powf(i as f64 * 0.5);
        let c = 1.0 / m1 + 1.0 / m2_kg;
        let disc = s * s - 4.0 * c * pr * m2_kg;
        if disc < 0.0 {
            continue;
        }
        for k2 in [(s + disc.sqrt()) / (2.0 * c), (s - disc.sqrt()) / (2.0 * c)] {
            let k1 = pr * m1 * m2_kg / k2;
            if !(k1 > 0.0 && k2 > 0.0) {
                continue;
            }
            let p = ChainParams {
                m1_kg: m1,
                m2_kg,
                k1_n_m: k1,
                k2_n_m: k2,
                d1_n_s_m: 2.0 * start_modes[1].damping.max(1e-3) * (k1 * m1).sqrt(),
                d2_n_s_m: 2.0 * start_modes[0].damping.max(1e-3) * (k2 * m2_kg).sqrt(),
            };
            let c = residual(&p).norm_squared();
            if best.as_ref().is_none_or(|b| c < b.0) {
                best = Some((c, p));
            }
        }
    }
    let Some((mut cost, mut p)) = best else {
        return Err(CalibError::Data("physical fit: the two modes admit no chain of positive stiffness".into()));
    };
    // Levenberg-Marquardt in the logarithms of the five free parameters.
    let jacobian = |p: &ChainParams, r0: &DVector<f64>| -> DMatrix<f64> {
        let v = p.free();
        let mut j = DMatrix::zeros(r0.len(), 5);
        for c in 0..5 {
            let h: f64 = 1e-6;
            let mut w = v;
            w[c] *= h.exp();
            let rc = residual(&p.with_free(&w));
            j.set_column(c, &((rc - r0) / h));
        }
        j
    };
    let mut mu = 1e-3;
    for _ in 0..100 {
        let r0 = residual(&p);
        let j = jacobian(&p, &r0);
        let jtj = j.transpose() * &j;
        let g = -(j.transpose() * &r0);
        let mut improved = false;
        for _ in 0..12 {
            let mut h = jtj.clone();
            for i in 0..5 {
                h[(i, i)] *= 1.0 + mu;
            }
            let Some(step) = h.cholesky().map(|ch| ch.solve(&g)) else {
                mu *= 10.0;
                continue;
            };
            let v: Vec<f64> = p.free().iter().zip(step.iter()).map(|(x, s)| x * s.clamp(-2.0, 2.0).exp()).collect();
            let trial = p.with_free(&v);
            let ct = residual(&trial).norm_squared();
            if ct < cost {
                improved = (cost - ct) / cost > 1e-12;
                p = trial;
                cost = ct;
                mu = (mu / 10.0).max(1e-12);
                break;
            }
            mu *= 10.0;
        }
        if !improved {
            break;
        }
    }
    let r0 = residual(&p);
    let j = jacobian(&p, &r0);
    let dof = (r0.len() - 5).max(1) as f64;
    let s2 = r0.norm_squared() / dof;
    let cov = (j.transpose() * &j).try_inverse().ok_or_else(|| {
        CalibError::Numeric("physical fit: the chain parameters are not determined by this record".into())
    })? * s2;
    let v = p.free();
    let sd: Vec<f64> = (0..5).map(|i| v[i] * cov[(i, i)].max(0.0).sqrt()).collect();
    let std = ChainParams { m2_kg: 0.0, ..p.with_free(&sd) };
    // Modes with first-order standard deviations (central differences in the logarithms).
    let modes = modes_with_std(&p.modes(), &cov, &[1e-6; 5], |c, d| {
        let mut w = v;
        w[c] *= d.exp();
        p.with_free(&w).modes()
    });
    Ok(PhysicalFit { params: p, std, modes, residual_std_m: s2.sqrt() })
}
