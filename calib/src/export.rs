//! A calibration in the formats the ecosystem reads: the calibrated serial robot as a URDF with
//! corrected joint origins, the device frame as its root link and the measured target as its
//! tip link (`ferrocal export --urdf`), and as a modified Denavit-Hartenberg table with
//! Hayati's angle for parallel axes (`ferrocal export --dh`).
//!
//! What a URDF cannot hold: physical effects (compliance, backlash, periodic errors, ...). They
//! stay in the companion calibration file written beside the URDF, which `evaluate` reads with
//! the URDF as the robot model: identity device frame and tool, zero joint offsets, and the
//! effects.

use ferrocal_robot::serial::{parse_urdf_str, to_urdf, MdhTable, UrdfFrames, UrdfOptions};
use ferrocal_robot::{Kinematics, RobotModel};

use crate::error::{CalibError, Result};
use crate::file::CalibrationFile;
use crate::kinematic::CalibratedModel;

/// A URDF export and what it was checked against.
#[derive(Clone, Debug)]
pub struct UrdfExport {
    /// The URDF document.
    pub urdf: String,
    /// The calibration file for the URDF as the robot model (identity frames, zero offsets, the
    /// effects), so that `evaluate --robot <urdf> --calibration <this>` predicts as the original.
    pub companion: CalibrationFile,
    /// Largest difference, over the test configurations, between the URDF read back and the
    /// calibrated model: position (m) and orientation (rad).
    pub roundtrip_m_rad: (f64, f64),
}

/// Exports `cm` (a serial robot, calibrated from the model `robot_spec`) as a URDF; `urdf_name`
/// is how the companion file names the URDF (its path as the user will pass it to `--robot`),
/// `comment` goes into the file's header. The URDF is read back and compared with `cm` at 200
/// configurations within the joint limits.
pub fn export_urdf(cm: &CalibratedModel, robot_spec: &str, urdf_name: &str, comment: &str) -> Result<UrdfExport> {
    let RobotModel::Serial(chain) = &cm.model else {
        return Err(CalibError::Data(format!(
            "URDF export is for serial robots; '{}' is a parallel robot (its calibration file is its export)",
            cm.model.name()
        )));
    };
    let mut chain = chain.clone();
    chain.tool *= cm.tool;
    let frames = UrdfFrames { root_link: "device".into(), root_to_base: cm.device_frame, tip_link: "target".into() };
    let urdf = to_urdf(&chain, &cm.joint_offsets, &frames, comment)?;
    let back = parse_urdf_str(&urdf, &UrdfOptions { tip_link: Some("target".into()) })?;
    let back = RobotModel::Serial(back);
    // The check: the URDF read back against the calibrated model (without effects).
    let worst = worst_difference(cm, |q| Ok(back.forward(q)?))?;
    let mut for_urdf = CalibratedModel::nominal(back);
    for_urdf.orientation_calibrated = cm.orientation_calibrated;
    for_urdf.effects = cm.effects.clone();
    // Effects take their loads from the nominal geometry of the original model, as when they
    // were identified (the URDF holds the calibrated link frames).
    for_urdf.load_model = cm.load_model.clone();
    let mut companion = CalibrationFile::new(urdf_name, &for_urdf);
    if !cm.effects.is_empty() {
        companion.load_model = Some(robot_spec.to_string());
    }
    Ok(UrdfExport { urdf, companion, roundtrip_m_rad: worst })
}

/// The largest difference between the calibrated model `cm` (without effects) and another
/// model's forward kinematics `other`, over 200 configurations spread within the joint limits
/// (+-3 rad or m where a limit is open): position (m) and orientation (rad).
fn worst_difference(
    cm: &CalibratedModel,
    other: impl Fn(&[f64]) -> Result<nalgebra::Isometry3<f64>>,
) -> Result<(f64, f64)> {
    let limits = cm.model.joint_limits();
    let mut worst = (0.0f64, 0.0f64);
    for s in 0..200usize {
        let q: Vec<f64> = limits
            .iter()
            .enumerate()
            .map(|(i, l)| {
                let u = 0.5 + 0.5 * ((s * 7 + i * 13) as f64 * 0.618_033_988_75).sin();
                let (lo, hi) =
                    if l.lower.is_finite() && l.upper.is_finite() { (l.lower, l.upper) } else { (-3.0, 3.0) };
                lo + u * (hi - lo)
            })
            .collect();
        let want = cm.predict(&q)?;
        let got = other(&q)?;
        worst.0 = worst.0.max((got.translation.vector - want.translation.vector).norm());
        worst.1 = worst.1.max(got.rotation.angle_to(&want.rotation));
    }
    Ok(worst)
}

/// A modified DH export and what it was checked against.
#[derive(Clone, Debug)]
pub struct MdhExport {
    /// The table: base = the device frame times the robot's base, tool = the measured target.
    pub table: MdhTable,
    /// Largest difference, over 200 configurations, between the table's forward kinematics and
    /// the calibrated model (without effects): position (m) and orientation (rad).
    pub roundtrip_m_rad: (f64, f64),
}

/// Exports `cm` (a serial robot) as a modified DH table with Hayati's angle for parallel axes
/// ([`ferrocal_robot::serial::MdhTable`]): the calibrated corrections and joint zero offsets
/// become the table's lengths, twists and offsets, the device frame goes into `base` and the
/// measured target into `tool`. Effects are not in the table (the calibration file keeps them).
pub fn export_mdh(cm: &CalibratedModel) -> Result<MdhExport> {
    let RobotModel::Serial(chain) = &cm.model else {
        return Err(CalibError::Data(format!(
            "a DH table is for serial robots; '{}' is a parallel robot (its calibration file is its export)",
            cm.model.name()
        )));
    };
    let mut chain = chain.clone();
    chain.base = cm.device_frame * chain.base;
    chain.tool *= cm.tool;
    let table = chain.to_mdh_table(&cm.joint_offsets)?;
    let roundtrip_m_rad = worst_difference(cm, |q| Ok(table.forward(q)?))?;
    Ok(MdhExport { table, roundtrip_m_rad })
}
