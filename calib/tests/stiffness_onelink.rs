//! The source's one-link example (Klimchik et al. 2015): the parameter-to-noise ratios of the
//! Orthoglide link's compliance matrix, the failures of the naive 36-parameter estimate and the
//! reduced estimate that has none; bad input refused with the parameters that can be trusted.

use ferrocal_calib::stiffness::fit::{fit, rms_max};
use ferrocal_calib::stiffness::onelink::{
    entry_ratios, one_link_layout, one_link_problem, orthogonal_design, SOURCE_NOISE, SOURCE_NU,
};
use ferrocal_calib::stiffness::reduce::{aggregate, fixed_vector, sparsity, symmetric};
use ferrocal_calib::stiffness::StiffnessIdError;
use ferrocal_calib::stiffness::{identify_checked, physical_problems, reduce, Parameterization, ReductionSettings};
use ferrocal_robot::stiffness::presets::orthoglide_link_compliance;
use nalgebra::{DVector, Matrix6, Vector6};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// Noisy deflections of `k` under `wrenches` (25 um / 0.25 mrad), and the noise-free ones.
fn measure(k: &Matrix6<f64>, wrenches: &[Vector6<f64>], seed: u64) -> (Vec<Vector6<f64>>, Vec<Vector6<f64>>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let s = SOURCE_NOISE.pose_sigmas();
    let truth: Vec<Vector6<f64>> = wrenches.iter().map(|w| k * w).collect();
    let meas = truth
        .iter()
        .map(|t| {
            Vector6::from_fn(|r, _| {
                let n: f64 = StandardNormal.sample(&mut rng);
                t[r] + s[r] * n
            })
        })
        .collect();
    (meas, truth)
}

#[test]
fn parameter_to_noise_ratios_are_the_sources() {
    let k = orthoglide_link_compliance();
    // 50 repeats of +-10 N / +-10 N m on each axis: W^T W = 10^4 I, std = sigma_i / 100.
    let w = orthogonal_design(50, 10.0, 10.0);
    assert_eq!(w.len(), 600);
    let nu = entry_ratios(&k, &w, &SOURCE_NOISE).unwrap();
    for (name, source) in SOURCE_NU {
        let e = nu.iter().find(|e| e.name == name).unwrap();
        let sigma = if name.as_bytes()[1] <= b'3' { 25e-6 } else { 0.25e-3 };
        assert!((e.std - sigma / 100.0).abs() < 1e-9 * sigma, "{name}: std {:e}", e.std);
        // The source prints 2 to 4 significant digits: agree to its rounding (0.5 % or 0.005).
        let tol = (0.005 * source).max(0.005);
        assert!((e.nu - source).abs() <= tol, "{name}: nu {} vs the source's {source}", e.nu);
        eprintln!("{name}: nu {:.4} (source {source})", e.nu);
    }
    // "27 of 36 entries unusable": the 26 zero entries and k11 have nu below 2.
    assert_eq!(nu.iter().filter(|e| e.nu < 2.0).count(), 27);
}

#[test]
fn the_reduction_of_one_link_is_symmetry_template_and_the_threshold() {
    let layout = one_link_layout();
    let m1 = symmetric(&layout);
    assert_eq!(m1.len(), 21);
    let (m2, gone) = sparsity(&layout, &m1);
    assert_eq!((m2.len(), gone.len()), (8, 13));
    let (m3, merged) = aggregate(&layout, &m2);
    assert_eq!((m3.len(), merged.len()), (8, 0));
    let mut names = m2.names();
    names.sort();
    assert_eq!(names, ["link.k11", "link.k22", "link.k26", "link.k33", "link.k35", "link.k44", "link.k55", "link.k66"]);
}

#[test]
fn the_naive_estimate_fails_as_in_the_source_and_the_reduced_one_does_not() {
    let k = orthoglide_link_compliance();
    let w = orthogonal_design(50, 10.0, 10.0);
    let (val_w, _) = (orthogonal_design(5, 10.0, 10.0), ());
    let layout = one_link_layout();
    let (mut negative_k11, mut naive_bad, mut k11_kept, trials) = (0, 0, 0, 40);
    let mut samples: Vec<(f64, f64, f64, f64)> = Vec::new();
    for seed in 0..trials {
        let (meas, truth) = measure(&k, &w, 100 + seed);
        let problem = one_link_problem(&w, &meas, Some(&truth), &SOURCE_NOISE).unwrap();
        let naive = fit(&problem, &Parameterization::complete(&layout), 1e-12).unwrap();
        assert_eq!(naive.rank, 36);
        // k22 (row 2: std 2.5e-7) and k66 (row 6: std 2.5e-6) for the Monte-Carlo check.
        samples.push((naive.values[7] - k[(1, 1)], naive.values[35] - k[(5, 5)], naive.std[7], naive.std[35]));
        let probs = physical_problems(&layout, &naive.values);
        if naive.values[0] < 0.0 {
            negative_k11 += 1;
            assert!(probs.iter().any(|(_, t)| t.contains("k11") && t.contains("negative")), "{probs:?}");
        }
        if probs.iter().any(|(_, t)| t.contains("asymmetric")) {
            naive_bad += 1;
        }
        let (vm, vt) = measure(&k, &val_w, 10_000 + seed);
        let validation = one_link_problem(&val_w, &vm, Some(&vt), &SOURCE_NOISE).unwrap();
        let red = reduce(&problem, Some(&validation), None, &ReductionSettings::default()).unwrap();
        assert!(red.physical_problems.is_empty(), "seed {seed}: {:?}", red.physical_problems);
        // k11 (true nu 0.18) is dropped at M6 unless its noisy estimate happens to exceed 2
        // standard deviations (P = 3.4 %); the other seven always stay.
        if red.param.index_of("link.k11").is_some() {
            k11_kept += 1;
        }
        assert_eq!(
            red.param.len() - usize::from(red.param.index_of("link.k11").is_some()),
            7,
            "{:?}",
            red.param.names()
        );
        let c = &red.complete_values;
        for r in 0..6 {
            assert!(c[7 * r] >= 0.0);
            for cc in 0..6 {
                assert_eq!(c[6 * r + cc], c[6 * cc + r], "symmetric by construction");
            }
        }
        // The reduced estimate's entries are within 4 standard deviations of the truth.
        for (i, n) in red.param.names().iter().enumerate() {
            let idx = red.param.params[i].basis[0].0;
            let truth = k[(idx / 6, idx % 6)];
            assert!((red.fit.values[i] - truth).abs() < 4.0 * red.fit.std[i], "{n}: {} vs {truth}", red.fit.values[i]);
        }
        // Dropping k11 costs less than a quarter of the measurement noise (its estimate is
        // noise: std 2.5e-7 m/N, 2.5 um under 10 N).
        let m6 = red.step("M6").unwrap();
        assert!(m6.dropped_effect_m.unwrap() < 0.25 * 25e-6, "{:?}", m6.dropped_effect_m);
        let m0 = red.step("M0").unwrap().validation_truth_rms_m.unwrap();
        assert!(m6.validation_truth_rms_m.unwrap() < m0, "reduced predicts better than naive");
    }
    eprintln!(
        "negative k11 in {negative_k11} of {trials}; asymmetric naive estimate in {naive_bad}; k11 kept {k11_kept}"
    );
    // P(k11 < 0) = Phi(-0.18) = 0.43.
    assert!((8..=28).contains(&negative_k11), "{negative_k11}");
    assert_eq!(naive_bad, trials);
    assert!(k11_kept <= 5, "k11 kept in {k11_kept} of {trials}");
    // The covariance's standard deviations agree with the spread over the simulated experiments
    // (40 samples: the sample std is within 30 % with probability > 0.99).
    let n = samples.len() as f64;
    let e22 = (samples.iter().map(|s| s.0 * s.0).sum::<f64>() / n).sqrt();
    let e66 = (samples.iter().map(|s| s.1 * s.1).sum::<f64>() / n).sqrt();
    let (p22, p66) = (samples[0].2, samples[0].3);
    eprintln!("k22 std: Monte Carlo {e22:.3e}, covariance {p22:.3e}; k66: {e66:.3e} vs {p66:.3e}");
    assert!((e22 / p22 - 1.0).abs() < 0.3 && (e66 / p66 - 1.0).abs() < 0.3);
}

#[test]
fn unexcited_and_unphysical_estimates_are_refused_with_the_trusted_parameters() {
    let k = orthoglide_link_compliance();
    let layout = one_link_layout();
    let settings = ReductionSettings::default();
    let m2 = sparsity(&layout, &symmetric(&layout)).0;
    // Only forces: the moment columns (k44, k55, k66 and the couplings) are never excited.
    let w: Vec<Vector6<f64>> =
        orthogonal_design(50, 10.0, 10.0).into_iter().filter(|w| w[3] == 0.0 && w[4] == 0.0 && w[5] == 0.0).collect();
    let (meas, _) = measure(&k, &w, 7);
    let problem = one_link_problem(&w, &meas, None, &SOURCE_NOISE).unwrap();
    let e = identify_checked(&problem, &m2, &DVector::zeros(36), &settings).unwrap_err();
    match &e {
        StiffnessIdError::Unexcited { unexcited, trusted, .. } => {
            assert!(unexcited.contains(&"link.k44".to_string()) && unexcited.contains(&"link.k66".to_string()), "{e}");
            assert!(trusted.contains(&"link.k11".to_string()) && trusted.contains(&"link.k22".to_string()), "{e}");
            // k26 (force y -> rotation z) is seen through the force columns.
            assert!(trusted.contains(&"link.k26".to_string()), "{e}");
        }
        other => panic!("{other}"),
    }
    let msg = e.to_string();
    assert!(msg.contains("do not excite") && msg.contains("trusted"), "{msg}");
    // Very noisy measurements: the free k11 comes out negative.
    let w = orthogonal_design(1, 10.0, 10.0);
    let mut seen = false;
    for seed in 0..20 {
        let (meas, _) = measure(&k, &w, 500 + seed);
        let problem = one_link_problem(&w, &meas, None, &SOURCE_NOISE).unwrap();
        match identify_checked(&problem, &m2, &DVector::zeros(36), &settings) {
            Err(StiffnessIdError::NotPhysical { problems, trusted }) => {
                assert!(
                    problems.iter().any(|p| p.contains("negative") || p.contains("positive definite")),
                    "{problems:?}"
                );
                assert!(trusted.is_empty(), "every parameter belongs to the failing link: {trusted:?}");
                seen = true;
            }
            Ok(f) => assert!(f.values[0] >= 0.0),
            Err(other) => panic!("{other}"),
        }
    }
    assert!(seen, "some seed gives a negative k11");
    // A measuring device a million times too coarse resolves nothing: said so, nothing trusted.
    let coarse = ferrocal_robot::stiffness::NoiseModel { sigma_position_m: 25.0, sigma_orientation_rad: 250.0 };
    let w = orthogonal_design(2, 10.0, 10.0);
    let (meas, _) = measure(&k, &w, 3);
    let problem = one_link_problem(&w, &meas, None, &coarse).unwrap();
    let e = reduce(&problem, None, None, &settings).unwrap_err().to_string();
    assert!(e.contains("no parameter is resolved") && e.contains("trusted: none"), "{e}");
    // The fixed vector of nothing is zero and the RMS helper is the RMS.
    assert_eq!(fixed_vector(36, &[]).norm(), 0.0);
    assert!((rms_max(&[3.0, 4.0]).0 - (12.5f64).sqrt()).abs() < 1e-12);
}
