//! The compliant 3-DOF Gantry-Tau cell (issue [motion] item 1): the L1's nominal kinematics
//! (`robot::parallel::presets::gantry_tau_l1`) with the compliance between the drives and the tool
//! that the source's dynamic experiments met.
//!
//! Each guideway's drive is the source's closed actuator loop (a first-order lag with five samples
//! of dead time at 4 ms) and imposes the motor position `a_i`, which the encoder reads. The cart
//! (mass `m_c`, the cart with its share of the links) hangs on the motor through the drive train
//! (rack, pinion, belt: stiffness `k_d`, damping `d_d` along the guideway): the source measured
//! carts shifting by up to 100 µm when the links' load changed. Each arm's link cluster is an axial
//! spring-damper (`k_i`, `d_i`, rest length the kinematic `L_i`) between the cart joint
//! `C_i = A_i + c_i v_i` and the platform point `T` (mass `m_p`, platform and tool; the clusters'
//! parallelograms keep its orientation constant). Gravity loads the platform:
//!
//! ```text
//! a_i'  = (r_i(t - delay) - a_i) / tau
//! m_c c_i'' = k_d (a_i - c_i) + d_d (a_i' - c_i') - f_i (u_i . v_i)
//! m_p T''   = sum_i f_i u_i + m_p g
//! f_i = k_i (l_i - L_i) + d_i l_i',   l_i = |C_i - T|,   u_i = (C_i - T) / l_i
//! ```
//!
//! The equations are integrated as they stand (the geometry, the links' preload from gravity and
//! its change with the pose included) by fourth-order Runge-Kutta with sub-steps, the reference
//! held over each sample. The tracker reads `T` with Gaussian noise.
//!
//! Model family: the identification in `ferrocal_calib::motion::mimo_fit` fits a linear model
//! about one pose (no preload, no change of the link directions with the motion, the motor
//! position between samples a straight line), so it does not share this simulator's family; the
//! masses are given to it (weighed), the stiffnesses and dampings are estimated.

use nalgebra::{DMatrix, SMatrix, SVector, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use ferrocal_calib::motion::mimo_fit::{CellGeometry, CellStructure};
use ferrocal_robot::parallel::presets::gantry_tau_l1;
use ferrocal_robot::parallel::GantryTau3;
use ferrocal_robot::Kinematics;

use super::TrueMode;
use crate::error::{DatasetError, Result};

/// State size: motors 3, carts 3, cart velocities 3, platform 3, platform velocity 3.
const NX: usize = 15;
type State = SVector<f64, NX>;

/// The true compliant cell.
#[derive(Clone, Debug, PartialEq)]
pub struct CompliantCell {
    /// The kinematics (every guideway direction a unit vector).
    pub robot: GantryTau3,
    /// Masses, drive trains (one for every cart) and link clusters (axial, with their joints).
    pub structure: CellStructure,
    /// Gravity along `-z` of the base frame, m/s^2.
    pub gravity_m_s2: f64,
    /// Time constant of the closed actuator loops, s.
    pub servo_tau_s: f64,
    /// Dead time of the actuator loops, samples.
    pub servo_delay_samples: usize,
    /// Sample time, s.
    pub dt_s: f64,
    /// Runge-Kutta steps per sample.
    pub substeps: usize,
}

/// One simulated record of the cell.
#[derive(Clone, Debug, PartialEq)]
pub struct CellRecord {
    /// References of the three drives, m.
    pub reference_m: Vec<[f64; 3]>,
    /// Encoder readings (motor positions), m.
    pub encoder_m: Vec<[f64; 3]>,
    /// True tool position (platform point), base frame, m.
    pub tool_true_m: Vec<[f64; 3]>,
    /// Measured tool position, m.
    pub tool_measured_m: Vec<[f64; 3]>,
}

impl CompliantCell {
    /// The L1 cell: the source's actuator loop at 4 ms, an 8 kg platform with tool, 4 kg carts on
    /// drive trains of 1.5 MN/m, link clusters of 1.35-1.8 x 10^5 N/m; its structure's lowest modes
    /// lie in the source's 7-16 Hz range (Table 6.4), the carts' near 100 Hz.
    pub fn l1_like() -> Self {
        let dt_s = 0.004;
        Self {
            robot: gantry_tau_l1(),
            structure: CellStructure {
                platform_kg: 8.0,
                cart_kg: 4.0,
                drive_n_m: 1.5e6,
                drive_n_s_m: 150.0,
                link_n_m: [1.5e5, 1.8e5, 1.35e5],
                link_n_s_m: [130.0, 145.0, 115.0],
            },
            gravity_m_s2: 9.81,
            servo_tau_s: -dt_s / 0.9647f64.ln(),
            servo_delay_samples: 5,
            dt_s,
            substeps: 8,
        }
    }

    fn validate(&self) -> Result<()> {
        let pos =
            [self.structure.platform_kg, self.structure.cart_kg, self.structure.drive_n_m, self.servo_tau_s, self.dt_s];
        let nonneg = [self.structure.drive_n_s_m, self.gravity_m_s2];
        let ok = pos.iter().all(|v| v.is_finite() && *v > 0.0)
            && nonneg.iter().all(|v| v.is_finite() && *v >= 0.0)
            && self.structure.link_n_m.iter().all(|v| v.is_finite() && *v > 0.0)
            && self.structure.link_n_s_m.iter().all(|v| v.is_finite() && *v >= 0.0)
            && self.substeps > 0;
        if !ok {
            return Err(DatasetError::Input(format!(
                "compliant cell: masses, stiffnesses, tau, dt must be finite and positive, dampings and gravity \
                 finite and not negative, substeps at least 1 (platform {} kg, cart {} kg, drive {} N/m, links {:?} N/m)",
                self.structure.platform_kg, self.structure.cart_kg, self.structure.drive_n_m, self.structure.link_n_m
            )));
        }
        self.robot.validate().map_err(|e| DatasetError::Input(format!("compliant cell: {e}")))?;
        for (i, arm) in self.robot.arms.iter().enumerate() {
            if (arm.v.norm() - 1.0).abs() > 1e-9 {
                return Err(DatasetError::Input(format!(
                    "compliant cell: guideway {} direction has norm {:.9}; the dynamics need unit directions",
                    i + 1,
                    arm.v.norm()
                )));
            }
        }
        Ok(())
    }

    /// The rigid (kinematic) tool position for motor positions `q`.
    pub fn rigid_tool(&self, q: &[f64; 3]) -> Result<Vector3<f64>> {
        self.robot
            .forward(q)
            .map(|p| p.translation.vector)
            .map_err(|e| DatasetError::Input(format!("compliant cell: carts at {q:?} m: {e}")))
    }

    /// Motor positions that put the rigid tool at `t`.
    pub fn rigid_joints(&self, t: &Vector3<f64>) -> Result<[f64; 3]> {
        self.robot
            .inverse_position(t)
            .map_err(|e| DatasetError::Input(format!("compliant cell: tool at {:?} m: {e}", t.as_slice())))
    }

    fn cart_point(&self, i: usize, c: f64) -> Vector3<f64> {
        self.robot.arms[i].a_m + self.robot.arms[i].v * c
    }

    /// Time derivative of the state for the (delayed) references `r`.
    fn derivative(&self, x: &State, r: &[f64; 3]) -> State {
        let mut dx = State::zeros();
        let t = Vector3::new(x[9], x[10], x[11]);
        let tv = Vector3::new(x[12], x[13], x[14]);
        let mut platform_force = Vector3::new(0.0, 0.0, -self.structure.platform_kg * self.gravity_m_s2);
        for i in 0..3 {
            let (a, c, cv) = (x[i], x[3 + i], x[6 + i]);
            let ad = (r[i] - a) / self.servo_tau_s;
            dx[i] = ad;
            dx[3 + i] = cv;
            let v = self.robot.arms[i].v;
            let d = self.cart_point(i, c) - t;
            let l = d.norm();
            let u = d / l;
            let ld = u.dot(&(v * cv - tv));
            let f = self.structure.link_n_m[i] * (l - self.robot.arms[i].length_m) + self.structure.link_n_s_m[i] * ld;
            let drive = self.structure.drive_n_m * (a - c) + self.structure.drive_n_s_m * (ad - cv);
            dx[6 + i] = (drive - f * u.dot(&v)) / self.structure.cart_kg;
            platform_force += u * f;
        }
        for k in 0..3 {
            dx[9 + k] = tv[k];
            dx[12 + k] = platform_force[k] / self.structure.platform_kg;
        }
        dx
    }

    /// The state at rest with the motors at `a`: carts and platform where the drive trains, the
    /// links and gravity balance (Newton on the six positions from the rigid kinematics).
    pub fn equilibrium(&self, a: [f64; 3]) -> Result<SVector<f64, NX>> {
        self.validate()?;
        let t0 = self.rigid_tool(&a)?;
        let mut x = State::zeros();
        for i in 0..3 {
            x[i] = a[i];
            x[3 + i] = a[i];
            x[9 + i] = t0[i];
        }
        let idx = [3usize, 4, 5, 9, 10, 11];
        let acc = |x: &State| {
            let d = self.derivative(x, &a);
            SVector::<f64, 6>::from_fn(|k, _| d[idx[k] + 3])
        };
        for _ in 0..30 {
            let f = acc(&x);
            if f.norm() < 1e-10 {
                return Ok(x);
            }
            let mut jac = SMatrix::<f64, 6, 6>::zeros();
            for (k, &j) in idx.iter().enumerate() {
                let h = 1e-7;
                let mut xp = x;
                xp[j] += h;
                let mut xm = x;
                xm[j] -= h;
                jac.set_column(k, &((acc(&xp) - acc(&xm)) / (2.0 * h)));
            }
            let step = jac.lu().solve(&(-f)).ok_or_else(|| {
                DatasetError::Input(format!("compliant cell: no static equilibrium at motors {a:?} m (singular)"))
            })?;
            for (k, &j) in idx.iter().enumerate() {
                x[j] += step[k];
            }
        }
        let f = acc(&x);
        if f.norm() < 1e-6 {
            Ok(x)
        } else {
            Err(DatasetError::Input(format!(
                "compliant cell: static equilibrium at motors {a:?} m not found (residual acceleration {:.2e} m/s^2)",
                f.norm()
            )))
        }
    }

    /// The structure's six modes at rest with the motors held at `a` (the motion equations
    /// linearised numerically about the equilibrium, the preload included), lowest first.
    pub fn modes_at(&self, a: [f64; 3]) -> Result<Vec<TrueMode>> {
        let x0 = self.equilibrium(a)?;
        let mech: Vec<usize> = (3..NX).collect();
        let n = mech.len();
        let mut jac = DMatrix::<f64>::zeros(n, n);
        for (k, &j) in mech.iter().enumerate() {
            let h = 1e-7;
            let mut xp = x0;
            xp[j] += h;
            let mut xm = x0;
            xm[j] -= h;
            let d = (self.derivative(&xp, &a) - self.derivative(&xm, &a)) / (2.0 * h);
            for (r, &i) in mech.iter().enumerate() {
                jac[(r, k)] = d[i];
            }
        }
        let modes = TrueMode::of(jac.complex_eigenvalues().iter().copied());
        if modes.len() != 6 {
            return Err(DatasetError::Input(format!(
                "compliant cell: {} oscillating modes at motors {a:?} m, expected 6 (overdamped?)",
                modes.len()
            )));
        }
        Ok(modes)
    }

    /// The cell's geometry at rest with the motors at `a`, as the linear fit sees it: the
    /// guideway directions and the link directions at the equilibrium.
    pub fn geometry_at(&self, a: [f64; 3]) -> Result<CellGeometry> {
        let x = self.equilibrium(a)?;
        let t = Vector3::new(x[9], x[10], x[11]);
        let link = [0, 1, 2].map(|i| (self.cart_point(i, x[3 + i]) - t).normalize());
        Ok(CellGeometry { guideway: [0, 1, 2].map(|i| self.robot.arms[i].v), link })
    }

    /// Runs the cell from rest (static equilibrium at the first reference) over the references,
    /// sampled at `dt_s`; the tool is measured with Gaussian noise of `tool_sigma_m` per axis and
    /// the encoders are rounded to `encoder_resolution_m`.
    pub fn run(
        &self,
        reference_m: &[[f64; 3]],
        encoder_resolution_m: f64,
        tool_sigma_m: f64,
        seed: u64,
    ) -> Result<CellRecord> {
        let r0 = reference_m.first().copied().unwrap_or([0.0; 3]);
        self.run_from(r0, reference_m, encoder_resolution_m, tool_sigma_m, seed)
    }

    /// As [`Self::run`], from rest with the motors at `start_m` whatever the first reference
    /// (a learning trial's initial state stays put while its references change); the references
    /// before the dead time has passed are `start_m`.
    pub fn run_from(
        &self,
        start_m: [f64; 3],
        reference_m: &[[f64; 3]],
        encoder_resolution_m: f64,
        tool_sigma_m: f64,
        seed: u64,
    ) -> Result<CellRecord> {
        self.validate()?;
        if let Some(k) = reference_m.iter().position(|r| r.iter().any(|v| !v.is_finite())) {
            return Err(DatasetError::Input(format!("compliant cell: reference sample {k} is not finite")));
        }
        if !(encoder_resolution_m >= 0.0 && tool_sigma_m >= 0.0) {
            return Err(DatasetError::Input(format!(
                "compliant cell: encoder resolution {encoder_resolution_m} m and tool sigma {tool_sigma_m} m must not be negative"
            )));
        }
        let r0 = start_m;
        let mut x = self.equilibrium(r0)?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let normal = Normal::new(0.0, tool_sigma_m.max(f64::MIN_POSITIVE)).expect("finite sigma");
        let n = reference_m.len();
        let mut rec = CellRecord {
            reference_m: reference_m.to_vec(),
            encoder_m: Vec::with_capacity(n),
            tool_true_m: Vec::with_capacity(n),
            tool_measured_m: Vec::with_capacity(n),
        };
        let h = self.dt_s / self.substeps as f64;
        let quant = |v: f64| {
            if encoder_resolution_m > 0.0 {
                (v / encoder_resolution_m).round() * encoder_resolution_m
            } else {
                v
            }
        };
        for k in 0..n {
            rec.encoder_m.push([quant(x[0]), quant(x[1]), quant(x[2])]);
            let t = [x[9], x[10], x[11]];
            rec.tool_true_m.push(t);
            let mut noisy = t;
            if tool_sigma_m > 0.0 {
                noisy.iter_mut().for_each(|v| *v += normal.sample(&mut rng));
            }
            rec.tool_measured_m.push(noisy);
            let r = if k >= self.servo_delay_samples { reference_m[k - self.servo_delay_samples] } else { r0 };
            for _ in 0..self.substeps {
                let k1 = self.derivative(&x, &r);
                let k2 = self.derivative(&(x + k1 * (h / 2.0)), &r);
                let k3 = self.derivative(&(x + k2 * (h / 2.0)), &r);
                let k4 = self.derivative(&(x + k3 * h), &r);
                x += (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0);
            }
            if x.iter().any(|v| !v.is_finite()) {
                return Err(DatasetError::Input(format!("compliant cell: the simulation diverged at sample {k}")));
            }
        }
        Ok(rec)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_l1_cell_rests_near_its_rigid_pose_and_has_modes_in_the_sources_range() {
        let cell = CompliantCell::l1_like();
        let a = [0.0; 3];
        let x = cell.equilibrium(a).unwrap();
        let rigid = cell.rigid_tool(&a).unwrap();
        let sag = (Vector3::new(x[9], x[10], x[11]) - rigid).norm();
        // Gravity on 8 kg through links of ~1e5 N/m: a sag of a few hundred µm to a few mm.
        eprintln!("sag {:.3} mm", sag * 1e3);
        assert!(sag > 1e-5 && sag < 5e-3, "sag {sag} m");
        let modes = cell.modes_at(a).unwrap();
        eprintln!("{modes:?}");
        assert!(modes[0].frequency_hz > 6.0 && modes[0].frequency_hz < 16.0, "{modes:?}");
        assert!(modes[5].frequency_hz > 60.0 && modes[5].frequency_hz < 125.0, "{modes:?}");
        assert!(modes.iter().all(|m| m.damping > 0.001 && m.damping < 0.2), "{modes:?}");
    }

    #[test]
    fn a_held_reference_stays_at_rest_and_a_step_settles_on_the_new_equilibrium() {
        let cell = CompliantCell::l1_like();
        let mut r = vec![[0.0; 3]; 2500];
        r[20..].iter_mut().for_each(|v| *v = [0.01, -0.005, 0.002]);
        let rec = cell.run(&r, 0.0, 0.0, 1).unwrap();
        let t0 = rec.tool_true_m[0];
        let drift = (0..3).map(|k| (rec.tool_true_m[20][k] - t0[k]).abs()).fold(0.0, f64::max);
        assert!(drift < 1e-9, "drifted {drift} m at rest");
        let end = cell.equilibrium([0.01, -0.005, 0.002]).unwrap();
        let last = rec.tool_true_m[2499];
        assert!((0..3).all(|k| (last[k] - end[9 + k]).abs() < 1e-6), "{last:?} vs {:?}", &end.as_slice()[9..12]);
    }

    #[test]
    fn bad_cells_and_references_are_refused_by_name() {
        let mut cell = CompliantCell::l1_like();
        cell.robot.arms[1].v *= 1.01;
        let e = cell.equilibrium([0.0; 3]).unwrap_err().to_string();
        assert!(e.contains("guideway 2"), "{e}");
        let cell = CompliantCell::l1_like();
        let e = cell.run(&[[0.0; 3], [f64::NAN, 0.0, 0.0]], 0.0, 0.0, 1).unwrap_err().to_string();
        assert!(e.contains("sample 1"), "{e}");
    }
}
