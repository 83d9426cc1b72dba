//! The named limits of the verdicts, their documented defaults, and the TOML file that
//! overrides them (`ferrocal --thresholds FILE.toml`; `docs/verdicts.md`).
//!
//! The file holds one table per section, with only the keys to change:
//!
//! ```toml
//! [camera]
//! rms_px_warn = 0.3
//!
//! [evaluate]
//! rms_mm_fail = 1.0
//! ```
//!
//! A key the program does not know (a misspelt name) is refused with the file and the key
//! named, so that a limit never silently stays at its default.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

/// Why a thresholds file was refused.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ThresholdsError {
    /// The file could not be read.
    #[error("{}: cannot read the thresholds file: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The reason.
        source: std::io::Error,
    },
    /// The file is not TOML, or a value has the wrong type.
    #[error("{}: {message}", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// What the TOML reader said.
        message: String,
    },
    /// The file names a key (or a section) that does not exist.
    #[error("{}: unknown key '{key}' in the thresholds file (known: {known}; docs/verdicts.md lists them)", path.display())]
    UnknownKey {
        /// The file.
        path: PathBuf,
        /// The unknown key, dotted from the file's root (`camera.rms_px_warm`).
        key: String,
        /// The keys known at that level, comma-separated.
        known: String,
    },
    /// A limit is not a finite number or infinity as TOML writes it (`inf`).
    #[error("{}: '{key}' must be a number, got {value}", path.display())]
    NotANumber {
        /// The file.
        path: PathBuf,
        /// The key.
        key: String,
        /// The value as written.
        value: String,
    },
}

/// Every limit of every verdict. `Default` gives the documented defaults; [`Thresholds::load`]
/// reads a file that overrides some of them.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Thresholds {
    /// `camera calibrate` (and every camera calibrated on the way).
    pub camera: CameraLimits,
    /// `camera stereo`.
    pub stereo: StereoLimits,
    /// `handeye`.
    pub handeye: HandeyeLimits,
    /// `calibrate`.
    pub calibrate: CalibrateLimits,
    /// `evaluate`.
    pub evaluate: EvaluateLimits,
    /// `diagnose` (robot, camera and force-sensor variants).
    pub diagnose: DiagnoseLimits,
    /// `detect`.
    pub detect: DetectLimits,
    /// `measure` (session and recording forms).
    pub measure: MeasureLimits,
    /// `import`.
    pub import: ImportLimits,
    /// `export` and `correct`.
    pub export: ExportLimits,
    /// `plan`.
    pub plan: PlanLimits,
    /// The studies (`demo`, `dynamics`, `stiffness`, `motion`, `corner-study`, `handeye study`).
    pub study: StudyLimits,
    /// `robot fk`, `robot ik`.
    pub robot: RobotLimits,
    /// `dynamics identify`, `dynamics identify-static`.
    pub dynamics: DynamicsLimits,
    /// `stiffness identify`.
    pub stiffness: StiffnessLimits,
}

/// Limits of a single camera's calibration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CameraLimits {
    /// Reprojection RMS of the fit, px: warning above (default 0.5 px, the usual mark of a good
    /// calibration with sub-pixel corners; OpenCV's sample reaches 0.4 px).
    pub rms_px_warn: f64,
    /// Reprojection RMS of the fit, px: failure above (default 2.0 px; industrial_calibration's
    /// own tests accept up to 1.5 px).
    pub rms_px_fail: f64,
    /// Held-out reprojection RMS over the fit's RMS (`--test-every`): warning above (default 1.5).
    pub heldout_ratio_warn: f64,
    /// Held-out over fit RMS: failure above (default 3.0: the model does not predict new views).
    pub heldout_ratio_fail: f64,
    /// Views used: warning below (default 10; Zhang's method needs 3, OpenCV's documentation
    /// recommends 10 or more).
    pub views_warn: f64,
    /// Views used: failure below (default 3, the minimum of Zhang's method).
    pub views_fail: f64,
}

impl Default for CameraLimits {
    fn default() -> Self {
        Self {
            rms_px_warn: 0.5,
            rms_px_fail: 2.0,
            heldout_ratio_warn: 1.5,
            heldout_ratio_fail: 3.0,
            views_warn: 10.0,
            views_fail: 3.0,
        }
    }
}

/// Limits of a stereo pair.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StereoLimits {
    /// Reprojection RMS of the pair's joint fit, px: warning above (default 0.5).
    pub rms_px_warn: f64,
    /// Reprojection RMS of the pair: failure above (default 2.0).
    pub rms_px_fail: f64,
    /// Row difference of corresponding corners after rectification, px RMS: warning above
    /// (default 0.5; stereo matching searches along rows).
    pub row_rms_px_warn: f64,
    /// Rectified row difference: failure above (default 2.0).
    pub row_rms_px_fail: f64,
    /// Where the right camera sits: its position along the left camera's -x axis (image left)
    /// over the baseline; warning above (default 0.5). A side-by-side pair named as its cameras
    /// sit gives -1 (OpenCV's sample: the right camera 83 mm along +x), a vertical rig about 0,
    /// swapped `--left` and `--right` lists +1.
    pub baseline_leftward_warn: f64,
    /// The right camera's leftward share of the baseline: failure above (default 0.7: the left
    /// and right lists are swapped).
    pub baseline_leftward_fail: f64,
    /// Two pairs agree on the cameras' relative pose when their relative poses (each camera
    /// calibrated alone) differ by less than this: the rotation difference in radians plus the
    /// translation difference over the baseline (default 0.1, the rig calibration's own
    /// consensus limit).
    pub pair_distance: f64,
    /// The share of pairs whose relative pose disagrees with the consensus: warning above
    /// (default 0.2).
    pub pairs_disagree_fraction_warn: f64,
    /// The share of disagreeing pairs: refused above (default 0.5; the lists are shifted, or
    /// not taken at the same instants), naming the shift of the right list that pairs them
    /// when one does.
    pub pairs_disagree_fraction_fail: f64,
}

impl Default for StereoLimits {
    fn default() -> Self {
        Self {
            rms_px_warn: 0.5,
            rms_px_fail: 2.0,
            row_rms_px_warn: 0.5,
            row_rms_px_fail: 2.0,
            baseline_leftward_warn: 0.5,
            baseline_leftward_fail: 0.7,
            pair_distance: 0.1,
            pairs_disagree_fraction_warn: 0.2,
            pairs_disagree_fraction_fail: 0.5,
        }
    }
}

/// Limits of a hand-eye calibration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HandeyeLimits {
    /// Chain reprojection RMS (held-out images, else training), px: warning above (default 1.5,
    /// industrial_calibration's acceptance for both of its hand-eye sets).
    pub chain_rms_px_warn: f64,
    /// Chain reprojection RMS: failure above (default 20 px).
    pub chain_rms_px_fail: f64,
    /// The smallest per-image PnP RMS the chain is compared with, px (default 0.1: corners on
    /// real images are rarely located better, and rendered ones reach 0.01 px).
    pub pnp_floor_px: f64,
    /// Chain RMS over the per-image PnP RMS of the same images and camera: warning above
    /// (default 20: the robot's pose errors add to the corners' noise).
    pub chain_over_pnp_warn: f64,
    /// Chain over PnP RMS: failure above (default 100: the chain does not describe the images;
    /// a wrong `--mount` gives hundreds).
    pub chain_over_pnp_fail: f64,
    /// Mean distance of the chain's target origin from PnP's, mm: warning above (default 6,
    /// industrial_calibration's limit on its ChArUco set).
    pub pnp_position_mm_warn: f64,
    /// PnP position agreement: failure above (default 20, its limit on the 10 x 10 set with
    /// uncalibrated intrinsics).
    pub pnp_position_mm_fail: f64,
    /// Mean angle between the chain's target orientation and PnP's, degrees: warning above
    /// (default 1.5, the ChArUco set's limit).
    pub pnp_rotation_deg_warn: f64,
    /// PnP orientation agreement: failure above (default 3, the 10 x 10 set's limit).
    pub pnp_rotation_deg_fail: f64,
    /// A rig file's camera-to-camera transform (`--intrinsics` carrying OpenCV's `R`, `T`)
    /// against the fitted one, in the fit's standard deviations (the largest of the six
    /// coordinates): warning above (default 3). A warning only: the file's own uncertainty is not
    /// known, and a camera knocked since the file was made shows exactly so.
    pub rig_file_sigma_warn: f64,
    /// Length of the flange-side transform (`T_flange_camera` eye-in-hand, `T_flange_target`
    /// eye-to-hand), mm: warning above (default 500). A camera or target on a robot's flange sits
    /// within a few hundred millimetres of it (the real sets: 10x10 135 mm, charuco 120 mm); a
    /// pose table written inverted (`T_flange_base`) fits with the world transform in its
    /// place, metres long (the charuco set inverted: 1297 mm).
    pub tool_offset_mm_warn: f64,
    /// Flange-side transform length: failure above (default 1000 mm: no tool; the poses look
    /// inverted).
    pub tool_offset_mm_fail: f64,
}

impl Default for HandeyeLimits {
    fn default() -> Self {
        Self {
            chain_rms_px_warn: 1.5,
            chain_rms_px_fail: 20.0,
            pnp_floor_px: 0.1,
            chain_over_pnp_warn: 20.0,
            chain_over_pnp_fail: 100.0,
            pnp_position_mm_warn: 6.0,
            pnp_position_mm_fail: 20.0,
            pnp_rotation_deg_warn: 1.5,
            pnp_rotation_deg_fail: 3.0,
            rig_file_sigma_warn: 3.0,
            tool_offset_mm_warn: 500.0,
            tool_offset_mm_fail: 1000.0,
        }
    }
}

/// Limits of a kinematic calibration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CalibrateLimits {
    /// Held-out position RMS of the calibrated model, mm: warning above (default 2.0,
    /// industrial_calibration's acceptance for its camera-measured positioner).
    pub heldout_rms_mm_warn: f64,
    /// Held-out position RMS: failure above (default 10 mm).
    pub heldout_rms_mm_fail: f64,
    /// Held-out RMS of the calibrated model over the nominal model's (frames fitted on the same
    /// rows): warning above (default 0.9: industrial_calibration asks for more than 10 % better
    /// than nominal).
    pub heldout_vs_nominal_warn: f64,
    /// Calibrated over nominal held-out RMS: failure above (default 1.05: the calibration makes
    /// poses it did not see worse, beyond 5 % of scatter).
    pub heldout_vs_nominal_fail: f64,
    /// Held-out RMS over training RMS of the same fit: warning above (default 2.0: overfitting
    /// or a split that differs from the training poses).
    pub heldout_over_train_warn: f64,
    /// Held-out over training RMS: failure above (default 5.0).
    pub heldout_over_train_fail: f64,
    /// Joints the data cannot identify (advice given): warning above (default 0).
    pub unidentified_warn: f64,
    /// The largest change the calibration makes to a length of the robot model (a link length
    /// or offset correction, a prismatic joint's zero offset; not the device frame or the
    /// tool), mm: warning above (default 10 mm). A robot of the model is built within a few
    /// tenths of a millimetre of it (the real UR5, UR10 and positioner tables change no length
    /// by more than 1.3 mm); a UR5's table calibrated as a UR10 changes links by about 180 mm.
    pub model_change_mm_warn: f64,
    /// The largest length change: failure above (default 50 mm: the table is of another robot,
    /// `--robot` is wrong).
    pub model_change_mm_fail: f64,
    /// The largest change the calibration makes to an angle of the robot model (a joint's zero
    /// offset, a twist or axis correction), degrees: warning above (default 5 deg).
    pub model_change_deg_warn: f64,
    /// The largest angle change: failure above (default 20 deg).
    pub model_change_deg_fail: f64,
}

impl Default for CalibrateLimits {
    fn default() -> Self {
        Self {
            heldout_rms_mm_warn: 2.0,
            heldout_rms_mm_fail: 10.0,
            heldout_vs_nominal_warn: 0.9,
            heldout_vs_nominal_fail: 1.05,
            heldout_over_train_warn: 2.0,
            heldout_over_train_fail: 5.0,
            unidentified_warn: 0.0,
            model_change_mm_warn: 10.0,
            model_change_mm_fail: 50.0,
            model_change_deg_warn: 5.0,
            model_change_deg_fail: 20.0,
        }
    }
}

/// Limits of `evaluate`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EvaluateLimits {
    /// Position RMS of the scored rows, mm: warning above (default 1.0).
    pub rms_mm_warn: f64,
    /// Position RMS: failure above (default 2.0, industrial_calibration's acceptance for its
    /// positioner).
    pub rms_mm_fail: f64,
}

impl Default for EvaluateLimits {
    fn default() -> Self {
        Self { rms_mm_warn: 1.0, rms_mm_fail: 2.0 }
    }
}

/// Limits of `diagnose`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DiagnoseLimits {
    /// Final over nominal held-out RMS: warning above (default 1.0: the accepted effects do not
    /// predict held-out data better).
    pub heldout_ratio_warn: f64,
    /// Final over nominal held-out RMS: failure above (default 1.1).
    pub heldout_ratio_fail: f64,
    /// Significant candidates rejected (for physics or stability): warning above (default 0).
    pub rejected_warn: f64,
}

impl Default for DiagnoseLimits {
    fn default() -> Self {
        Self { heldout_ratio_warn: 1.0, heldout_ratio_fail: 1.1, rejected_warn: 0.0 }
    }
}

/// Limits of `detect`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DetectLimits {
    /// Fraction of the images in which the pattern was found: warning below (default 1.0).
    pub found_fraction_warn: f64,
    /// Fraction found: failure below (default 0.5).
    pub found_fraction_fail: f64,
}

impl Default for DetectLimits {
    fn default() -> Self {
        Self { found_fraction_warn: 1.0, found_fraction_fail: 0.5 }
    }
}

/// Limits of `measure`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MeasureLimits {
    /// Fraction of the poses measured: warning below (default 0.9).
    pub measured_fraction_warn: f64,
    /// Fraction measured: failure below (default 0.5).
    pub measured_fraction_fail: f64,
    /// Reprojection RMS of the camera (rig) calibration, px: warning above (default 0.5).
    pub rms_px_warn: f64,
    /// Camera calibration RMS: failure above (default 2.0).
    pub rms_px_fail: f64,
    /// A pose's cameras disagree when the target position from one camera alone, carried into
    /// camera 0's frame by the calibrated rig, differs from camera 0's own by more than this many
    /// standard deviations of the two (default 10) ...
    pub cameras_disagree_sigmas: f64,
    /// ... and by more than this fraction of the target's distance (default 1e-3: 1 mm at 1 m;
    /// a floor for rigs whose stated sigmas are tighter than their calibration).
    pub cameras_disagree_relative: f64,
    /// Fraction of the compared poses whose cameras disagree: warning above (default 0: every
    /// such pose is named).
    pub cameras_disagree_fraction_warn: f64,
    /// Fraction whose cameras disagree: refused above (default 0.5; the message names a swap or
    /// a shift of the image lists when one makes the poses agree), no table written.
    pub cameras_disagree_fraction_fail: f64,
    /// Camera baseline or median target distance, m: refused above (default 50 m; no camera
    /// measures a target in a robot cell from that far, a board or target square size in the
    /// wrong unit gives kilometres).
    pub distance_m_fail: f64,
}

impl Default for MeasureLimits {
    fn default() -> Self {
        Self {
            measured_fraction_warn: 0.9,
            measured_fraction_fail: 0.5,
            rms_px_warn: 0.5,
            rms_px_fail: 2.0,
            cameras_disagree_sigmas: 10.0,
            cameras_disagree_relative: 1e-3,
            cameras_disagree_fraction_warn: 0.0,
            cameras_disagree_fraction_fail: 0.5,
            distance_m_fail: 50.0,
        }
    }
}

/// Limits of `import`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ImportLimits {
    /// Rows written: warning below (default 10; a calibration needs many distinct poses).
    pub rows_warn: f64,
    /// Rows written: failure below (default 3, the fewest a frame registration needs).
    pub rows_fail: f64,
}

impl Default for ImportLimits {
    fn default() -> Self {
        Self { rows_warn: 10.0, rows_fail: 3.0 }
    }
}

/// Limits of `export` and `correct`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ExportLimits {
    /// Largest position difference of the written model read back from the calibrated one, mm:
    /// warning above (default 1e-6 mm).
    pub roundtrip_mm_warn: f64,
    /// Read-back position difference: failure above (default 1e-3 mm).
    pub roundtrip_mm_fail: f64,
    /// Largest orientation difference read back, degrees: warning above (default 1e-6).
    pub roundtrip_deg_warn: f64,
    /// Read-back orientation difference: failure above (default 1e-3).
    pub roundtrip_deg_fail: f64,
    /// `correct`: largest distance a corrected command leaves from its intended pose under the
    /// calibrated model, mm: warning above (default 1e-4 mm).
    pub residual_mm_warn: f64,
    /// `correct`: largest distance left: failure above (default 1e-3 mm; commands beyond it are
    /// refused anyway).
    pub residual_mm_fail: f64,
    /// `correct`: largest change a correction makes to a command's pose, mm: warning above
    /// (default 10 mm: a calibration that moves the robot this far is worth a second look).
    pub correction_mm_warn: f64,
    /// `correct`: largest correction: failure above (default 50 mm: the calibration most likely
    /// belongs to another robot or frame).
    pub correction_mm_fail: f64,
    /// `correct`: a row counts as outside the calibrated region when a revolute joint lies more
    /// than this beyond the range the calibration's poses covered, degrees (default 5); a
    /// warning names how many and by how much.
    pub outside_deg_warn: f64,
    /// `correct`: ... or a prismatic joint more than this beyond its covered range, or the wanted
    /// position more than this outside the box of the calibration's positions, mm (default 25).
    pub outside_mm_warn: f64,
    /// `correct`: a row counts as near a singularity when the smallest singular value of its
    /// task Jacobian (metres per radian of joint motion; orientation rows at 0.1 m per radian)
    /// is below this (default 0.005 m: a 1 mm error of the pose needs 0.2 rad of some joint
    /// combination); a warning names the rows.
    pub singular_m_warn: f64,
}

fn default_outside_deg() -> f64 {
    5.0
}

fn default_outside_mm() -> f64 {
    25.0
}

fn default_singular_m() -> f64 {
    0.005
}

impl Default for ExportLimits {
    fn default() -> Self {
        Self {
            roundtrip_mm_warn: 1e-6,
            roundtrip_mm_fail: 1e-3,
            roundtrip_deg_warn: 1e-6,
            roundtrip_deg_fail: 1e-3,
            residual_mm_warn: 1e-4,
            residual_mm_fail: 1e-3,
            correction_mm_warn: 10.0,
            correction_mm_fail: 50.0,
            outside_deg_warn: default_outside_deg(),
            outside_mm_warn: default_outside_mm(),
            singular_m_warn: default_singular_m(),
        }
    }
}

/// Limits of `plan`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PlanLimits {
    /// The plan's own checks that failed (selection, sigma ratio, predicted accuracy, path):
    /// failure above (default 0).
    pub failed_checks_fail: f64,
}

impl Default for PlanLimits {
    fn default() -> Self {
        Self { failed_checks_fail: 0.0 }
    }
}

/// Limits of the studies' reports.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StudyLimits {
    /// Report sections whose check failed: failure above (default 0).
    pub failed_checks_fail: f64,
    /// Report sections skipped (an input is missing): warning above (default 0).
    pub skipped_warn: f64,
    /// `corner-study`: the largest ratio of this project's corner RMS error to the Cramer-Rao
    /// bound over the noisy levels: warning above (default 3: an efficient estimator reaches 1).
    pub corner_over_crb_warn: f64,
    /// `handeye study`: the smallest 3-sigma coverage of the hand-eye translation and rotation
    /// coordinates over the mounts: warning below (default 0.95; an honest covariance covers
    /// 99.73 %).
    pub coverage_3sigma_warn: f64,
    /// `handeye study`: smallest 3-sigma coverage: failure below (default 0.8: the stated
    /// standard deviations are far too small).
    pub coverage_3sigma_fail: f64,
    /// `handeye study`: simulations whose calibration failed: warning above (default 0).
    pub failed_runs_warn: f64,
}

impl Default for StudyLimits {
    fn default() -> Self {
        Self {
            failed_checks_fail: 0.0,
            skipped_warn: 0.0,
            corner_over_crb_warn: 3.0,
            coverage_3sigma_warn: 0.95,
            coverage_3sigma_fail: 0.8,
            failed_runs_warn: 0.0,
        }
    }
}

/// Limits of `robot fk` and `robot ik`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RobotLimits {
    /// `robot fk`: the smallest distance of a joint from its nearer limit, as a fraction of the
    /// joint's range: warning below (default 0.01: 3.4 deg of a +-170 deg axis, 7.2 deg of a
    /// +-360 deg UR axis, 20 mm of a 2 m slide; a pose at the end of travel trips the
    /// controller's soft limits or cannot be left in one direction).
    pub limit_margin_warn: f64,
    /// `robot ik`: distance of the solution's tool position from the target, mm: failure above
    /// (default 1e-3 mm; a converged solution is at 1e-7 mm).
    pub ik_position_mm_fail: f64,
    /// `robot ik`: angle of the solution's tool orientation from the target, degrees: failure
    /// above (default 1e-3 deg).
    pub ik_orientation_deg_fail: f64,
}

impl Default for RobotLimits {
    fn default() -> Self {
        Self { limit_margin_warn: 0.01, ik_position_mm_fail: 1e-3, ik_orientation_deg_fail: 1e-3 }
    }
}

/// Limits of `dynamics identify` and `dynamics identify-static`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DynamicsLimits {
    /// Parameters the data do not determine (infinite standard deviation, or dropped for
    /// rank): warning above (default 0).
    pub undetermined_warn: f64,
    /// Condition number of the weighted, column-scaled regressor: warning above (default 1000;
    /// excitation designs aim below 100, and the simulated recordings give 4 to 190).
    pub condition_number_warn: f64,
    /// Relative standard deviation of the identified mass (`m_kg`): warning above (default
    /// 0.05; the simulated recordings give 0.05 % to 0.8 %).
    pub mass_relative_std_warn: f64,
    /// A-posteriori variance factor s0 with the noise measured from repeated periods
    /// (`--period-samples`): warning above (default 2: the residuals are twice the noise, the
    /// model leaves something out; the right model on simulated data gives 1.00, model 6 on a
    /// deforming sensor 1.63).
    pub s0_warn: f64,
}

impl Default for DynamicsLimits {
    fn default() -> Self {
        Self { undetermined_warn: 0.0, condition_number_warn: 1000.0, mass_relative_std_warn: 0.05, s0_warn: 2.0 }
    }
}

/// Limits of `stiffness identify`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StiffnessLimits {
    /// A-posteriori variance factor s0 of the final fit against the table's `sigma_mm`:
    /// warning above (default 2: the deflections scatter twice as much as stated, or the model
    /// leaves something out; the simulated tables give 0.9 to 1.3).
    pub s0_warn: f64,
}

impl Default for StiffnessLimits {
    fn default() -> Self {
        Self { s0_warn: 2.0 }
    }
}

impl Thresholds {
    /// Reads a thresholds file: the defaults with the file's keys in their place.
    pub fn load(path: &Path) -> Result<Self, ThresholdsError> {
        let text =
            std::fs::read_to_string(path).map_err(|source| ThresholdsError::Read { path: path.into(), source })?;
        Self::from_toml(&text, path)
    }

    /// Parses the text of a thresholds file; `path` names it in errors.
    pub fn from_toml(text: &str, path: &Path) -> Result<Self, ThresholdsError> {
        let parse = |message: String| ThresholdsError::Parse { path: path.into(), message };
        let mut given: toml::Table = toml::from_str(text).map_err(|e| parse(one_line(&e.to_string())))?;
        let defaults = default_table().map_err(parse)?;
        check_keys(&mut given, &defaults, "", path)?;
        toml::Value::Table(given).try_into().map_err(|e: toml::de::Error| parse(one_line(&e.to_string())))
    }

    /// Every limit as `(dotted name, default value)`, in the order of the file (for the
    /// documentation and `--help`).
    pub fn defaults_list() -> Vec<(String, f64)> {
        let mut out = Vec::new();
        if let Ok(t) = default_table() {
            for (section, v) in &t {
                if let Some(inner) = v.as_table() {
                    for (k, x) in inner {
                        out.push((format!("{section}.{k}"), x.as_float().unwrap_or(f64::NAN)));
                    }
                }
            }
        }
        out
    }
}

/// The defaults as a TOML table.
fn default_table() -> Result<toml::Table, String> {
    match toml::Value::try_from(Thresholds::default()) {
        Ok(toml::Value::Table(t)) => Ok(t),
        Ok(_) => Err("the default thresholds are not a table".into()),
        Err(e) => Err(e.to_string()),
    }
}

/// Refuses keys of `given` that `known` lacks (recursively); integers become floats.
fn check_keys(given: &mut toml::Table, known: &toml::Table, prefix: &str, path: &Path) -> Result<(), ThresholdsError> {
    for (key, value) in given.iter_mut() {
        let dotted = if prefix.is_empty() { key.clone() } else { format!("{prefix}.{key}") };
        let Some(k) = known.get(key) else {
            return Err(ThresholdsError::UnknownKey {
                path: path.into(),
                key: dotted,
                known: known.keys().cloned().collect::<Vec<_>>().join(", "),
            });
        };
        match (value, k) {
            (toml::Value::Table(g), toml::Value::Table(kt)) => check_keys(g, kt, &dotted, path)?,
            (v @ toml::Value::Integer(_), toml::Value::Float(_)) => {
                let i = v.as_integer().unwrap_or_default();
                *v = toml::Value::Float(i as f64);
            }
            (toml::Value::Float(_), toml::Value::Float(_)) => {}
            (v, toml::Value::Float(_)) => {
                return Err(ThresholdsError::NotANumber { path: path.into(), key: dotted, value: v.to_string() })
            }
            (v, _) => {
                return Err(ThresholdsError::Parse {
                    path: path.into(),
                    message: format!("'{dotted}' must be a table of limits, got {v}"),
                })
            }
        }
    }
    Ok(())
}

fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}
