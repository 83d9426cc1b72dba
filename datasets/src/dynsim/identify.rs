//! The `dynamics identify` workflows on recorded tables: a dynamic model (force-sensor models 6
//! to 9, or the hexapod's rigid-body and friction parameters) from synchronised leg-position and
//! force streams ([`identify_streams`]), and a quasi-static force-sensor model from averaged
//! forces at poses ([`identify_static`]), on the rig's geometry ([`PlatformSim::preset`]); and
//! the missing-physics diagnosis of the sensor from such a table ([`diagnose_static_table`]).

use std::path::{Path, PathBuf};

use ferrocal_calib::diagnose::force::{diagnose_force_sensor, ForceDiagnoseOptions, ForceDiagnoseReport};
use ferrocal_calib::dynamics::force_sensor::{SensorModel, SensorRegressor};
use ferrocal_calib::dynamics::identify::{identify_from_streams, DynamicFit, RowModel};
use ferrocal_calib::dynamics::{Differentiation, NoiseModel, SensorRows};
use ferrocal_lsq::linear::{fit, LinearFit, LinearOptions, Weighting};
use ferrocal_robot::dynamics::HexapodDynamics;

use super::study::static_problem;
use super::PlatformSim;
use crate::error::{DatasetError, Result};
use crate::formats::dynamics_tables::{self, FORCE_COLUMNS, LEG_COLUMNS};

/// What `ferrocal dynamics identify` reads and how it processes the streams.
#[derive(Clone, Debug)]
pub struct StreamIdentifyOptions {
    /// `hexapod`, or a dynamic force-sensor model (6 to 9).
    pub model: String,
    /// The leg-position stream (CSV).
    pub legs: PathBuf,
    /// The force stream (CSV): actuator forces for the hexapod, else sensor forces.
    pub forces: PathBuf,
    /// Differentiate in the time domain (a 4th-order filter) instead of by frequency.
    pub time_domain: bool,
    /// The filters' cutoff, Hz.
    pub cutoff_hz: f64,
    /// Samples per excitation period: the noise estimated from the periods (else unit weights).
    pub period_samples: Option<usize>,
}

/// The sensor framework of the rig ([`PlatformSim::preset`]).
pub fn rig_sensor_regressor() -> Result<SensorRegressor> {
    Ok(PlatformSim::preset().sensor_regressor()?)
}

/// A dynamic model from the streams of `o`, with the differentiation used.
pub fn identify_streams(o: &StreamIdentifyOptions) -> Result<(DynamicFit, Differentiation)> {
    let hexapod = PlatformSim::preset().hexapod;
    let is_hexapod = o.model.trim().eq_ignore_ascii_case("hexapod");
    let d = if o.time_domain {
        Differentiation::TimeDomain { cutoff_hz: o.cutoff_hz, order: 4 }
    } else {
        Differentiation::Frequency { cutoff_hz: o.cutoff_hz }
    };
    let noise =
        o.period_samples.map_or(NoiseModel::Unit, |samples_per_period| NoiseModel::Periods { samples_per_period });
    let reg;
    let dynm;
    let model: &dyn RowModel = if is_hexapod {
        dynm = HexapodDynamics::new(&hexapod)?;
        &dynm
    } else {
        let m: SensorModel = o.model.parse()?;
        if !m.is_dynamic() {
            return Err(DatasetError::Input(format!("{m} is quasi-static: use `ferrocal dynamics identify-static` with averaged forces at poses, or a dynamic model 6 to 9")));
        }
        reg = rig_sensor_regressor()?;
        &SensorRows { regressor: &reg, model: m }
    };
    let legs = dynamics_tables::read_stream(&o.legs, "leg positions", &LEG_COLUMNS)?;
    let forces = dynamics_tables::read_stream(
        &o.forces,
        if is_hexapod { "actuator forces" } else { "sensor forces" },
        &FORCE_COLUMNS,
    )?;
    let f = identify_from_streams(&hexapod, model, &legs, &forces, &d, &noise).map_err(|e| {
        DatasetError::from(e).context(format!("identifying from {} and {}", o.legs.display(), o.forces.display()))
    })?;
    Ok((f, d))
}

/// A quasi-static force-sensor model (`model`, 0 to 5) from the averaged forces at poses of the
/// table `poses_path` (`ferrocal dynamics simulate`'s static.csv); with the number of poses.
pub fn identify_static(model: u8, poses_path: &Path) -> Result<(SensorModel, usize, LinearFit)> {
    let m = SensorModel::new(model)?;
    if m.is_dynamic() {
        return Err(DatasetError::Input(format!(
            "{m} is dynamic: use `ferrocal dynamics identify` with leg and force streams"
        )));
    }
    let (poses, forces) = dynamics_tables::read_static_table(poses_path)?;
    let reg = rig_sensor_regressor()?;
    let (am, y) = static_problem(&reg, m, &poses, &forces)
        .map_err(|e| DatasetError::Input(format!("{}: {e}", poses_path.display())))?;
    let f = fit(&am, &y, &m.names(), &Weighting::Unit, &LinearOptions::default()).map_err(|e| {
        DatasetError::from(e).context(format!("{m} from {} poses of {}", poses.len(), poses_path.display()))
    })?;
    Ok((m, poses.len(), f))
}

/// The missing-physics diagnosis of a force-sensing end-effector from a quasi-static table
/// (`ferrocal dynamics simulate`'s static.csv) on the rig's sensor framework
/// ([`rig_sensor_regressor`]): the rigid body and offsets identified, the deformation terms
/// tested on held-out poses. With the number of poses.
pub fn diagnose_static_table(path: &Path, opts: &ForceDiagnoseOptions) -> Result<(usize, ForceDiagnoseReport)> {
    let (poses, forces) = dynamics_tables::read_static_table(path)?;
    let reg = rig_sensor_regressor()?;
    let rep = diagnose_force_sensor(&reg, &poses, &forces, opts)
        .map_err(|e| DatasetError::from(e).context(format!("force-sensor diagnosis of {}", path.display())))?;
    Ok((poses.len(), rep))
}
