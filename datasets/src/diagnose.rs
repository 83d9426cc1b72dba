//! The `diagnose` workflow on a measurement table: the options from the command's settings
//! ([`diagnose_options`]) and the diagnosis with, when asked, the calibration refitted with the
//! accepted effects ([`diagnose_rows`]). The camera and force-sensor variants read their inputs
//! with [`crate::camera::target_point_views`] and [`crate::dynsim::identify::diagnose_static_table`].

use ferrocal_calib::diagnose::{compensated_calibration, diagnose, DiagnoseOptions, DiagnoseReport};
use ferrocal_calib::kinematic::KinematicCalibration;
use ferrocal_calib::PoseMeasurement;
use ferrocal_robot::RobotModel;

use crate::error::{DatasetError, Result};

/// The options of a table's diagnosis: `folds` of the cross-validation, the family-wise `alpha`,
/// the `validation_fraction` kept aside without a split column, and the position standard
/// deviation of rows without a sigma column (`sigma_mm`; without it the noise is taken from the
/// geometric fit's residuals).
pub fn diagnose_options(
    folds: usize,
    alpha: f64,
    validation_fraction: f64,
    sigma_mm: Option<f64>,
) -> Result<DiagnoseOptions> {
    if sigma_mm.is_some_and(|s| !(s.is_finite() && s > 0.0)) {
        return Err(DatasetError::Input("--sigma-mm must be positive".into()));
    }
    Ok(DiagnoseOptions {
        folds,
        alpha,
        validation_fraction,
        sigma_position_m: sigma_mm.map_or(DiagnoseOptions::default().sigma_position_m, |s| s * 1e-3),
        sigma_from_data: sigma_mm.is_none(),
        ..DiagnoseOptions::default()
    })
}

/// The diagnosis of `model` on `rows`, and with `compensate` the calibration refitted on all
/// training rows with the accepted effects included.
pub fn diagnose_rows(
    model: &RobotModel,
    rows: &[PoseMeasurement],
    opts: &DiagnoseOptions,
    compensate: bool,
) -> Result<(DiagnoseReport, Option<KinematicCalibration>)> {
    let rep = diagnose(model, rows, opts).map_err(|e| DatasetError::from(e).context("diagnosis"))?;
    let compensated = match compensate {
        true => Some(
            compensated_calibration(model, rows, &rep)
                .map_err(|e| DatasetError::from(e).context("refitting the calibration with the accepted effects"))?,
        ),
        false => None,
    };
    Ok((rep, compensated))
}
