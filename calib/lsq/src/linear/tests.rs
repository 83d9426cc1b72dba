use nalgebra::{DMatrix, DVector};

use super::*;

fn names(list: &[&str]) -> Vec<String> {
    list.iter().map(|s| s.to_string()).collect()
}

#[test]
fn recovers_a_line_with_its_standard_deviation() {
    let m = 200;
    let a = DMatrix::from_fn(m, 2, |i, j| if j == 0 { 1.0 } else { i as f64 * 0.01 });
    // Deterministic "noise" with zero mean and no trend.
    let noise: Vec<f64> = (0..m).map(|i| if i % 2 == 0 { 0.1 } else { -0.1 }).collect();
    let y = DVector::from_fn(m, |i, _| 3.0 + 2.0 * a[(i, 1)] + noise[i]);
    let f = fit(&a, &y, &names(&["b", "k"]), &Weighting::Unit, &LinearOptions::default()).unwrap();
    assert!((f.values[0] - 3.0).abs() < 0.05 && (f.values[1] - 2.0).abs() < 0.05, "{:?}", f.values);
    assert!((f.s0 - 0.1).abs() < 0.01, "s0 {}", f.s0);
    // Textbook std of the slope: s0 / sqrt(sum (x - mean)^2).
    let xm: f64 = (0..m).map(|i| a[(i, 1)]).sum::<f64>() / m as f64;
    let sxx: f64 = (0..m).map(|i| (a[(i, 1)] - xm).powi(2)).sum();
    assert!((f.std[1] - f.s0 / sxx.sqrt()).abs() < 1e-9 * f.std[1].max(1.0));
    assert!((f.correlation[(0, 0)] - 1.0).abs() < 1e-12);
    assert_eq!((f.rank, f.dof), (2, 198));
}

#[test]
fn block_weights_equal_explicit_gauss_markov() {
    let m = 60;
    let a = DMatrix::from_fn(m, 3, |i, j| ((i * 7 + j * 3) % 11) as f64 - 5.0 + j as f64 * 0.3);
    let y = DVector::from_fn(m, |i, _| (i as f64 * 0.37).sin());
    let cov = DMatrix::from_row_slice(3, 3, &[2.0, 0.5, 0.1, 0.5, 1.0, -0.2, 0.1, -0.2, 0.5]);
    let n = names(&["p0", "p1", "p2"]);
    let wi = cov.clone().try_inverse().unwrap();
    let mut w = DMatrix::zeros(m, m);
    for g in 0..m / 3 {
        w.view_mut((3 * g, 3 * g), (3, 3)).copy_from(&wi);
    }
    let info_inv = (a.transpose() * &w * &a).try_inverse().unwrap();
    let u = &info_inv * a.transpose() * &w * &y;
    for policy in [RankPolicy::Refuse, RankPolicy::Truncate, RankPolicy::DropPivoted] {
        let opts = LinearOptions { covariance: CovarianceScale::APriori, ..LinearOptions::new(policy, 1e-9) };
        let f = fit(&a, &y, &n, &Weighting::Block(cov.clone()), &opts).unwrap();
        for j in 0..3 {
            assert!((u[j] - f.values[j]).abs() < 1e-9, "{policy:?}: {u} vs {:?}", f.values);
            for k in 0..3 {
                assert!((info_inv[(j, k)] - f.covariance[(j, k)]).abs() < 1e-9 * info_inv[(j, j)], "{policy:?}");
            }
        }
        // chi^2 = e^T W e with the unweighted residuals.
        let chi2 = (f.residuals.transpose() * &w * &f.residuals)[(0, 0)];
        assert!((chi2 - f.chi2).abs() < 1e-9 * chi2, "{policy:?}: {chi2} vs {}", f.chi2);
    }
}

#[test]
fn rank_deficiency_names_the_parameters() {
    let m = 30;
    let a = DMatrix::from_fn(m, 3, |i, j| match j {
        0 => i as f64,
        _ => 1.0,
    });
    let y = DVector::from_fn(m, |i, _| i as f64);
    let n = names(&["slope", "offset_a", "offset_b"]);
    let e = fit(&a, &y, &n, &Weighting::Unit, &LinearOptions::default()).unwrap_err();
    let text = e.to_string();
    assert!(text.contains("rank 2") && text.contains("offset_a") && text.contains("offset_b"), "{text}");
    assert!(!text.contains("slope,"), "{text}");
    match e {
        LsqError::RankDeficient { rank, n_params, no_effect, coupled, .. } => {
            assert_eq!((rank, n_params), (2, 3));
            assert!(no_effect.is_empty());
            assert_eq!(coupled, vec![vec!["offset_a".to_string(), "offset_b".to_string()]]);
        }
        other => panic!("{other}"),
    }
}

#[test]
fn options_are_validated_and_bad_input_named() {
    let a = DMatrix::from_fn(5, 2, |i, j| (i + j) as f64);
    let y = DVector::from_element(5, 1.0);
    let n = names(&["a", "b"]);
    let bad = LinearOptions { rank_tolerance: -1.0, ..LinearOptions::default() };
    assert!(fit(&a, &y, &n, &Weighting::Unit, &bad).unwrap_err().to_string().contains("rank tolerance"));
    let mut a2 = a.clone();
    a2[(3, 1)] = f64::NAN;
    let e = fit(&a2, &y, &n, &Weighting::Unit, &LinearOptions::default()).unwrap_err().to_string();
    assert!(e.contains("row 4") && e.contains("'b'"), "{e}");
    let e = fit(&a, &y, &n, &Weighting::Sigmas(vec![1.0; 4]), &LinearOptions::default()).unwrap_err().to_string();
    assert!(e.contains("4 standard deviations for 5 rows"), "{e}");
}
