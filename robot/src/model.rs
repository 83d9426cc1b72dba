//! [`RobotModel`]: any model ferrocal knows, behind one type, and loading by name or file.

use std::path::Path;

use nalgebra::DMatrix;

use crate::error::{Result, RobotError};
use crate::geometry::Pose;
use crate::kinematics::{JointKind, JointLimits, Kinematics, Mobility};
use crate::parallel::{GantryTau3, GantryTau6, GantryTauF1, Hexapod, ParallelRobot};
use crate::params::{ParamInfo, Parameterized};
use crate::serial::{parse_urdf, SerialChain, UrdfOptions};

/// Any robot model: a serial chain or a parallel robot.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub enum RobotModel {
    /// A serial chain (URDF, DH, MDH).
    Serial(SerialChain),
    /// The nominal / modified 3-DOF Gantry-Tau.
    GantryTau3(GantryTau3),
    /// The six-link Gantry-Tau error model.
    GantryTau6(GantryTau6),
    /// The 6-DOF F1 Gantry-Tau.
    GantryTauF1(GantryTauF1),
    /// A Stewart / hexapod platform.
    Hexapod(Hexapod),
}

impl RobotModel {
    /// Loads `spec`: a preset name (`ur5`, ...), a `.urdf` file, or a `.toml` model file.
    pub fn load(spec: &str) -> Result<Self> {
        let path = Path::new(spec);
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("urdf") | Some("xml") => Ok(RobotModel::Serial(parse_urdf(path, &UrdfOptions::default())?)),
            Some("toml") => crate::parallel::file::load(path),
            _ if path.exists() => Err(RobotError::Parse {
                location: crate::error::Location { file: path.to_path_buf(), line: 1, column: 1 },
                message: "unknown model file type: use .urdf for serial robots or .toml for parallel robots".into(),
            }),
            _ => crate::presets::preset(spec),
        }
    }

    /// The model as a kinematics trait object.
    pub fn kinematics(&self) -> &dyn Kinematics {
        match self {
            RobotModel::Serial(s) => s,
            RobotModel::GantryTau3(m) => m,
            RobotModel::GantryTau6(m) => m,
            RobotModel::GantryTauF1(m) => m,
            RobotModel::Hexapod(m) => m,
        }
    }

    /// The model as a mutable kinematics trait object.
    pub fn kinematics_mut(&mut self) -> &mut dyn Kinematics {
        match self {
            RobotModel::Serial(s) => s,
            RobotModel::GantryTau3(m) => m,
            RobotModel::GantryTau6(m) => m,
            RobotModel::GantryTauF1(m) => m,
            RobotModel::Hexapod(m) => m,
        }
    }

    /// The parallel-robot view of the model (closure equations, link segments, spherical-joint
    /// angles), or `None` for a serial chain.
    pub fn parallel(&self) -> Option<&dyn ParallelRobot> {
        match self {
            RobotModel::Serial(_) => None,
            RobotModel::GantryTau3(m) => Some(m),
            RobotModel::GantryTau6(m) => Some(m),
            RobotModel::GantryTauF1(m) => Some(m),
            RobotModel::Hexapod(m) => Some(m),
        }
    }

    /// Model name.
    pub fn name(&self) -> &str {
        match self {
            RobotModel::Serial(s) => &s.name,
            RobotModel::GantryTau3(m) => &m.name,
            RobotModel::GantryTau6(m) => &m.name,
            RobotModel::GantryTauF1(m) => &m.name,
            RobotModel::Hexapod(m) => &m.name,
        }
    }
}

impl Parameterized for RobotModel {
    fn parameters(&self) -> Vec<ParamInfo> {
        self.kinematics().parameters()
    }
    fn set_parameter_values(&mut self, values: &[f64]) -> Result<()> {
        self.kinematics_mut().set_parameter_values(values)
    }
}

impl Kinematics for RobotModel {
    fn dof(&self) -> usize {
        self.kinematics().dof()
    }
    fn joint_names(&self) -> Vec<String> {
        self.kinematics().joint_names()
    }
    fn joint_kinds(&self) -> Vec<JointKind> {
        self.kinematics().joint_kinds()
    }
    fn joint_limits(&self) -> Vec<JointLimits> {
        self.kinematics().joint_limits()
    }
    fn mobility(&self) -> Mobility {
        self.kinematics().mobility()
    }
    fn forward(&self, q: &[f64]) -> Result<Pose> {
        self.kinematics().forward(q)
    }
    fn inverse(&self, t: &Pose, seed: &[f64]) -> Result<Vec<f64>> {
        self.kinematics().inverse(t, seed)
    }
    fn jacobian(&self, q: &[f64]) -> Result<DMatrix<f64>> {
        self.kinematics().jacobian(q)
    }
}
