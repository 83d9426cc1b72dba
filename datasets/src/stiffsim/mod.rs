//! The elastostatic measurement cell: a compliant arm (joint and link compliance, a gravity
//! compensator spring) measured by a laser tracker under payloads, reproducible by seed.
//!
//! The truth is a virtual joint model whose compliances differ from the design estimates by
//! random factors ([`perturb_compliance`]): each joint compliance by `exp(s N(0, 1))`, each
//! link's compliance matrix by the congruence `D K D` with `D = diag(exp(s N(0, 1) / 2))`
//! (symmetric, positive definite and in the link's beam template like the estimate), the
//! compensator's spring stiffness by `exp(s N(0, 1) / 3)`. At a configuration `q` under a
//! [`LoadCase`] the truth's linear deflections are applied through the exact compliant
//! kinematics; the tracker sees reflectors fixed to the tool ("partial pose": positions only),
//! with independent Gaussian noise per coordinate. The measured quantity is each reflector's
//! displacement from where the rigid (geometrically calibrated) model puts it.
//!
//! Everything random comes from one `ChaCha8Rng` seeded by [`StiffSimConfig::seed`]. The
//! identification of a measured deflection table is [`identify`].

pub mod checks;
pub mod identify;
pub mod study;
pub mod tables;

use ferrocal_calib::measurement::PoseMeasurement;
use ferrocal_calib::stiffness::compensate::compliant_pose;
use ferrocal_calib::stiffness::error::{Result, StiffnessIdError};
use ferrocal_calib::stiffness::problem::{Measured, Observation};
use ferrocal_calib::stiffness::LoadCase;
use ferrocal_robot::stiffness::presets::kr270_like;
use ferrocal_robot::stiffness::VjmModel;
use ferrocal_robot::Kinematics;
use nalgebra::{Point3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

/// Settings of the cell.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StiffSimConfig {
    /// Seed of every random draw.
    pub seed: u64,
    /// Relative spread `s` of the truth around the design estimates.
    pub truth_spread: f64,
    /// Tracker noise per coordinate.
    pub sigma_m: f64,
    /// Reflectors in the tool frame.
    pub markers_in_tool_m: Vec<[f64; 3]>,
    /// Fraction of each joint's range used for random configurations (centred).
    pub range_fraction: f64,
}

impl Default for StiffSimConfig {
    /// Seed 1, 30 % spread, 30 um tracker noise, three reflectors 0.2 m apart on the tool.
    fn default() -> Self {
        Self {
            seed: 1,
            truth_spread: 0.3,
            sigma_m: 30e-6,
            markers_in_tool_m: vec![[0.2, 0.0, 0.0], [-0.1, 0.17, 0.0], [-0.1, -0.17, 0.05]],
            range_fraction: 0.8,
        }
    }
}

/// The compliances of `model` scaled by random factors (see the module documentation).
pub fn perturb_compliance(model: &VjmModel, spread: f64, rng: &mut ChaCha8Rng) -> Result<VjmModel> {
    let mut n = || -> f64 { StandardNormal.sample(rng) };
    let mut truth = model.clone();
    for k in &mut truth.joint_compliance {
        *k *= (spread * n()).exp();
    }
    for s in &mut truth.springs {
        let d: Vec<f64> = (0..6).map(|_| (0.5 * spread * n()).exp()).collect();
        s.compliance = nalgebra::Matrix6::from_fn(|r, c| s.compliance[(r, c)] * d[r] * d[c]);
    }
    if let Some(c) = &mut truth.compensator {
        c.stiffness_n_per_m *= (spread / 3.0 * n()).exp();
    }
    truth.validate()?;
    Ok(truth)
}

/// The simulated cell.
#[derive(Clone, Debug)]
pub struct StiffSim {
    /// The design-estimate model (what the identification starts from).
    pub nominal: VjmModel,
    /// The truth.
    pub truth: VjmModel,
    /// The settings.
    pub config: StiffSimConfig,
    rng: ChaCha8Rng,
}

impl StiffSim {
    /// A cell around `nominal`.
    pub fn new(nominal: VjmModel, config: StiffSimConfig) -> Result<Self> {
        if !(config.sigma_m.is_finite() && config.sigma_m >= 0.0) {
            return Err(StiffnessIdError::Options(format!("tracker noise {} m must be non-negative", config.sigma_m)));
        }
        if config.markers_in_tool_m.is_empty() {
            return Err(StiffnessIdError::Options("the tracker needs at least one reflector".into()));
        }
        let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
        let truth = perturb_compliance(&nominal, config.truth_spread, &mut rng)?;
        Ok(Self { nominal, truth, config, rng })
    }

    /// The KR 270-like arm of `ferrocal_robot::stiffness::presets`.
    pub fn kr270(config: StiffSimConfig) -> Result<Self> {
        Self::new(kr270_like()?, config)
    }

    /// Reflector positions in the tool frame.
    pub fn markers(&self) -> Vec<Vector3<f64>> {
        self.config.markers_in_tool_m.iter().map(|m| Vector3::from(*m)).collect()
    }

    /// `n` random configurations inside the central `range_fraction` of every joint's range.
    pub fn random_configurations(&mut self, n: usize) -> Vec<Vec<f64>> {
        let lim = self.nominal.chain.joint_limits();
        let f = self.config.range_fraction.clamp(0.0, 1.0);
        (0..n)
            .map(|_| {
                lim.iter()
                    .map(|l| {
                        let (lo, hi) = (l.lower.max(-std::f64::consts::PI), l.upper.min(std::f64::consts::PI));
                        let mid = 0.5 * (lo + hi);
                        let half = 0.5 * (hi - lo) * f;
                        mid + half * (2.0 * self.rng.random::<f64>() - 1.0)
                    })
                    .collect()
            })
            .collect()
    }

    /// One tracker measurement of every reflector at `q` under `load`, as an observation for
    /// the identification (with its noise-free values).
    pub fn observe(&mut self, id: &str, q: &[f64], load: &LoadCase) -> Result<Observation> {
        let t_true = compliant_pose(&self.truth, q, load)?;
        let t_rigid = self.nominal.chain.forward(q)?;
        let unloaded = if load.self_weight {
            t_rigid
        } else {
            // A difference of loaded and unloaded measurements: both deflect under the links'
            // weight; the difference is what the payload adds.
            let none = LoadCase { mass_kg: 0.0, force_n: [0.0; 3], ..*load };
            let with_weight = LoadCase { self_weight: true, ..*load };
            let base = compliant_pose(&self.truth, q, &LoadCase { self_weight: true, ..none })?;
            let loaded = compliant_pose(&self.truth, q, &with_weight)?;
            return self.observe_difference(id, q, load, &base, &loaded);
        };
        self.observe_difference(id, q, load, &unloaded, &t_true)
    }

    fn observe_difference(
        &mut self,
        id: &str,
        q: &[f64],
        load: &LoadCase,
        reference: &ferrocal_robot::Pose,
        loaded: &ferrocal_robot::Pose,
    ) -> Result<Observation> {
        let markers = self.markers();
        let sigma = self.config.sigma_m;
        // The difference of two readings has sqrt(2) times the noise of one.
        let sigma_eff = if load.self_weight { sigma } else { sigma * std::f64::consts::SQRT_2 };
        let mut truth = Vec::new();
        let mut dp = Vec::new();
        for m in &markers {
            let d = loaded * Point3::from(*m) - reference * Point3::from(*m);
            truth.extend(d.iter().copied());
            let noisy: [f64; 3] = std::array::from_fn(|k| {
                let e: f64 = StandardNormal.sample(&mut self.rng);
                d[k] + sigma_eff * e
            });
            dp.push(noisy);
        }
        Ok(Observation {
            id: id.to_string(),
            q: q.to_vec(),
            loading: load.loading(&self.nominal, q)?,
            measured: Measured::Markers {
                markers_in_tool_m: self.config.markers_in_tool_m.clone(),
                dp_m: dp,
                sigma_m: sigma_eff.max(1e-12),
            },
            truth: Some(truth),
        })
    }

    /// Absolute tracker rows of the tool point for `diagnose`: one row per configuration and
    /// payload mass (the payload at the tool point), with the tracker's `sigma`.
    pub fn tracker_rows(&mut self, qs: &[Vec<f64>], payloads_kg: &[f64]) -> Result<Vec<PoseMeasurement>> {
        let sigma = self.config.sigma_m;
        let mut rows = Vec::new();
        for (k, q) in qs.iter().enumerate() {
            for (l, m) in payloads_kg.iter().enumerate() {
                let load = LoadCase::payload(*m, [0.0; 3]);
                let t = compliant_pose(&self.truth, q, &load)?;
                let p = t.translation.vector;
                let noisy = Vector3::from_fn(|r, _| {
                    let e: f64 = StandardNormal.sample(&mut self.rng);
                    p[r] + sigma * e
                });
                let mut row = PoseMeasurement::new(format!("p{k:04}_{l}"), q.clone(), noisy);
                row.sigma_m = Some(sigma.max(1e-9));
                row.payload_kg = Some(*m);
                rows.push(row);
            }
        }
        Ok(rows)
    }
}
