//! The extension point for robot effects: one trait for what an effect does (its regressors,
//! validity, words and plausibility), one registry of the kinds a list or a JSON file may name.
//!
//! **Adding an effect** touches one file and one line (recipe in `docs/architecture.md`): a type
//! implementing [`Effect`] (how it changes the joint values, the lengths or the pose of a row,
//! its parameters, its words) and [`EffectKind`] (how a `--effects` list item and a JSON object
//! spell it, which candidates a recording offers `diagnose`), added to `library_kinds` inside
//! this crate or with [`register_effect`] from outside it. The effect then travels as
//! [`EffectSpec::Custom`] through everything an effect reaches: `calibrate --effects` (the list
//! and JSON files), the calibration file, the kinematic fit, `correct`, and `diagnose`'s
//! screening, cross-validation, plausibility and words. Its truth is simulated through the same
//! trait: a [`CalibratedModel`](crate::kinematic::CalibratedModel) carrying the effect with chosen
//! values predicts what the robot measures.
//!
//! The built-in effects (`joint_compliance` ... `axis_misalignment`) are the variants of
//! [`EffectSpec`] before `Custom`; their names are reserved.

use std::collections::BTreeMap;
use std::fmt;
use std::sync::{Arc, RwLock};

use ferrocal_robot::{JointKind, RobotModel, Unit};
use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};

use crate::effects::EffectSpec;
use crate::error::{CalibError, Result};
use crate::measurement::PoseMeasurement;

/// What an effect does to a row's prediction, and how a report speaks of it. The corrections are
/// those of the built-in effects (see `effects`): joint values `q -> q + dq`, lengths scaled by a
/// factor, and a rigid correction of the predicted pose in the model's base frame; each is a
/// function of the row and the effect's parameters `theta` (in the order of
/// [`Effect::parameters`]). `diagnose` linearises them about `theta = 0` (each parameter at its
/// [`Effect::scales`] size), so they should be smooth and zero at zero.
pub trait Effect: fmt::Debug + Send + Sync {
    /// Its name: the spelling of `--effects` lists and of JSON's `"effect"` field.
    fn name(&self) -> &'static str;
    /// Its settings as the JSON fields beside `"effect"` (read back by [`EffectKind::read_json`]).
    fn settings(&self) -> serde_json::Map<String, serde_json::Value>;
    /// Its settings as the list fields after the name, `name:field:field` (read back by
    /// [`EffectKind::parse`]).
    fn list_fields(&self) -> Vec<String>;
    /// The joint it belongs to (1-based), if any.
    fn joint(&self) -> Option<usize> {
        None
    }
    /// The joints a report names for it.
    fn joints_reported(&self) -> Vec<usize> {
        self.joint().into_iter().collect()
    }
    /// Names and units of its parameters (`kinds`: the model's joints).
    fn parameters(&self, kinds: &[JointKind]) -> Vec<(String, Unit)>;
    /// The typical size of each parameter (the fit's scaling, the screen's step).
    fn scales(&self) -> Vec<f64>;
    /// The input a row lacks for it (e.g. "temperature (temp_c)"), if any.
    fn missing_input(&self, _row: &PoseMeasurement) -> Option<&'static str> {
        None
    }
    /// Checks it against the model.
    fn validate(&self, _model: &RobotModel) -> Result<()> {
        Ok(())
    }
    /// Adds its joint corrections for `row` to `dq`.
    fn add_joint_delta(
        &self,
        _model: &RobotModel,
        _row: &PoseMeasurement,
        _theta: &[f64],
        _dq: &mut [f64],
    ) -> Result<()> {
        Ok(())
    }
    /// Whether it corrects the predicted pose ([`Effect::pose_correction`]).
    fn corrects_pose(&self) -> bool {
        false
    }
    /// The rigid correction of the predicted pose (model's base frame) at effective joints `q`.
    fn pose_correction(
        &self,
        _model: &RobotModel,
        _row: &PoseMeasurement,
        _q: &[f64],
        _theta: &[f64],
    ) -> Result<Isometry3<f64>> {
        Ok(Isometry3::identity())
    }
    /// The factor by which it scales lengths for `row`.
    fn length_scale(&self, _row: &PoseMeasurement, _theta: &[f64]) -> f64 {
        1.0
    }
    /// The input the effect shows against, in words (`joint_names`: the model's joints).
    fn telling_input(&self, _joint_names: &[String]) -> String {
        match self.joint() {
            Some(j) => format!("q{j}"),
            None => "row".into(),
        }
    }
    /// What the fitted effect means, in words (before the held-out figures a finding adds).
    fn statement(&self, theta: &[f64]) -> String {
        let values: Vec<String> =
            self.parameters(&[]).iter().zip(theta).map(|((n, _), v)| format!("{n} = {v:.3e}")).collect();
        format!("{}: {}", self.name(), values.join(", "))
    }
    /// How the fitted values compare with what machines do.
    fn plausibility(&self, _theta: &[f64]) -> Plausibility {
        Plausibility::default()
    }
}

/// A fitted effect's sign and size against what machines do.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Plausibility {
    /// No machine does this: `diagnose` vetoes the candidate, with this reason.
    pub impossible: Option<String>,
    /// Unusual (claimed only on strong held-out evidence), with this reason.
    pub unusual: Option<String>,
}

/// One kind of effect in the registry: how it is spelled and which candidates it offers.
pub trait EffectKind: Send + Sync {
    /// The name lists and JSON use (not one of the built-in effects' names).
    fn name(&self) -> &'static str;
    /// The effect of a list item `name:fields...` (`fields` after the name).
    fn parse(&self, fields: &[&str]) -> std::result::Result<Arc<dyn Effect>, String>;
    /// The effect of a JSON object (with its `"effect"` field).
    fn read_json(&self, value: &serde_json::Value) -> std::result::Result<Arc<dyn Effect>, String>;
    /// The candidates `diagnose` tests on a recording (none: the kind is only fitted when named).
    fn candidates(&self, _model: &RobotModel, _rows: &[&PoseMeasurement]) -> Vec<Arc<dyn Effect>> {
        Vec::new()
    }
}

/// The built-in effects' names (the variants of [`EffectSpec`]), in the order errors list them.
pub const BUILTIN_EFFECTS: [&str; 9] = [
    "joint_compliance",
    "backlash",
    "joint_scale_error",
    "periodic_joint_error",
    "thermal_expansion",
    "time_drift",
    "link_compliance",
    "coupled_transmission",
    "axis_misalignment",
];

// A new effect's file is a module of this one (`calib/src/effect_registry/<name>.rs`), declared
// here beside its line in `library_kinds`.

/// The registry: the effect kinds of this library beyond the built-in ones, one line each.
fn library_kinds() -> Vec<Arc<dyn EffectKind>> {
    Vec::new()
}

static REGISTERED: RwLock<Vec<Arc<dyn EffectKind>>> = RwLock::new(Vec::new());

/// Adds an effect kind from outside the library, for the whole process (a later registration
/// of the same name replaces the earlier one): from then on lists and JSON may name it and
/// `diagnose` tests its candidates. A built-in effect's name is refused.
pub fn register_effect(kind: Arc<dyn EffectKind>) -> Result<()> {
    let name = kind.name();
    if BUILTIN_EFFECTS.contains(&name) || library_kinds().iter().any(|k| k.name() == name) {
        return Err(CalibError::Data(format!("effect '{name}' is already defined by the library")));
    }
    let mut list = REGISTERED.write().map_err(|_| CalibError::Data("the effect registry is poisoned".into()))?;
    list.retain(|k| k.name() != name);
    list.push(kind);
    Ok(())
}

/// Every effect kind beyond the built-in ones: the library's, then the registered ones.
pub fn effect_kinds() -> Vec<Arc<dyn EffectKind>> {
    let mut out = library_kinds();
    if let Ok(list) = REGISTERED.read() {
        out.extend(list.iter().cloned());
    }
    out
}

/// The kind named `name` beyond the built-in ones.
pub fn effect_kind(name: &str) -> Option<Arc<dyn EffectKind>> {
    effect_kinds().into_iter().find(|k| k.name() == name)
}

/// An effect of the registry as [`EffectSpec::Custom`] carries it: compared, written and read by
/// its name and settings.
#[derive(Clone)]
pub struct CustomEffect(pub Arc<dyn Effect>);

impl CustomEffect {
    /// Wraps an effect.
    pub fn new(effect: impl Effect + 'static) -> Self {
        Self(Arc::new(effect))
    }

    /// The `--effects` list item that names it (`name:field:...`).
    pub fn list_item(&self) -> String {
        std::iter::once(self.0.name().to_string()).chain(self.0.list_fields()).collect::<Vec<_>>().join(":")
    }

    /// Its parameters keyed by their names (the report's parameter map).
    pub fn parameter_map(&self, theta: &[f64], kinds: &[JointKind]) -> BTreeMap<String, f64> {
        self.0.parameters(kinds).into_iter().zip(theta).map(|((n, _), v)| (n, *v)).collect()
    }

    fn json(&self) -> serde_json::Map<String, serde_json::Value> {
        let mut m = serde_json::Map::new();
        m.insert("effect".into(), self.0.name().into());
        m.extend(self.0.settings());
        m
    }
}

impl std::ops::Deref for CustomEffect {
    type Target = dyn Effect;
    fn deref(&self) -> &Self::Target {
        &*self.0
    }
}

impl fmt::Debug for CustomEffect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.list_item())
    }
}

impl PartialEq for CustomEffect {
    fn eq(&self, other: &Self) -> bool {
        self.json() == other.json()
    }
}

impl Serialize for CustomEffect {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        self.json().serialize(s)
    }
}

impl<'de> Deserialize<'de> for CustomEffect {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        use serde::de::Error;
        let value = serde_json::Value::deserialize(d)?;
        let name = value.get("effect").and_then(|v| v.as_str()).ok_or_else(|| D::Error::custom("no 'effect' name"))?;
        let kind = effect_kind(name).ok_or_else(|| D::Error::custom(unknown_effect(name)))?;
        kind.read_json(&value).map(CustomEffect).map_err(D::Error::custom)
    }
}

/// The error for an effect name nobody defines, listing those that exist.
pub fn unknown_effect(name: &str) -> String {
    let mut names: Vec<&str> = BUILTIN_EFFECTS.to_vec();
    let kinds = effect_kinds();
    names.extend(kinds.iter().map(|k| k.name()));
    format!("unknown effect '{name}' ({})", names.join(", "))
}

impl From<CustomEffect> for EffectSpec {
    fn from(e: CustomEffect) -> Self {
        EffectSpec::Custom(e)
    }
}
