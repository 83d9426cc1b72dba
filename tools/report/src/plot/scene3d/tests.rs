use super::*;

/// The numbers of every `data-p` attribute of an SVG text.
fn data_points(svg: &str) -> Vec<Vec<f64>> {
    svg.split("data-p=\"")
        .skip(1)
        .map(|rest| rest.split('"').next().unwrap().split(' ').map(|v| v.parse().unwrap()).collect())
        .collect()
}

/// The value of attribute `name` in the element text `el`.
fn attr(el: &str, name: &str) -> f64 {
    el.split(&format!(" {name}=\"")).nth(1).unwrap().split('"').next().unwrap().parse().unwrap()
}

#[test]
fn the_projection_is_orthographic_and_right_handed() {
    let (k, cx, cy) = (100.0, 360.0, 275.0);
    // Seen from +x: +y to the right, +z up, x along the line of sight.
    let at = |p: [f64; 3]| project(&p, 0.0, 0.0, k, cx, cy);
    assert_eq!(at([0.0, 1.0, 0.0]), (cx + k, cy));
    let (x, y) = at([0.0, 0.0, 1.0]);
    assert!((x - cx).abs() < 1e-12 && (y - (cy - k)).abs() < 1e-12);
    assert_eq!(at([1.0, 0.0, 0.0]), (cx, cy));
    // From above (elevation 90 deg) at azimuth 0: +y right, +x down the screen (right-handed).
    let (x, y) = project(&[1.0, 0.0, 0.0], 0.0, std::f64::consts::FRAC_PI_2, k, cx, cy);
    assert!((x - cx).abs() < 1e-9 && (y - (cy + k)).abs() < 1e-9, "({x}, {y})");
    // No length grows on the screen at any angle (orthographic).
    for (az, el) in [(0.3, 0.2), (-2.0, 1.1), (1.0, -0.7)] {
        let (a, b) = (project(&[0.1, 0.2, 0.3], az, el, k, cx, cy), project(&[0.4, -0.2, 0.5], az, el, k, cx, cy));
        let d_screen = ((a.0 - b.0).powi(2) + (a.1 - b.1).powi(2)).sqrt();
        assert!(d_screen <= k * (0.09f64 + 0.16 + 0.04).sqrt() + 1e-9);
    }
}

#[test]
fn every_element_carries_its_point_inside_the_unit_sphere_and_is_drawn_at_the_default_angle() {
    let mut sc = Scene3d::new("cell <test>", "mm");
    sc.camera(&Isometry3::translation(100.0, 0.0, 500.0), 50.0, 0, "camera");
    sc.frame(&Isometry3::identity(), 80.0, "base");
    sc.outline(&[Point3::new(0.0, 0.0, 0.0), Point3::new(200.0, 0.0, 0.0), Point3::new(200.0, 150.0, 0.0)], 1, 2.0);
    sc.dots(&[Point3::new(f64::NAN, 0.0, 0.0)], 2, 3.0); // not finite: left out
    sc.legend(1, "target");
    let svg = sc.to_svg();
    assert!(svg.starts_with("<svg") && svg.ends_with("</script></svg>"));
    assert!(svg.contains("cell &lt;test&gt;") && svg.contains("lengths in mm") && svg.contains(">target</text>"));
    // camera: outline, 4 rays, tick, dot, label (8); frame: 3 axes, label (4); outline (1).
    let data = data_points(&svg);
    assert_eq!(data.len(), 13);
    for d in &data {
        assert!(d.len() % 3 == 0 && !d.is_empty());
        for p in d.chunks(3) {
            let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
            assert!(r <= 1.0 + 1e-3, "{p:?} outside the unit sphere");
        }
    }
    // The first dot (the camera centre) is drawn where project puts it at the default angle.
    let circle = svg.split("<circle ").nth(1).unwrap();
    let p = &data_points(circle)[0];
    let k = 0.46 * (H_PX - 40.0);
    let (x, y) = project(&[p[0], p[1], p[2]], AZIMUTH_RAD, ELEVATION_RAD, k, W_PX / 2.0, 30.0 + (H_PX - 30.0) / 2.0);
    assert!((attr(circle, "cx") - x).abs() < 0.06 && (attr(circle, "cy") - y).abs() < 0.06);
}

#[test]
fn the_up_direction_is_drawn_upwards() {
    // A camera frame: -y is up. The point at -y is above the one at +y on the screen.
    let mut sc = Scene3d::new("camera frame", "m").with_up(-Vector3::y());
    sc.dots(&[Point3::new(0.0, -1.0, 0.0), Point3::new(0.0, 1.0, 0.0)], 0, 3.0);
    let svg = sc.to_svg();
    let cy: Vec<f64> = svg.split("<circle ").skip(1).map(|c| attr(c, "cy")).collect();
    assert!(cy[0] < cy[1] - 100.0, "{cy:?}");
}

#[test]
fn the_scale_bar_is_a_round_length() {
    assert_eq!(nice_length(0.37), 0.2);
    assert_eq!(nice_length(730.0), 500.0);
    assert_eq!(nice_length(1.0), 1.0);
    assert_eq!(fmt_length(0.05), "0.05");
    assert_eq!(fmt_length(200.0), "200");
}

#[test]
fn the_script_holds_nothing_the_html_parser_reads_as_markup() {
    let js = script(200.0, 360.0, 275.0);
    assert!(!js.contains('<') && !js.contains('&'), "{js}");
}
