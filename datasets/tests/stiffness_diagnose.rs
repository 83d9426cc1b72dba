//! The joint compliance `diagnose` finds and the one the virtual joint model identifies agree on
//! the same simulated tracker recordings (a UR5 under 0 and 5 kg).

use ferrocal_calib::diagnose::{diagnose, DiagnoseOptions};
use ferrocal_calib::measurement::PoseMeasurement;
use ferrocal_calib::stiffness::fit::fit;
use ferrocal_calib::stiffness::problem::{LinearProblem, Measured, Observation};
use ferrocal_datasets::stiffsim::study::rigid_link_param;
use ferrocal_datasets::stiffsim::{StiffSim, StiffSimConfig};
use ferrocal_robot::stiffness::{Loading, VjmModel, Wrench, WrenchLimits};
use ferrocal_robot::{Kinematics, RobotModel};
use nalgebra::{Point3, Vector3};

/// Loaded-minus-unloaded tool displacements of rows recorded in pairs (payload 0, then `m`).
fn differences(model: &VjmModel, rows: &[PoseMeasurement], sigma_m: f64) -> Vec<Observation> {
    rows.chunks(2)
        .map(|pair| {
            let (a, b) = (&pair[0], &pair[1]);
            assert_eq!(a.q, b.q);
            let m = b.payload_kg.unwrap() - a.payload_kg.unwrap();
            let tool = model.chain.forward(&b.q).unwrap();
            let p = Point3::from(tool.translation.vector);
            let g = Vector3::from(model.chain.gravity_m_s2);
            let d = b.position_m - a.position_m;
            Observation {
                id: b.pose_id.clone(),
                q: b.q.clone(),
                loading: Loading::tool(Wrench::gravity(m, &p, &p, &g)),
                measured: Measured::Markers {
                    markers_in_tool_m: vec![[0.0; 3]],
                    dp_m: vec![[d.x, d.y, d.z]],
                    sigma_m: sigma_m * std::f64::consts::SQRT_2,
                },
                truth: None,
            }
        })
        .collect()
}

#[test]
fn diagnose_and_the_vjm_agree_on_the_joint_compliance() {
    let chain = match RobotModel::load("ur5").unwrap() {
        RobotModel::Serial(c) => c,
        _ => unreachable!(),
    };
    let truth_k = [0.0, 5e-6, 0.0, 0.0, 0.0, 0.0];
    let model = VjmModel::rigid_links(chain.clone(), truth_k.to_vec()).unwrap();
    let cfg = StiffSimConfig { seed: 5, truth_spread: 0.0, sigma_m: 20e-6, ..StiffSimConfig::default() };
    let mut sim = StiffSim::new(model, cfg).unwrap();
    let qs = sim.random_configurations(120);
    let rows = sim.tracker_rows(&qs, &[0.0, 5.0]).unwrap();
    // diagnose on the absolute rows (geometry fitted with the effect).
    let rep = diagnose(&RobotModel::Serial(chain.clone()), &rows, &DiagnoseOptions::default()).unwrap();
    let f = rep.findings.iter().find(|f| f.effect == "joint_compliance" && f.joints == [2]).unwrap_or_else(|| {
        panic!("diagnose found {:#?}", rep.findings.iter().map(|f| f.statement.clone()).collect::<Vec<_>>())
    });
    let c_diag = f.parameters["compliance_rad_per_nm"];
    // The VJM on the loaded-minus-unloaded differences of the same rows.
    let vjm = VjmModel::rigid_links(chain, vec![0.0; 6]).unwrap();
    let obs = differences(&vjm, &rows, 20e-6);
    let problem = LinearProblem::from_observations(&vjm, &obs, &WrenchLimits::default()).unwrap();
    let param = rigid_link_param(&problem.layout);
    let fit = fit(&problem, &param, 1e-6).unwrap();
    let j2 = param.index_of("joint2.k").unwrap();
    let (c_vjm, s_vjm) = (fit.values[j2], fit.std[j2]);
    eprintln!(
        "joint 2 compliance: diagnose {c_diag:.4e}, VJM {c_vjm:.4e} +- {s_vjm:.1e} rad/(N m), truth 5e-6; {:.2} s",
        rep.elapsed_s
    );
    assert!((c_vjm - 5e-6).abs() < 0.05 * 5e-6 && (c_vjm - 5e-6).abs() < 4.0 * s_vjm, "VJM {c_vjm:e} +- {s_vjm:e}");
    assert!((c_diag - 5e-6).abs() < 0.1 * 5e-6, "diagnose {c_diag:e}");
    assert!((c_diag - c_vjm).abs() < 0.1 * c_vjm, "diagnose {c_diag:e} vs VJM {c_vjm:e}");
    // The other joints: no compliance in either (joint 1 is vertical: unexcited by gravity).
    assert!(fit.std[param.index_of("joint1.k").unwrap()].is_infinite());
    for j in 3..=6 {
        let i = param.index_of(&format!("joint{j}.k")).unwrap();
        assert!(fit.values[i].abs() < 4.0 * fit.std[i] + 1e-9, "joint {j}: {:e} +- {:e}", fit.values[i], fit.std[i]);
    }
    assert!(rep.findings.iter().all(|f| f.effect != "joint_compliance" || f.joints == [2]), "{:#?}", rep.findings);
}
