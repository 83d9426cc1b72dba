use super::*;
use ferrocal_robot::{Parameterized, RobotModel};
use nalgebra::{Matrix3, Translation3, UnitQuaternion};

/// A UR5 whose calibrated model differs from the nominal one: a few millimetres and
/// milliradians in its joint corrections, joint offsets, a device frame 1.5 m away and a tool
/// 0.1 m off the flange.
fn calibrated_ur5() -> CalibratedModel {
    let nominal = RobotModel::load("ur5").unwrap();
    let mut cm = CalibratedModel::nominal(nominal.clone());
    let mut values = cm.model.parameter_values();
    for (k, p) in cm.model.parameters().iter().enumerate() {
        if p.name.contains(".corr_") {
            // 1 mm or 1 mrad steps.
            values[k] += 1e-3 * ((k % 5) as f64 - 2.0);
        }
    }
    cm.model.set_parameter_values(&values).unwrap();
    cm.joint_offsets = vec![0.002, -0.001, 0.0015, 0.0, -0.002, 0.001];
    cm.device_frame =
        Isometry3::from_parts(Translation3::new(1.5, -0.2, 0.3), UnitQuaternion::from_euler_angles(0.01, -0.02, 2.0));
    cm.tool = Isometry3::translation(0.01, 0.02, 0.1);
    cm.orientation_calibrated = true;
    cm
}

fn rows(qs: &[[f64; 6]]) -> Vec<PoseMeasurement> {
    qs.iter().enumerate().map(|(k, q)| PoseMeasurement::new(format!("{k}"), q.to_vec(), Vector3::zeros())).collect()
}

/// The nominal frames fitted over six poses spread over the joint space.
fn frames_of(cm: &CalibratedModel) -> NominalFrames {
    let fit_rows = rows(&[
        [0.1, -1.2, 1.4, -1.8, -1.5, 0.3],
        [-0.8, -1.6, 1.9, -0.7, 1.2, -2.0],
        [0.9, -0.9, 0.8, 0.5, -0.4, 1.0],
        [1.4, -2.0, 2.1, -2.6, 0.9, 2.5],
        [-1.1, -0.6, 1.1, 1.7, 2.2, -0.6],
        [0.4, -1.9, 0.6, -0.2, -2.1, 0.1],
    ]);
    let refs: Vec<&PoseMeasurement> = fit_rows.iter().collect();
    NominalFrames::fit(cm, &refs).unwrap()
}

#[test]
fn the_68_percent_radius_is_the_one_sigma_probability_in_3_d() {
    // Isotropic: the chi distribution with 3 degrees of freedom at 0.6827 is 1.8780.
    let s = 0.3;
    let r = radius_68(&(Matrix3::identity() * s * s));
    assert!((r / s - 1.8780).abs() < 2e-3, "{}", r / s);
    // One axis alone: the 1-D one-sigma interval.
    let r = radius_68(&Matrix3::from_diagonal(&Vector3::new(0.0, s * s, 0.0)));
    assert!((r / s - 1.0).abs() < 2e-3, "{}", r / s);
    // Rotated covariances give the same radius.
    let rot = UnitQuaternion::from_euler_angles(0.3, -1.0, 2.0).to_rotation_matrix().into_inner();
    let c = Matrix3::from_diagonal(&Vector3::new(1.0, 4.0, 0.25));
    assert!((radius_68(&(rot * c * rot.transpose())) - radius_68(&c)).abs() < 1e-6 * radius_68(&c));
    assert_eq!(radius_68(&Matrix3::zeros()), 0.0);
}

#[test]
fn a_command_depends_on_its_row_alone_and_reaches_the_nominal_pose() {
    let cm = calibrated_ur5();
    let frames = frames_of(&cm);
    let program = rows(&[[0.3, -1.1, 1.2, -1.6, -1.57, 0.2], [0.35, -1.15, 1.25, -1.6, -1.57, 0.2]]);
    let opts = effective_options(&cm, &CorrectOptions::default());
    let both = correct_program(&cm, &frames, &program, &opts).unwrap();
    let alone = correct_program(&cm, &frames, &program[1..], &opts).unwrap();
    assert_eq!(both[1].q, alone[0].q);
    for c in &both {
        assert!(c.reached(), "{c:?}");
        assert!(c.nominal_error_m > 1e-4, "the calibration changes the pose: {c:?}");
        assert!(c.sigma_min > 0.01, "{c:?}");
    }
    // A target given as a pose, without a start: the same command as the program's row (the
    // nominal model's inverse kinematics picks the branch nearest its seeds; the program's
    // command is on one of them here).
    let want = frames.intended(&cm, &program[0].q).unwrap();
    let mut target = PoseMeasurement::new("t", vec![], want.translation.vector);
    target.orientation = Some(want.rotation);
    let c = command_for_target(&cm, &frames, &target, &want, &opts).unwrap();
    assert!(c.reached(), "{c:?}");
    let at = cm.predict(&c.q).unwrap();
    assert!((at.translation.vector - want.translation.vector).norm() < 1e-6);
    assert!(at.rotation.angle_to(&want.rotation) < 1e-5);
}

#[test]
fn a_pose_beyond_a_joint_limit_is_not_reached_and_names_the_joint() {
    let mut cm = calibrated_ur5();
    // Joint 1 limited to +-0.5 rad: a pose that needs it at 1.0 rad cannot be reached.
    if let RobotModel::Serial(chain) = &mut cm.model {
        chain.joints[0].limits = ferrocal_robot::JointLimits::new("q1", -0.5, 0.5).unwrap();
    }
    let frames = NominalFrames::over_joint_space(&cm).unwrap();
    assert_eq!(frames.source, FramesSource::JointSpaceSample);
    let row = rows(&[[1.0, -1.2, 1.4, -1.8, -1.5, 0.3]]).remove(0);
    let want = frames.intended(&cm, &row.q).unwrap();
    let opts = effective_options(&cm, &CorrectOptions::default());
    let c = correct_command(&cm, &row, &[0.4, -1.2, 1.4, -1.8, -1.5, 0.3], &want, &opts).unwrap();
    assert!(!c.reached(), "{c:?}");
    assert_eq!(c.at_limit, vec![1]);
}

#[test]
fn the_landing_covariance_grows_with_the_parameters_covariance_and_the_unexplained_scatter() {
    let cm = calibrated_ur5();
    let row = rows(&[[0.3, -1.1, 1.2, -1.6, -1.57, 0.2]]).remove(0);
    let u = Uncertainty {
        names: vec!["frame.x_m".into(), "offset.q2_rad".into()],
        covariance: vec![vec![1e-8, 0.0], vec![0.0, 1e-8]],
        unmodelled_sigma_m: 0.0,
        lack_of_fit_scale: 1.0,
    };
    let c = u.landing_covariance(&cm, &row).unwrap();
    // The device frame's x moves the point along the device's x by the same amount.
    let jq = {
        let (mut a, mut b) = (row.clone(), row.clone());
        a.q[1] += 1e-6;
        b.q[1] -= 1e-6;
        (cm.predict_row(&a).unwrap().translation.vector - cm.predict_row(&b).unwrap().translation.vector) / 2e-6
    };
    let want: Matrix3<f64> = 1e-8 * (Vector3::x() * Vector3::x().transpose()) + 1e-8 * jq * jq.transpose();
    assert!((c - want).norm() < 1e-4 * want.norm(), "{c}\n{want}");
    let with_floor = Uncertainty { unmodelled_sigma_m: 1e-4, ..u.clone() };
    let c2 = with_floor.landing_covariance(&cm, &row).unwrap();
    assert!(((c2 - c) - Matrix3::identity() * 1e-8).norm() < 1e-15);
    // A name the model does not have is an error naming it.
    let bad = Uncertainty {
        names: vec!["joint9.nothing".into()],
        covariance: vec![vec![1.0]],
        unmodelled_sigma_m: 0.0,
        lack_of_fit_scale: 1.0,
    };
    assert!(bad.landing_covariance(&cm, &row).unwrap_err().to_string().contains("joint9.nothing"));
}

/// A command at the wrist singularity (joint 5 at zero, joints 4 and 6 aligned) through a
/// calibration that measured orientations: whether or not a command matching the orientation is
/// found, the row carries a smallest singular value far below the verdict's 0.005 m, and a
/// command 0.3 rad away from it does not.
#[test]
fn a_command_at_the_wrist_singularity_says_so_through_its_singular_value() {
    let cm = calibrated_ur5();
    let frames = frames_of(&cm);
    let opts = effective_options(&cm, &CorrectOptions::default());
    assert!(opts.use_orientation);
    let at = rows(&[[0.3, -1.1, 1.2, -1.6, 0.0, 0.2], [0.3, -1.1, 1.2, -1.6, 0.3, 0.2]]);
    let singular = correct_program_row(&cm, &frames, &at[0], &opts).unwrap();
    let away = correct_program_row(&cm, &frames, &at[1], &opts).unwrap();
    assert!(singular.sigma_min < 0.005, "{}", singular.sigma_min);
    assert!(away.reached() && away.sigma_min > 0.005, "{away:?}");
}
