//! The `calibrate` workflow: the table loaded and checked against the model
//! ([`load_model_and_rows`], [`check_distinct_poses`], [`check_params`]), and its validation protocol: a validation fit on the training rows with
//! the nominal and calibrated held-out errors, the delivered fit, and a spatially separated
//! check beside the default one ([`calibrate_table`]), and whether the result can be delivered
//! ([`CalibrationRun::deliverable`]). The report crate turns a [`CalibrationRun`] into the JSON
//! of `ferrocal calibrate` and its report sections. Also the `evaluate` workflow (a calibration
//! file applied, [`apply_calibration`], and scored on a table, [`evaluate_rows`]) and the
//! `export` workflow ([`export_calibration`]).

use ferrocal_calib::kinematic::{
    calibrate, refit_frame, split_rows, split_rows_by_plane, CalibratedModel, ErrorStats, FrameRefit,
    KinematicCalibration, KinematicOptions, ModelParams, SplitPlane,
};
use std::path::{Path, PathBuf};

use ferrocal_calib::export::{export_mdh, export_urdf};
use ferrocal_calib::file::CalibrationFile;
use ferrocal_calib::lsq::Loss;
use ferrocal_calib::{PoseMeasurement, Split};
use ferrocal_robot::{Kinematics, Parameterized, RobotModel};

use crate::error::{DatasetError, Result};

/// A calibration on the training rows with the nominal and calibrated held-out errors.
pub type Validation = Option<(KinematicCalibration, ErrorStats, ErrorStats)>;

/// The spatially separated check: rows beyond the median plane normal to the positions' first
/// principal axis held out.
#[derive(Clone, Debug)]
pub struct SpatialCheck {
    /// The plane; rows on its positive side are held out.
    pub plane: SplitPlane,
    /// Training rows.
    pub n_train: usize,
    /// Held-out errors of the nominal model (frames registered on the training rows).
    pub before: ErrorStats,
    /// Held-out errors of the calibration on the training rows.
    pub after: ErrorStats,
}

/// A calibration as `ferrocal calibrate` delivers it: the fit on all rows (or on the training
/// rows when the table fixes the split) with the validation fit on the training rows.
pub struct CalibrationRun<'a> {
    /// The delivered calibration.
    pub cal: KinematicCalibration,
    /// The validation fit with the nominal and calibrated held-out errors, when rows are held out.
    pub validation: Validation,
    /// The rows of the delivered fit.
    pub final_rows: Vec<&'a PoseMeasurement>,
    /// True when the table's `split` column fixed the split.
    pub fixed_split: bool,
    /// The spatially separated check; with every-second-pose validation only.
    pub heldout_spatial: Option<SpatialCheck>,
}

fn fit(
    model: &RobotModel,
    rows: &[&PoseMeasurement],
    opts: &KinematicOptions,
    what: &str,
) -> Result<KinematicCalibration> {
    calibrate(model, rows, opts).map_err(|e| DatasetError::from(e).context(what))
}

/// Calibrates `model` from `rows`: a validation fit on the training rows (every second pose, or
/// the table's split; none when `validate` is false and the table has no split), then the
/// delivered fit on all rows unless the table fixes the split. `step` is called after each fit.
pub fn calibrate_table<'a>(
    model: &RobotModel,
    rows: &'a [PoseMeasurement],
    opts: &KinematicOptions,
    validate: bool,
    step: &dyn Fn(),
) -> Result<CalibrationRun<'a>> {
    let fixed_split = rows.iter().any(|r| r.split.is_some());
    let (mut train, mut test) = split_rows(rows, validate);
    // With the residual test (`opts.outliers`), the rows the fit on all rows drops are left out of
    // every fit and every held-out score; the other rows keep their place in the split.
    let mut screened = None;
    if opts.outliers.is_some() && !fixed_split {
        let all: Vec<&PoseMeasurement> = rows.iter().collect();
        let c = fit(model, &all, opts, "calibration")?;
        if !c.dropped_rows.is_empty() {
            let gone = |r: &&PoseMeasurement| c.dropped_rows.iter().any(|d| d.pose_id == r.pose_id);
            train.retain(|r| !gone(r));
            test.retain(|r| !gone(r));
        }
        screened = Some(c);
    }
    let dropped: Vec<String> =
        screened.as_ref().map(|c| c.dropped_rows.iter().map(|d| d.pose_id.clone()).collect()).unwrap_or_default();
    let kept = |r: &&PoseMeasurement| !dropped.contains(&r.pose_id);
    // Validation: fit on the training rows, evaluate on the held-out rows.
    let validation = if test.is_empty() {
        None
    } else {
        let cal = fit(model, &train, opts, "calibration on the training rows")?;
        let before = nominal_stats(model, &train, &test)?;
        let after = cal.calibrated.evaluate(&test)?;
        Some((cal, before, after))
    };
    step();
    // The delivered calibration: all rows, unless the table fixes the split.
    let final_rows: Vec<&PoseMeasurement> =
        if fixed_split { train.clone() } else { rows.iter().filter(kept).collect() };
    let cal = match (&validation, fixed_split, screened) {
        (Some((c, _, _)), true, _) => c.clone(),
        (_, _, Some(c)) => c,
        _ => fit(model, &final_rows, opts, "calibration")?,
    };
    // A spatially separated check beside the default one: training poses are not neighbours of
    // the held-out ones.
    let mut heldout_spatial = None;
    if validation.is_some() && !fixed_split {
        if let Some((mut tr, mut te, plane)) = split_rows_by_plane(rows) {
            tr.retain(kept);
            te.retain(kept);
            let c = fit(model, &tr, opts, "calibration on the spatial training rows")?;
            let (before, after) = (nominal_stats(model, &tr, &te)?, c.calibrated.evaluate(&te)?);
            heldout_spatial = Some(SpatialCheck { plane, n_train: tr.len(), before, after });
        }
    }
    step();
    Ok(CalibrationRun { cal, validation, final_rows, fixed_split, heldout_spatial })
}

/// Errors of the nominal model on `test` with frames registered on `train`.
pub fn nominal_stats(model: &RobotModel, train: &[&PoseMeasurement], test: &[&PoseMeasurement]) -> Result<ErrorStats> {
    let opts =
        KinematicOptions { model_params: ModelParams::None, joint_offsets: false, ..KinematicOptions::default() };
    let cal = fit(model, train, &opts, "registering the nominal model")?;
    Ok(cal.calibrated.evaluate(test)?)
}

/// Loads a model and a measurement table and checks that they agree; the table's warnings go to
/// `warn` once they do.
///
/// A URDF that is a tree of chains (`docs/trees.md`) is read whole when the table holds every
/// moving joint of the tree or names its measured links (a `tip` column, or `tip` for the rows
/// without one); the tips are the links the rows name, in the order they first appear. A table
/// that holds only the joints of the chain to one tip, of a tree whose other branches move and
/// carry mass, is read as that chain with a warning that the other branches' motion is missing.
pub fn load_model_and_rows(
    robot: &str,
    measurements: &Path,
    tip: Option<&str>,
    warn: &dyn Fn(&str),
) -> Result<(RobotModel, Vec<PoseMeasurement>)> {
    let mut table = crate::import::read_measurements(measurements)?;
    if let Some(tip) = tip {
        for r in table.set.rows.iter_mut().filter(|r| r.tip().is_none()) {
            r.meta.insert("tip".into(), tip.to_string());
        }
    }
    let model = crate::trees::load_for_table(robot, measurements, &table.set.rows, table.joint_units.len(), warn)?;
    let n = model.dof();
    if table.joint_units.len() != n {
        return Err(DatasetError::Input(format!(
            "{}: the table has {} joint columns but the robot model '{}' has {n} joints",
            measurements.display(),
            table.joint_units.len(),
            model.name()
        )));
    }
    table.check_joint_kinds(&model.joint_kinds()).map_err(|e| {
        e.context(format!("{}: joint units do not match the joint kinds of '{}'", measurements.display(), model.name()))
    })?;
    table.check_joint_values(&model.joint_limits(), model.name())?;
    table.warnings.iter().for_each(|w| warn(w));
    Ok((model, table.set.rows))
}

/// Fewest distinct joint configurations a calibration or diagnosis accepts (a rigid registration
/// of the device frame alone needs three).
pub const MIN_DISTINCT_POSES: usize = 3;

/// Refuses a pose set with fewer than [`MIN_DISTINCT_POSES`] distinct joint configurations
/// (a table of one pose repeated 200 times calibrates nothing).
pub fn check_distinct_poses(rows: &[PoseMeasurement], measurements: &Path) -> Result<usize> {
    let distinct = crate::import::plausible::distinct_poses(rows);
    if distinct < MIN_DISTINCT_POSES {
        return Err(DatasetError::Input(format!(
            "{}: the {} rows hold {distinct} independent pose(s) (rows with the same joint readings are one pose); a calibration needs many distinct poses: measure more poses",
            measurements.display(),
            rows.len()
        )));
    }
    Ok(distinct)
}

/// The flags of `ferrocal calibrate` that choose the method, as given on the command line.
#[derive(Clone, Copy, Debug)]
pub struct CalibrateFlags<'a> {
    /// `--params`: `default`, `all`, `none` or comma-separated name prefixes ([`parse_params`]).
    pub params: &'a str,
    /// `--loss`: `none`, `huber:<sigmas>` or `cauchy:<sigmas>` ([`parse_loss`]).
    pub loss: &'a str,
    /// Position standard deviation for rows without a sigma column, mm.
    pub sigma_mm: f64,
    /// Orientation standard deviation for rows with orientations, degrees.
    pub sigma_deg: f64,
    /// Ignore measured orientations.
    pub positions_only: bool,
    /// Drop parameters whose parameter-to-noise ratio is below this.
    pub practical_threshold: Option<f64>,
    /// `--effects`: a `diagnose --json` report, a calibration file or a list of effects.
    pub effects: Option<&'a str>,
    /// `--cost`: `fk` or `closure`.
    pub cost: &'a str,
    /// Largest number of solver iterations.
    pub max_iterations: usize,
}

impl CalibrateFlags<'_> {
    /// The options of the calibration, each flag checked by name; a row far beyond the others
    /// (a typo) is named and dropped, not fitted.
    pub fn options(&self) -> Result<KinematicOptions> {
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if !positive(self.sigma_mm) || !positive(self.sigma_deg) {
            return Err(DatasetError::Input("--sigma-mm and --sigma-deg must be positive".into()));
        }
        if self.max_iterations == 0 {
            return Err(DatasetError::Input("--max-iterations must be at least 1".into()));
        }
        Ok(KinematicOptions {
            model_params: parse_params(self.params)?,
            use_orientation: !self.positions_only,
            sigma_position_m: self.sigma_mm * 1e-3,
            sigma_orientation_rad: self.sigma_deg.to_radians(),
            loss: parse_loss(self.loss)?,
            practical_threshold: self.practical_threshold,
            effects: match self.effects {
                Some(e) => ferrocal_calib::effect_list::effects_from_argument(e)
                    .map_err(|e| DatasetError::from(e).context("--effects"))?,
                None => Vec::new(),
            },
            cost: match self.cost {
                "fk" => ferrocal_calib::kinematic::Cost::ForwardKinematics,
                "closure" => ferrocal_calib::kinematic::Cost::Closure,
                other => return Err(DatasetError::Input(format!("--cost {other}: use fk or closure"))),
            },
            lm: ferrocal_calib::lsq::LmOptions {
                max_iterations: self.max_iterations,
                ..KinematicOptions::default().lm
            },
            outliers: Some(ferrocal_calib::kinematic::OutlierScreen::default()),
            ..KinematicOptions::default()
        })
    }
}

/// The robust loss of `--loss`: `none` (or `squared`), `huber:<sigmas>` or `cauchy:<sigmas>`.
pub fn parse_loss(s: &str) -> Result<Loss> {
    let (kind, val) = s.split_once(':').unwrap_or((s, ""));
    let delta = || -> Result<f64> {
        let d: f64 =
            val.parse().map_err(|e| DatasetError::Input(format!("--loss {s}: '{val}' is not a number: {e}")))?;
        if !(d.is_finite() && d > 0.0) {
            return Err(DatasetError::Input(format!("--loss {s}: the scale must be positive")));
        }
        Ok(d)
    };
    Ok(match kind {
        "none" | "squared" => Loss::Squared,
        "huber" => Loss::Huber { delta: delta()? },
        "cauchy" => Loss::Cauchy { delta: delta()? },
        _ => return Err(DatasetError::Input(format!("--loss {s}: use none, huber:<sigmas> or cauchy:<sigmas>"))),
    })
}

/// The parameters of `--params`: `default`, `all`, `none` or comma-separated name prefixes.
pub fn parse_params(s: &str) -> Result<ModelParams> {
    Ok(match s {
        "default" => ModelParams::Default,
        "all" => ModelParams::All,
        "none" => ModelParams::None,
        list => {
            let prefixes: Vec<String> =
                list.split(',').map(|p| p.trim().to_string()).filter(|p| !p.is_empty()).collect();
            if prefixes.is_empty() {
                return Err(DatasetError::Input(format!(
                    "--params '{list}' names no parameter: use default, all, none or comma-separated name prefixes"
                )));
            }
            ModelParams::Prefixes { prefixes }
        }
    })
}

/// Refuses `--params` prefixes that match none of the model's parameters (a misspelt list
/// would otherwise calibrate the frames alone and report success).
pub fn check_params(params: &ModelParams, model: &RobotModel) -> Result<()> {
    if let ModelParams::Prefixes { prefixes } = params {
        let names: Vec<String> = model.parameters().into_iter().map(|p| p.name).collect();
        let unmatched: Vec<&String> =
            prefixes.iter().filter(|x| !names.iter().any(|n| n.starts_with(x.as_str()))).collect();
        if !unmatched.is_empty() {
            let examples: Vec<&str> = names.iter().take(4).map(String::as_str).collect();
            return Err(DatasetError::Input(format!(
                "--params: {} match(es) no parameter of '{}' (its names look like {}, ...; `ferrocal robot info --robot {}` lists them)",
                unmatched.iter().map(|u| format!("'{u}'")).collect::<Vec<_>>().join(", "),
                model.name(),
                examples.join(", "),
                model.name()
            )));
        }
    }
    Ok(())
}

impl CalibrationRun<'_> {
    /// Whether the calibration can be delivered, with what stderr should say about it: refused
    /// when the distinct poses of the delivered fit give no more equations than identified
    /// parameters (repeated rows of one pose add equations but no information), or when a fit
    /// did not converge (unless `accept_unconverged`, then with a warning). The lines name
    /// `measurements` where a row is meant: the solver's noise note, the rows the outlier screen
    /// dropped, its note.
    ///
    /// A fit that did not converge while changing a length or an angle of the model beyond
    /// `model_change_fail` (mm, degrees: `calibrate.model_change_*_fail`) is refused naming the
    /// parameter and `--robot`, not with the advice to raise `--max-iterations` (a UR5 table
    /// calibrated as a UR10 stops at the limit; with more iterations it converges with 180 mm
    /// link corrections).
    pub fn deliverable(
        &self,
        measurements: &Path,
        accept_unconverged: bool,
        model_change_fail: (f64, f64),
    ) -> Result<Vec<String>> {
        let (cal, rows) = (&self.cal, &self.final_rows);
        let distinct = crate::import::plausible::distinct_poses(rows.iter().copied());
        let block = if cal.used_orientation { 6 } else { 3 };
        if distinct * block <= cal.free.len() {
            return Err(DatasetError::Input(format!(
                "{}: the {} rows hold only {distinct} independent poses ({} equations) for {} identified parameters: the pose set is rank-deficient; measure more distinct poses; nothing was written",
                measurements.display(),
                rows.len(),
                distinct * block,
                cal.free.len()
            )));
        }
        let mut lines = Vec::new();
        let fits =
            std::iter::once(("calibration", cal)).chain(self.validation.iter().map(|(v, _, _)| ("validation fit", v)));
        for (what, fit) in fits {
            if let Some(problem) = fit.convergence_problem() {
                let (mm, deg) = fit.largest_model_changes();
                let beyond = [(mm, "mm", model_change_fail.0), (deg, "deg", model_change_fail.1)]
                    .into_iter()
                    .find_map(|(m, unit, limit)| m.filter(|m| m.change.abs() > limit).map(|m| (m, unit, limit)));
                if let (Some((m, unit, limit)), false) = (beyond, accept_unconverged) {
                    return Err(DatasetError::Input(format!(
                        "{what}: {problem}, changing {} by {:+.1} {unit} (more than the {limit} {unit} of calibrate.model_change_{unit}_fail): the table does not fit this robot model: wrong --robot? check that {} was recorded on this robot and in the units its headers name; nothing was written",
                        m.name,
                        m.change,
                        measurements.display()
                    )));
                }
                if !accept_unconverged {
                    return Err(DatasetError::Input(format!("{what}: {problem}; nothing was written (raise --max-iterations, check the data, or accept it with --accept-unconverged)")));
                }
                lines.push(format!("warning: {what}: {problem}; delivered because of --accept-unconverged"));
            }
        }
        lines.extend(cal.noise_warning().map(|w| format!("note: {w}")));
        lines.extend(cal.dropped_rows.iter().map(|d| format!("warning: {}: {}", measurements.display(), d.describe())));
        lines.extend(cal.outlier_note.iter().map(|n| format!("warning: {}: {n}", measurements.display())));
        Ok(lines)
    }
}

/// Reads the calibration file `path`, checks that it was made for `robot` (its model `model`)
/// and applies it.
pub fn apply_calibration(robot: &str, model: &RobotModel, path: &Path) -> Result<CalibratedModel> {
    read_calibration(robot, model, path).map(|(_, cm)| cm)
}

/// [`apply_calibration`], keeping the file as read (its nominal frames, coverage and
/// uncertainty).
pub fn read_calibration(robot: &str, model: &RobotModel, path: &Path) -> Result<(CalibrationFile, CalibratedModel)> {
    let file = CalibrationFile::read(path)?;
    file.check_robot(robot, model).map_err(|e| DatasetError::from(e).context(format!("{}", path.display())))?;
    let cm = file.apply(model).map_err(|e| DatasetError::from(e).context(format!("applying {}", path.display())))?;
    Ok((file, cm))
}

/// A calibrated model scored on a table (`ferrocal evaluate`).
#[derive(Clone, Debug)]
pub struct EvaluateRun {
    /// The model, its device frame and tool point refitted on the table when asked.
    pub model: CalibratedModel,
    /// What the frame refit changed.
    pub refit: Option<FrameRefit>,
    /// The rows scored: the `test` rows of a table with a split column, else every row.
    pub scored: Vec<PoseMeasurement>,
    /// True when only the `test` rows are scored.
    pub test_only: bool,
    /// True when the table has a split column that marks no row `test` (every row is scored).
    pub no_test_marked: bool,
}

impl EvaluateRun {
    /// Refuses a run with no row to score (`measurements`: the table, named in the error).
    pub fn check_scored(&self, measurements: &Path) -> Result<()> {
        if self.scored.is_empty() {
            return Err(DatasetError::Input(format!(
                "{}: the table has no rows to score; give a table of measured poses",
                measurements.display()
            )));
        }
        Ok(())
    }

    /// Which rows were scored, in words (`n` of them).
    pub fn scored_words(&self, n: usize) -> String {
        if self.test_only {
            format!("the {n} held-out (test) rows")
        } else {
            format!("all {n} rows")
        }
    }
}

/// Scores `cm` on `rows`: first, when `refit_sigma_mm` is given (the position standard
/// deviation of rows without a sigma column, mm), the device frame and the measured point on
/// the tool refitted on the whole table; then a table with a split column is scored on its
/// `test` rows only (shared/spec/cli.md).
pub fn evaluate_rows(
    cm: CalibratedModel,
    rows: Vec<PoseMeasurement>,
    refit_sigma_mm: Option<f64>,
) -> Result<EvaluateRun> {
    let (mut model, mut refit) = (cm, None);
    if let Some(sigma_mm) = refit_sigma_mm {
        if !(sigma_mm.is_finite() && sigma_mm > 0.0) {
            return Err(DatasetError::Input("--sigma-mm must be positive".into()));
        }
        let refs: Vec<&PoseMeasurement> = rows.iter().collect();
        let (m, record) =
            refit_frame(&model, &refs, sigma_mm * 1e-3).map_err(|e| DatasetError::from(e).context("--refit-frame"))?;
        model = m;
        refit = Some(record);
    }
    let n_test = rows.iter().filter(|r| r.split == Some(Split::Test)).count();
    let no_test_marked = n_test == 0 && rows.iter().any(|r| r.split.is_some());
    let test_only = n_test > 0;
    let scored = if test_only { rows.into_iter().filter(|r| r.split == Some(Split::Test)).collect() } else { rows };
    Ok(EvaluateRun { model, refit, scored, test_only, no_test_marked })
}

/// A calibration exported (`ferrocal export`): the files composed, not written.
#[derive(Clone, Debug)]
pub struct ExportRun {
    /// The files in writing order: the DH table, the URDF and its companion calibration file.
    pub files: Vec<(PathBuf, String)>,
    /// The DH table.
    pub dh: Option<PathBuf>,
    /// The URDF.
    pub urdf: Option<PathBuf>,
    /// The URDF's companion calibration file (`<name>.calibration.json`).
    pub companion: Option<PathBuf>,
    /// How far the DH table's forward kinematics are from the calibrated model, mm and degrees.
    pub dh_roundtrip_mm_deg: Option<(f64, f64)>,
    /// How far the URDF read back is from the calibrated model, mm and degrees.
    pub urdf_roundtrip_mm_deg: Option<(f64, f64)>,
}

impl ExportRun {
    /// The largest read-back difference of the files, mm and degrees (zero without any).
    pub fn roundtrip_mm_deg(&self) -> (f64, f64) {
        let dh = self.dh_roundtrip_mm_deg.unwrap_or((0.0, 0.0));
        self.urdf_roundtrip_mm_deg.map_or(dh, |(mm, deg)| (dh.0.max(mm), dh.1.max(deg)))
    }
}

/// The URDF's companion calibration file beside `urdf` (`<name>.calibration.json`).
pub fn companion_path(urdf: &Path) -> PathBuf {
    urdf.with_extension("calibration.json")
}

/// Exports the calibrated serial robot `cm` (from the calibration file `calibration`, made for
/// `robot`) as a modified DH table at `dh` and as a URDF at `urdf` with its companion
/// calibration file, each checked by reading it back.
pub fn export_calibration(
    cm: &CalibratedModel,
    robot: &str,
    calibration: &Path,
    urdf: Option<&Path>,
    dh: Option<&Path>,
) -> Result<ExportRun> {
    let version = env!("CARGO_PKG_VERSION");
    let (dh_path, urdf_path) = (dh.map(Path::to_path_buf), urdf.map(Path::to_path_buf));
    let mut run = ExportRun {
        files: Vec::new(),
        dh: dh_path,
        urdf: urdf_path,
        companion: None,
        dh_roundtrip_mm_deg: None,
        urdf_roundtrip_mm_deg: None,
    };
    if let Some(dh) = dh {
        let ex = export_mdh(cm)?;
        let (mm, deg) = (ex.roundtrip_m_rad.0 * 1e3, ex.roundtrip_m_rad.1.to_degrees());
        let comment = vec![
            format!("written by ferrocal {version} from {} (robot {robot})", calibration.display()),
            "the measuring device's frame is in 'base', the measured target in 'tool'; effects (if any) stay in the calibration file".into(),
            format!(
                "checked: the table's forward kinematics differ from the calibrated model by at most {mm:.2e} mm and {deg:.2e} deg over 200 configurations"
            ),
        ];
        run.files.push((dh.to_path_buf(), ex.table.to_csv(&comment)));
        run.dh_roundtrip_mm_deg = Some((mm, deg));
    }
    if let Some(urdf) = urdf {
        let comment = format!(
            "written by ferrocal {version} from {} (robot {robot}); joint origins include the calibrated corrections and zero offsets; the measured target is link 'target', the measuring device's frame is link 'device'",
            calibration.display()
        );
        let ex = export_urdf(cm, robot, &urdf.display().to_string(), &comment)?;
        let companion = companion_path(urdf);
        run.files.push((urdf.to_path_buf(), ex.urdf));
        run.files.push((companion.clone(), serde_json::to_string_pretty(&ex.companion)?));
        run.companion = Some(companion);
        run.urdf_roundtrip_mm_deg = Some((ex.roundtrip_m_rad.0 * 1e3, ex.roundtrip_m_rad.1.to_degrees()));
    }
    Ok(run)
}
