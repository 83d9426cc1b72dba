//! The mechanism's solvers: the platform pose of given joints (Newton's method with the
//! assembly-mode guard, and by continuation from a known pose), the joints of a given pose, and
//! the start of the platform cluster.

use super::*;

impl Mechanism {
    /// Checks the assembly-mode guard: every leg on its side, and `pose` within the option's
    /// translation and rotation bounds of `start`.
    fn guard(&self, q: &[f64], start: &Pose, pose: &Pose, opts: &SolverOptions) -> std::result::Result<(), String> {
        let states = self.states_unchecked(q, pose);
        if let Some(msg) = self.side_violation(&states) {
            return Err(format!("converged to another assembly mode: {msg}"));
        }
        let dt = (pose.translation.vector - start.translation.vector).norm();
        let dr = pose.rotation.angle_to(&start.rotation);
        if dt > opts.max_translation_m || dr > opts.max_rotation_rad {
            return Err(format!(
                "converged {dt:.3} m and {:.1} deg from the start pose (bounds {:.3} m, {:.1} deg): probably another assembly mode",
                dr.to_degrees(),
                opts.max_translation_m,
                opts.max_rotation_rad.to_degrees()
            ));
        }
        Ok(())
    }

    /// Forward kinematics by Newton on the tool pose, from `start`, for mechanisms with six legs.
    /// Rejects (with [`RobotError::FkNotConverged`]) a solution that breaks the guard.
    pub fn solve_pose(&self, q: &[f64], start: &Pose, opts: &SolverOptions) -> Result<Pose> {
        self.check(q)?;
        if self.legs.len() != 6 {
            return Err(RobotError::FkNotConverged {
                reason: format!("Newton on the pose needs 6 legs, the mechanism has {}", self.legs.len()),
            });
        }
        let mut x = *start;
        let mut res = f64::INFINITY;
        for _ in 0..opts.max_iterations {
            let lin = self.linearize_unchecked(q, &x);
            res = lin.max_length_error_m();
            let Some(mut step) = solve_square(lin.fx, &(-lin.f)) else {
                return Err(RobotError::FkNotConverged {
                    reason: format!("singular pose derivative (leg-length error {res:.3e} m)"),
                });
            };
            if res <= opts.tolerance_m {
                if step.norm() < 1e-6 {
                    x = apply_twist(&x, &step.fixed_rows::<3>(0).into(), &step.fixed_rows::<3>(3).into());
                }
                return self
                    .guard(q, start, &x, opts)
                    .map(|_| x)
                    .map_err(|reason| RobotError::FkNotConverged { reason });
            }
            cap_step(&mut step, opts.max_step);
            x = apply_twist(&x, &step.fixed_rows::<3>(0).into(), &step.fixed_rows::<3>(3).into());
        }
        Err(RobotError::FkNotConverged {
            reason: format!("no convergence after {} iterations (leg-length error {res:.3e} m)", opts.max_iterations),
        })
    }

    /// Forward kinematics by continuation: from a known solution `pose_from` at `q_from`, walks to
    /// `q_to` in `opts.continuation_steps` equal joint-space steps, solving by Newton (with the
    /// guard) at each.
    pub fn solve_pose_continuation(
        &self,
        q_from: &[f64],
        pose_from: &Pose,
        q_to: &[f64],
        opts: &SolverOptions,
    ) -> Result<Pose> {
        self.check(q_from)?;
        self.check(q_to)?;
        let n = opts.continuation_steps.max(1);
        let mut pose = *pose_from;
        for k in 1..=n {
            let t = k as f64 / n as f64;
            let qk: Vec<f64> = q_from.iter().zip(q_to).map(|(a, b)| a + t * (b - a)).collect();
            pose = self
                .solve_pose(&qk, &pose, opts)
                .map_err(|e| RobotError::FkNotConverged { reason: format!("continuation step {k} of {n}: {e}") })?;
        }
        Ok(pose)
    }

    /// Newton on the joints `joints` (0-based) to close the legs `legs` at a fixed tool pose,
    /// from `q0` (other joints keep their `q0` values). Square systems only.
    pub fn solve_joints(
        &self,
        legs: &[usize],
        joints: &[usize],
        q0: &[f64],
        t_base_tool: &Pose,
        opts: &SolverOptions,
    ) -> Result<Vec<f64>> {
        self.check(q0)?;
        let n = joints.len();
        if legs.len() != n || legs.iter().any(|&k| k >= self.legs.len()) || joints.iter().any(|&j| j >= self.dof()) {
            return Err(RobotError::Singular {
                reason: "joint solve needs as many legs as joints, all in range".into(),
            });
        }
        let mut q = q0.to_vec();
        let mut res = f64::INFINITY;
        for it in 0..opts.max_iterations {
            let lin = self.linearize_unchecked(&q, t_base_tool);
            let f = DVector::from_iterator(n, legs.iter().map(|&k| lin.f[k]));
            res = legs
                .iter()
                .map(|&k| lin.f[k].abs() / (2.0 * lin.states[k].length_m.abs().max(1e-9)))
                .fold(0.0, f64::max);
            let jac = DMatrix::from_fn(n, n, |r, c| lin.fq[(legs[r], joints[c])]);
            let Some(mut step) = solve_square(jac, &(-f)) else {
                return Err(RobotError::IkNotConverged { iterations: it + 1, residual_m: res, residual_rad: 0.0 });
            };
            if res <= opts.tolerance_m {
                if step.norm() < 1e-6 {
                    for (c, &j) in joints.iter().enumerate() {
                        q[j] += step[c];
                    }
                }
                return Ok(q);
            }
            cap_step(&mut step, opts.max_step);
            for (c, &j) in joints.iter().enumerate() {
                q[j] += step[c];
            }
        }
        Err(RobotError::IkNotConverged { iterations: opts.max_iterations, residual_m: res, residual_rad: 0.0 })
    }

    /// Start pose for the Newton solvers of Gantry-Tau models: each carriage's legs averaged into
    /// one virtual link (centre `mean(A_k(q) - b0_k)`, radius `mean(L_k)`), the three spheres
    /// intersected on the `assembly` side, identity platform orientation. Exact when each cluster
    /// is a parallelogram with equal lengths and the platform is not rotated.
    pub fn cluster_start(&self, q: &[f64], assembly: Branch) -> Result<Pose> {
        self.check(q)?;
        if self.carriages.len() != 3 {
            return Err(RobotError::FkNotConverged { reason: "the cluster start needs three carriages".into() });
        }
        let evals = self.carriage_evals(q);
        let mut centres = [Vector3::zeros(); 3];
        let mut radii = [0.0; 3];
        for (c, (centre, radius)) in centres.iter_mut().zip(radii.iter_mut()).enumerate() {
            let mut n = 0.0;
            for leg in self.legs.iter().filter(|l| l.carriage == Some(c)) {
                *centre += evals[c].point(&leg.a_m) - leg.b0_m;
                *radius += leg.length_m + leg.length_joint.map_or(0.0, |j| q[j]);
                n += 1.0;
            }
            if n == 0.0 {
                return Err(RobotError::FkNotConverged {
                    reason: format!("{} carries no link", self.carriages[c].name),
                });
            }
            *centre /= n;
            *radius /= n;
        }
        let t = trilaterate(&centres, &radii, assembly).map_err(|reason| RobotError::Unreachable { reason })?;
        Ok(Isometry3::from_parts(Translation3::from(t), UnitQuaternion::identity()) * self.tool)
    }
}
