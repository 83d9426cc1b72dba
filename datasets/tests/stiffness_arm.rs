//! The source's 6-DOF study on the simulated KR 270-like arm (Klimchik et al. 2015): the
//! reduction from the complete model to a practically identifiable set, each step reported; the
//! designed experiment; compensation of a 2.5 kN class load with the reduced model against a
//! rigid-link / compliant-joint model; bad input refused with the parameters to trust.

use ferrocal_calib::identifiability::ParamClass;
use ferrocal_calib::stiffness::problem::{LinearProblem, Measured, Observation};
use ferrocal_calib::stiffness::reduce::{aggregate, fixed_vector, sparsity, symmetric};
use ferrocal_calib::stiffness::{identify_checked, LoadCase, ReductionSettings, StiffnessIdError};
use ferrocal_datasets::stiffsim::study::{arm_study, ArmStudySettings};
use ferrocal_datasets::stiffsim::{StiffSim, StiffSimConfig};
use ferrocal_robot::stiffness::presets::kr270_like;
use ferrocal_robot::stiffness::{Loading, Wrench, WrenchLimits};
use nalgebra::Vector3;

#[test]
fn the_first_three_reductions_give_the_sources_counts() {
    let mut m = kr270_like().unwrap();
    m.compensator = None;
    let layout = m.layout().unwrap();
    let m1 = symmetric(&layout);
    let (m2, _) = sparsity(&layout, &m1);
    let (m3, merged) = aggregate(&layout, &m2);
    assert_eq!([layout.len(), m1.len(), m2.len(), m3.len()], [258, 153, 62, 56], "the source: 258, 153, 62, 56");
    assert_eq!(merged.len(), 6, "{merged:?}");
}

#[test]
fn reduction_design_and_compensation_on_the_kr270_like_arm() {
    let mut ratios = Vec::new();
    for seed in 1..=6 {
        let t = std::time::Instant::now();
        let s = arm_study(&ArmStudySettings::quick(seed)).unwrap();
        let counts: Vec<usize> = s.reduction.steps.iter().map(|x| x.n_params).collect();
        let codes: Vec<&str> = s.reduction.steps.iter().map(|x| x.code.as_str()).collect();
        assert_eq!(codes, ["M0", "M1", "M2", "M3", "M4", "M5", "M6"]);
        // With the compensator's two terms: 258 + 2, 153 + 2, 62 + 2, 56 + 2.
        assert_eq!(counts[..4], [260, 155, 64, 58]);
        assert!(counts.windows(2).all(|w| w[1] <= w[0]), "{counts:?}");
        let last = *counts.last().unwrap();
        assert!((8..=40).contains(&last), "a few dozen at most: {counts:?}");
        // Every step is scored on the validation measurements.
        assert!(s.reduction.steps.iter().all(|x| x.validation_truth_rms_m.is_some() && x.rank > 0));
        let m5 = s.reduction.step("M5").unwrap();
        assert_eq!(m5.rank, m5.n_params, "after M5 every parameter is identifiable");
        let m6 = s.reduction.step("M6").unwrap();
        assert!(m6.validation_truth_rms_m.unwrap() < 0.2e-3, "{m6:?}");
        // The designed experiment beats random ones of the same size (D: ln det, larger).
        assert!(s.design.value > s.design.random_value, "{} vs {}", s.design.value, s.design.random_value);
        // Compensation of a 2.45 kN payload.
        assert!(s.task_force_n > 2400.0 && s.task_force_n < 2600.0);
        let none = s.errors("none").unwrap().rms_m;
        let red = s.errors("reduced model").unwrap().rms_m;
        let rl = s.errors("rigid links, compliant joints").unwrap().rms_m;
        assert!(none > 3e-3, "the load deflects the arm by millimetres: {none}");
        assert!(red < 0.1 * none, "more than 90 % removed: {red} of {none}");
        assert!(rl > red, "seed {seed}: rigid links {rl} vs reduced {red}");
        ratios.push(rl / red);
        eprintln!(
            "seed {seed}: {counts:?}; RMS none {:.3} mm, rigid-link {:.3} mm, reduced {:.3} mm; problems {:?}; {:.2} s",
            none * 1e3,
            rl * 1e3,
            red * 1e3,
            s.reduction.physical_problems,
            t.elapsed().as_secs_f64()
        );
    }
    ratios.sort_by(f64::total_cmp);
    let median = 0.5 * (ratios[2] + ratios[3]);
    assert!(median >= 3.0, "the rigid-link model leaves several times more: {ratios:?}");
}

#[test]
fn gravity_alone_leaves_parameters_unexcited_and_wrong_units_are_named() {
    let mut sim = StiffSim::kr270(StiffSimConfig { seed: 9, ..StiffSimConfig::default() }).unwrap();
    let qs = sim.random_configurations(30);
    let obs: Vec<Observation> = qs
        .iter()
        .enumerate()
        .map(|(k, q)| sim.observe(&format!("o{k}"), q, &LoadCase::payload(200.0, [0.1, 0.0, 0.1])).unwrap())
        .collect();
    let problem = LinearProblem::from_observations(&sim.nominal, &obs, &WrenchLimits::default()).unwrap();
    let layout = &problem.layout;
    let (m3, _) = aggregate(layout, &sparsity(layout, &symmetric(layout)).0);
    let e =
        identify_checked(&problem, &m3, &fixed_vector(layout.len(), &[]), &ReductionSettings::default()).unwrap_err();
    match &e {
        StiffnessIdError::Unexcited { unexcited, trusted, .. } => {
            // Gravity never pushes the pedestal sideways nor twists it about the vertical.
            assert!(unexcited.iter().any(|n| n.starts_with("link0.k")), "{e}");
            assert!(!trusted.is_empty(), "{e}");
        }
        other => panic!("{other}"),
    }
    assert!(e.to_string().contains("trusted"), "{e}");
    // Applied horizontal forces (a cable pull) excite what gravity cannot.
    let nominal = sim.nominal.clone();
    let g2 = |obs: &[Observation]| -> Vec<String> {
        let p = LinearProblem::from_observations(&nominal, obs, &WrenchLimits::default()).unwrap();
        let r = ferrocal_calib::stiffness::reduce(&p, None, None, &ReductionSettings::default()).unwrap();
        r.classes.iter().filter(|(_, c)| *c == ParamClass::NotIdentifiable).map(|(n, _)| n.clone()).collect()
    };
    let gravity_only = g2(&obs);
    assert!(gravity_only.iter().any(|n| n == "link0.k11"), "{gravity_only:?}");
    let mut pulled = obs.clone();
    for (k, q) in qs.iter().enumerate().take(10) {
        let f = if k % 2 == 0 { [800.0, 0.0, 0.0] } else { [0.0, 800.0, 0.0] };
        let load = LoadCase { force_n: f, ..LoadCase::payload(0.0, [0.0; 3]) };
        pulled.push(sim.observe(&format!("f{k}"), q, &load).unwrap());
    }
    let with_forces = g2(&pulled);
    assert!(with_forces.is_empty(), "{with_forces:?}");
    // A payload wrench typed in N mm for the moment: refused, naming the observation.
    let mut bad = obs[3].clone();
    bad.loading = Loading::gravity(Wrench::new(Vector3::new(0.0, 0.0, -1962.0), Vector3::new(196_200.0, 0.0, 0.0)));
    let e =
        LinearProblem::from_observations(&sim.nominal, &[obs[0].clone(), bad], &WrenchLimits::default()).unwrap_err();
    assert!(e.to_string().contains("o3") && e.to_string().contains("N mm"), "{e}");
    // Marker displacements in millimetres: the whitened residual shows it (s0 far above 1).
    let mut mm = obs.clone();
    for o in &mut mm {
        if let Measured::Markers { dp_m, .. } = &mut o.measured {
            for d in dp_m.iter_mut() {
                for v in d.iter_mut() {
                    *v *= 1e3;
                }
            }
        }
    }
    let p = LinearProblem::from_observations(&sim.nominal, &mm, &WrenchLimits::default()).unwrap();
    let red = ferrocal_calib::stiffness::reduce(
        &p,
        None,
        Some(&sim.nominal.complete_values()),
        &ReductionSettings::default(),
    )
    .unwrap();
    assert!(red.fit.s0 > 100.0 || !red.physical_problems.is_empty(), "s0 {}", red.fit.s0);
}
