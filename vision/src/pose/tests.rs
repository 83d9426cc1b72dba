//! Unit tests of pose estimation.

use super::*;

#[test]
fn detected_corner_covariances_become_weights_with_a_fallback() {
    let good = Matrix2::new(0.01, 0.002, 0.002, 0.02);
    let bad = Matrix2::new(0.01, 0.0, 0.0, -1.0);
    let noise = CornerNoise::from_detected(&[Some(good), None, Some(bad)], 0.1);
    let CornerNoise::PerCorner(c) = &noise else { panic!("per-corner weights expected") };
    assert_eq!(c[0], good);
    assert!((c[1] - Matrix2::identity() * 0.01).norm() < 1e-15);
    assert!((c[2] - Matrix2::identity() * 0.01).norm() < 1e-15);
    assert!((noise.information(0, 3).unwrap() - good.try_inverse().unwrap()).norm() < 1e-9);
}
