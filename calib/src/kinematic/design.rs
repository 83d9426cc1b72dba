//! The calibration problem's Jacobian for pose selection (experiment design).

use super::*;

/// The whitened, column-scaled Jacobian of the calibration problem at the start values for
/// joint configurations `poses` (measurements simulated by the nominal model, each with position
/// standard deviation `sigma_position_m`), over the candidates the options leave free. Rows come
/// in blocks of 3 per pose (6 with orientations); columns are named in the returned names.
/// This is what experiment design (pose selection) works on: the Fisher information of a pose
/// set is `J^T J` over its rows.
pub fn design_jacobian(
    model: &RobotModel,
    poses: &[Vec<f64>],
    sigma_position_m: f64,
    with_orientation: bool,
    opts: &KinematicOptions,
) -> Result<(DMatrix<f64>, Vec<String>)> {
    let mut rows = Vec::with_capacity(poses.len());
    for (k, q) in poses.iter().enumerate() {
        let t = model.forward(q).map_err(|e| CalibError::Data(format!("pose {}: {e}", k + 1)))?;
        let mut r = PoseMeasurement::new(format!("{}", k + 1), q.clone(), t.translation.vector);
        if with_orientation {
            r.orientation = Some(t.rotation);
        }
        r.sigma_m = Some(sigma_position_m);
        rows.push(r);
    }
    let refs: Vec<&PoseMeasurement> = rows.iter().collect();
    let use_ori = with_orientation && opts.use_orientation;
    let layout = StateLayout::for_rows(model, if use_ori { 6 } else { 3 }, opts, &refs)?;
    let start = layout.start_values(model);
    let problem = KinProblem {
        base_model: model.clone(),
        rows: &refs,
        layout: &layout,
        f0: opts.fixed_device_frame.unwrap_or_else(Isometry3::identity),
        tool0: Isometry3::identity(),
        use_ori,
        start: start.clone(),
        free: (0..layout.len()).collect(),
        sigma_pos: vec![sigma_position_m; rows.len()],
        sigma_ori: vec![opts.sigma_orientation_rad; rows.len()],
        whiten: vec![None; rows.len()],
        effects: opts.effects.clone(),
        cost: Cost::ForwardKinematics,
        n_legs: 0,
    };
    let j = problem.full_jacobian(&start)?;
    let allowed: Vec<usize> = (0..layout.len())
        .filter(|&i| {
            (opts.estimate_device_frame || !layout.frame.contains(&i))
                && (opts.estimate_tool || !layout.tool.contains(&i))
                && (opts.joint_offsets || !layout.offsets.contains(&i))
        })
        .collect();
    let scaled = DMatrix::from_fn(j.nrows(), allowed.len(), |r, c| j[(r, allowed[c])] * layout.scales[allowed[c]]);
    Ok((scaled, allowed.iter().map(|&i| layout.names[i].clone()).collect()))
}
