//! The verdicts of the commands, from their library home ([`ferrocal_calib::verdict::commands`]).

pub use ferrocal_calib::verdict::commands::{import};
