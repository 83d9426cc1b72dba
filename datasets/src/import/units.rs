//! Unit suffixes of table columns and their conversion to SI.

use ferrocal_robot::JointKind;

/// Unit of a joint column (`q<i>_rad`, `q<i>_deg`, `q<i>_m`, `q<i>_mm`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum JointUnit {
    /// Radians (revolute joint).
    Rad,
    /// Degrees (revolute joint).
    Deg,
    /// Metres (prismatic joint).
    M,
    /// Millimetres (prismatic joint).
    Mm,
}

impl JointUnit {
    /// Parses a column suffix (`rad`, `deg`, `m`, `mm`; case-sensitive).
    pub fn from_suffix(s: &str) -> Option<JointUnit> {
        match s {
            "rad" => Some(JointUnit::Rad),
            "deg" => Some(JointUnit::Deg),
            "m" => Some(JointUnit::M),
            "mm" => Some(JointUnit::Mm),
            _ => None,
        }
    }

    /// The column suffix.
    pub fn suffix(self) -> &'static str {
        match self {
            JointUnit::Rad => "rad",
            JointUnit::Deg => "deg",
            JointUnit::M => "m",
            JointUnit::Mm => "mm",
        }
    }

    /// The joint kind the unit implies: angles for revolute joints, lengths for prismatic ones.
    pub fn kind(self) -> JointKind {
        match self {
            JointUnit::Rad | JointUnit::Deg => JointKind::Revolute,
            JointUnit::M | JointUnit::Mm => JointKind::Prismatic,
        }
    }

    /// The SI unit of a joint kind (`rad` or `m`).
    pub fn si(kind: JointKind) -> JointUnit {
        match kind {
            JointKind::Revolute => JointUnit::Rad,
            JointKind::Prismatic => JointUnit::M,
        }
    }

    /// Converts a value in this unit to SI (rad or m).
    pub fn to_si(self, v: f64) -> f64 {
        match self {
            JointUnit::Rad | JointUnit::M => v,
            JointUnit::Deg => v.to_radians(),
            JointUnit::Mm => v / 1000.0,
        }
    }

    /// Converts an SI value (rad or m) to this unit.
    pub fn from_si(self, v: f64) -> f64 {
        match self {
            JointUnit::Rad | JointUnit::M => v,
            JointUnit::Deg => v.to_degrees(),
            JointUnit::Mm => v * 1000.0,
        }
    }
}

/// Unit of a length column (`_m` or `_mm`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum LengthUnit {
    /// Metres.
    #[default]
    M,
    /// Millimetres.
    Mm,
}

impl LengthUnit {
    /// Parses a column suffix (`m`, `mm`; case-sensitive).
    pub fn from_suffix(s: &str) -> Option<LengthUnit> {
        match s {
            "m" => Some(LengthUnit::M),
            "mm" => Some(LengthUnit::Mm),
            _ => None,
        }
    }

    /// The column suffix.
    pub fn suffix(self) -> &'static str {
        match self {
            LengthUnit::M => "m",
            LengthUnit::Mm => "mm",
        }
    }

    /// Converts a value in this unit to metres.
    pub fn to_m(self, v: f64) -> f64 {
        match self {
            LengthUnit::M => v,
            LengthUnit::Mm => v / 1000.0,
        }
    }

    /// Converts metres to this unit.
    pub fn from_m(self, v_m: f64) -> f64 {
        match self {
            LengthUnit::M => v_m,
            LengthUnit::Mm => v_m * 1000.0,
        }
    }
}
