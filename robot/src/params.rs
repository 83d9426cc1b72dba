//! Named, unit-carrying parameter vectors.
//!
//! Every model exposes its geometric (and, where present, inertial) parameters as a flat vector
//! with a name and a unit per entry. Identification works on that vector only: it reads the
//! current values, proposes new ones, and asks the model to take them; it never reaches into a
//! model's fields.

use serde::{Deserialize, Serialize};

use crate::error::{Result, RobotError};

/// The physical unit of a parameter (values are always stored in SI).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Unit {
    /// Metres.
    Metre,
    /// Radians.
    Radian,
    /// A pure number (direction components, scale factors).
    Dimensionless,
    /// Kilograms.
    Kilogram,
}

impl Unit {
    /// Short symbol used in names and tables.
    pub fn symbol(self) -> &'static str {
        match self {
            Unit::Metre => "m",
            Unit::Radian => "rad",
            Unit::Dimensionless => "1",
            Unit::Kilogram => "kg",
        }
    }

    /// A typical magnitude of a small error in this unit, used to scale identification problems
    /// (1 mm, 1 mrad, 1e-3, 0.1 kg).
    pub fn typical_scale(self) -> f64 {
        match self {
            Unit::Metre => 1e-3,
            Unit::Radian => 1e-3,
            Unit::Dimensionless => 1e-3,
            Unit::Kilogram => 0.1,
        }
    }
}

/// One entry of a model's parameter vector.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParamInfo {
    /// Unique, stable name, e.g. `joint2.a_m` or `arm1.v_x`.
    pub name: String,
    /// Unit of `value`.
    pub unit: Unit,
    /// Current value in SI.
    pub value: f64,
}

impl ParamInfo {
    /// Builds an entry.
    pub fn new(name: impl Into<String>, unit: Unit, value: f64) -> Self {
        Self { name: name.into(), unit, value }
    }
}

/// A model with a named parameter vector.
pub trait Parameterized {
    /// Names, units and current values of every parameter, in a fixed order.
    fn parameters(&self) -> Vec<ParamInfo>;

    /// Replaces every parameter value (same order as [`Parameterized::parameters`]).
    fn set_parameter_values(&mut self, values: &[f64]) -> Result<()>;

    /// Current values only.
    fn parameter_values(&self) -> Vec<f64> {
        self.parameters().into_iter().map(|p| p.value).collect()
    }

    /// Number of parameters.
    fn n_parameters(&self) -> usize {
        self.parameters().len()
    }

    /// Index of the parameter called `name`.
    fn parameter_index(&self, name: &str) -> Option<usize> {
        self.parameters().iter().position(|p| p.name == name)
    }

    /// A copy with `delta` added to the parameter vector.
    fn perturbed(&self, delta: &[f64]) -> Result<Self>
    where
        Self: Sized + Clone,
    {
        let mut values = self.parameter_values();
        if delta.len() != values.len() {
            return Err(RobotError::ParameterCount { expected: values.len(), got: delta.len() });
        }
        for (v, d) in values.iter_mut().zip(delta) {
            *v += d;
        }
        let mut out = self.clone();
        out.set_parameter_values(&values)?;
        Ok(out)
    }
}

/// Checks that a slice has the expected length and finite entries.
pub(crate) fn check_values(values: &[f64], expected: usize, names: &[ParamInfo]) -> Result<()> {
    if values.len() != expected {
        return Err(RobotError::ParameterCount { expected, got: values.len() });
    }
    for (v, p) in values.iter().zip(names) {
        if !v.is_finite() {
            return Err(RobotError::BadParameter { name: p.name.clone(), value: *v, reason: "not finite".into() });
        }
    }
    Ok(())
}
