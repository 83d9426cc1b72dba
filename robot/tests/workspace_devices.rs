//! [planning] measuring devices: what a camera rig can measure (whole target in the image,
//! feature size, viewing angle, line of sight) and how well (the pose estimation's noise), and a
//! laser tracker's range, line of sight and noise.

use ferrocal_robot::safety::ObstacleBox;
use ferrocal_robot::workspace::{
    CameraView, CameraVisibility, MeasuringDevice, TargetShape, TrackerView, VisibilitySettings,
};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

/// A 2048 x 1536 pinhole camera at the origin of the base frame looking along +x (z up in the
/// image).
fn camera(name: &str, y_m: f64) -> CameraView {
    let t = CameraView::look_at([0.0, y_m, 0.0], [3.0, 0.0, 0.0], [0.0, 0.0, 1.0]).unwrap();
    CameraView::pinhole(name, t, 3000.0, 3000.0, 1023.5, 767.5, 2048, 1536)
}

/// The tool at `p` with the target facing -x (towards the cameras), turned by `turn_deg` about z.
fn tool(p: [f64; 3], turn_deg: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(p[0], p[1], p[2]),
        UnitQuaternion::from_euler_angles(0.0, 0.0, turn_deg.to_radians()),
    )
}

fn rig(cams: Vec<CameraView>, occluders: Vec<ObstacleBox>) -> CameraVisibility {
    // Target normal (target z) along -x of the tool.
    let t_tool_target = Isometry3::from_parts(
        Translation3::identity(),
        UnitQuaternion::from_euler_angles(0.0, -std::f64::consts::FRAC_PI_2, 0.0),
    );
    CameraVisibility::new(
        cams,
        TargetShape::plate(0.03, 0.015),
        t_tool_target,
        VisibilitySettings::default(),
        occluders,
    )
    .unwrap()
}

#[test]
fn camera_visibility_names_the_reason() {
    let r = rig(vec![camera("c", 0.0)], vec![]);
    assert!(r.check(&tool([2.0, 0.0, 0.0], 0.0)).is_ok());
    let why = |t: Isometry3<f64>| r.check(&t).unwrap_err().reason;
    assert!(why(tool([2.0, 0.0, 0.0], 75.0)).contains("viewing angle"));
    assert!(why(tool([2.0, 0.0, 0.0], 180.0)).contains("from behind"));
    assert!(why(tool([2.0, 1.0, 0.0], 0.0)).contains("outside the image"));
    assert!(why(tool([12.0, 0.0, 0.0], 0.0)).contains("features too small"));
    let wall = ObstacleBox { name: "pillar".into(), min_m: [1.0, -0.2, -0.2], max_m: [1.1, 0.2, 0.2], margin_m: 0.0 };
    let blocked = rig(vec![camera("c", 0.0)], vec![wall]);
    let e = blocked.check(&tool([2.0, 0.0, 0.0], 0.0)).unwrap_err();
    assert!(e.reason.contains("line of sight blocked by 'pillar'"), "{e}");
    // A second camera that must see as well.
    let two = rig(vec![camera("a", 0.0), camera("b", 3.0)], vec![]);
    assert!(two.check(&tool([2.0, 0.0, 0.0], 0.0)).is_err());
}

#[test]
fn camera_noise_is_anisotropic_and_a_second_camera_fixes_the_depth() {
    let p = [2.0, 0.0, 0.0];
    let one = rig(vec![camera("a", 0.0)], vec![]);
    let c1 = one.position_covariance(&tool(p, 0.0)).unwrap();
    // Device frame = camera a: z is the depth.
    let (lat, depth) = (c1[(0, 0)].sqrt(), c1[(2, 2)].sqrt());
    assert!(depth > 5.0 * lat, "depth {depth:e} lateral {lat:e}");
    // Lateral: about sigma_px * Z / f / sqrt(n): 0.1 px at 2 m with f = 3000 px over 20 corners.
    let expect = 0.1 * 2.0 / 3000.0 / 20f64.sqrt();
    assert!(lat > 0.5 * expect && lat < 4.0 * expect, "lateral {lat:e}, expected about {expect:e}");
    // Farther is worse.
    let far = one.position_covariance(&tool([3.0, 0.0, 0.0], 0.0)).unwrap();
    assert!(far[(2, 2)] > c1[(2, 2)]);
    // A second camera 0.5 m to the side sees the target too: depth is triangulated.
    let t = CameraView::look_at([0.0, 0.5, 0.0], [2.0, 0.0, 0.0], [0.0, 0.0, 1.0]).unwrap();
    let b = CameraView::pinhole("b", t, 3000.0, 3000.0, 1023.5, 767.5, 2048, 1536);
    let two = rig(vec![camera("a", 0.0), b], vec![]);
    assert!(two.check(&tool(p, 0.0)).is_ok());
    let c2 = two.position_covariance(&tool(p, 0.0)).unwrap();
    assert!(c2[(2, 2)].sqrt() < 0.5 * depth, "stereo depth {:e} vs mono {depth:e}", c2[(2, 2)].sqrt());
    assert_eq!(two.t_device_base(), two.cameras[0].t_base_cam.inverse());
}

#[test]
fn tracker_range_line_of_sight_and_noise() {
    let t = TrackerView {
        name: "at960".into(),
        t_base_tracker: Isometry3::translation(0.0, 0.0, 0.0),
        range_m: [1.0, 5.0],
        sigma_const_um: 15.0,
        sigma_per_m_um: 6.0,
        reflector_in_tool_m: Vector3::new(0.0, 0.0, 0.05),
        reflector_axis_in_tool: Some(Vector3::new(-1.0, 0.0, 0.0)),
        max_incidence_deg: 30.0,
        occluders: vec![ObstacleBox {
            name: "column".into(),
            min_m: [1.4, 0.6, -1.0],
            max_m: [1.6, 0.9, 1.0],
            margin_m: 0.0,
        }],
    };
    let at = |x: f64, y: f64| Isometry3::translation(x, y, -0.05);
    assert!(t.check(&at(2.0, 0.0)).is_ok());
    assert!(t.check(&at(0.5, 0.0)).unwrap_err().reason.contains("out of range"));
    assert!(t.check(&at(6.0, 0.0)).unwrap_err().reason.contains("out of range"));
    assert!(t.check(&at(3.0, 1.5)).unwrap_err().reason.contains("line of sight blocked by 'column'"));
    let turned =
        Isometry3::from_parts(Translation3::new(2.0, 0.0, -0.05), UnitQuaternion::from_euler_angles(0.0, 0.0, 1.2));
    assert!(t.check(&turned).unwrap_err().reason.contains("turned away"));
    let c = t.position_covariance(&at(2.0, 0.0)).unwrap();
    let s = (15.0 + 6.0 * 2.0) * 1e-6;
    assert!((c[(0, 0)] - s * s).abs() < 1e-15 && c[(0, 1)] == 0.0);
    let _ = Point3::<f64>::origin();
}
