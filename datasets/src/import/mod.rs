//! Importers for real recordings, and export to the measurement table.
//!
//! - [`measurements`]: the measurement CSV of `shared/spec/measurements.md` (reader and writer);
//!   every other importer's [`MeasurementSet`](ferrocal_calib::MeasurementSet) can be written
//!   with [`write_measurements`] and so feed the command-line tools.
//! - [`ur5`]: the UR5 laser-tracker grid (`ur5_tracker/ur5_grid_train.csv`).
//! - [`ur10`]: the UR10 laser-tracker series A and B (`ur10_tracker/`): raw typed rows, the
//!   T-Mac-to-flange transform files, the hand-eye table, conversion to a measurement set and the
//!   reproduction of measured positions from nominal kinematics.
//! - [`images`]: image folders with an optional joints table.
//! - [`plausible`]: plausibility checks at the boundary (joint values against the model's
//!   limits, a table cut short, repeated poses) and the cutting of long cells in messages.
//! - [`convert`]: the `ferrocal import` workflow (a recording to a measurement table).
//! - [`geometry`]: Euler conventions of the recordings and rigid registration (Kabsch / Horn).
//!
//! All values are converted to SI (metres, radians) on import. Every error about file content
//! names the file, the 1-based line (comment lines count) and the column.

pub mod convert;
pub mod geometry;
pub mod images;
pub mod measurements;
pub mod observations;
pub mod plausible;
pub(crate) mod table;
pub mod units;
pub mod ur10;
pub mod ur5;

pub use geometry::{
    extrinsic_xyz_from_quat, fit_rigid, intrinsic_xyz_from_quat, quat_from_extrinsic_xyz, quat_from_intrinsic_xyz,
    register_positions, register_with_offset, OffsetRegistration, PositionRegistration,
};
pub use images::{
    list_images, natural_cmp, read_joints_table, write_joints_table, ImageEntry, ImageFolder, ImageFolderOptions,
    JointsRow, JointsTable, SkippedImage,
};
pub use measurements::{
    measurements_to_string, parse_measurements, read_joint_program, read_measurements, read_targets,
    write_measurements, MeasurementTable, WriteOptions,
};
pub use units::{JointUnit, LengthUnit};
pub use ur10::{
    import_ur10_measurements, read_tmac_flange_transform, read_ur10_handeye, read_ur10_measurements, HandEyeRow,
    TmacFlangeFile, Ur10Recording, Ur10Row, Ur10Std, Ur10Timestamp,
};
pub use ur5::{import_ur5_grid, read_ur5_grid, Ur5Grid, Ur5Row};
