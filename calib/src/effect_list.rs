//! Effects named by a user: `calibrate --effects <diagnose json | calibration json | list>`.
//!
//! A list is comma-separated; each item is the effect's name (`shared/spec/diagnose.md`) and its
//! settings after colons:
//!
//! | item | effect |
//! | --- | --- |
//! | `joint_compliance:J` | joint `J` (1-based) deflects with its load torque |
//! | `backlash:J` | joint `J` depends on its approach direction (`dirJ` column) |
//! | `joint_scale_error:J` | joint `J`'s reading is off by a factor |
//! | `periodic_joint_error:J:P` | joint `J`'s error repeats every `P`, with a unit: `deg`, `rad`, `mm`, `m` |
//! | `thermal_expansion[:T]` | lengths change with `temp_c`, geometry at `T` degrees Celsius (default 20) |
//! | `time_drift` | lengths change with `t_s` |
//! | `link_compliance:L` | link `L` bends under the load it carries |
//! | `coupled_transmission:J:K` | joint `J`'s error is proportional to joint `K`'s angle |
//! | `axis_misalignment:J` | revolute joint `J`'s axis wobbles with its angle (a tilt whose direction turns with the joint) |
//!
//! Effects of the registry (`effect_registry`) are spelled as their kind parses them.
//!
//! A JSON file may be a `ferrocal diagnose` report (its findings' `spec`), a calibration file
//! (its `effects`), or an array of effect objects as those carry them.

use std::path::Path;

use crate::effect_registry::{effect_kind, unknown_effect, CustomEffect, BUILTIN_EFFECTS};
use crate::effects::EffectSpec;
use crate::error::{CalibError, Result};

/// Parses a comma-separated effect list (see the module documentation).
pub fn parse_effect_list(text: &str) -> Result<Vec<EffectSpec>> {
    let mut out = Vec::new();
    for (k, item) in text.split(',').map(str::trim).enumerate() {
        if item.is_empty() {
            continue;
        }
        out.push(parse_item(item).map_err(|e| CalibError::Data(format!("effect {} ('{item}'): {e}", k + 1)))?);
    }
    if out.is_empty() {
        return Err(CalibError::Data("the effect list names no effect".into()));
    }
    Ok(out)
}

fn parse_item(item: &str) -> std::result::Result<EffectSpec, String> {
    let parts: Vec<&str> = item.split(':').map(str::trim).collect();
    let index = |k: usize, what: &str| -> std::result::Result<usize, String> {
        let s = parts.get(k).ok_or_else(|| format!("the {what} number is missing (e.g. {}:2)", parts[0]))?;
        match s.parse::<usize>() {
            Ok(v) if v >= 1 => Ok(v),
            _ => Err(format!("'{s}' is not a {what} number (1-based)")),
        }
    };
    let arity = |n: usize| -> std::result::Result<(), String> {
        if parts.len() > n {
            Err(format!("too many fields: '{}' is not expected", parts[n..].join(":")))
        } else {
            Ok(())
        }
    };
    let spec = match parts[0] {
        "joint_compliance" => EffectSpec::JointCompliance { joint: index(1, "joint")? },
        "backlash" => EffectSpec::Backlash { joint: index(1, "joint")? },
        "joint_scale_error" => EffectSpec::JointScaleError { joint: index(1, "joint")? },
        "link_compliance" => EffectSpec::LinkCompliance { link: index(1, "link")? },
        "axis_misalignment" => EffectSpec::AxisMisalignment { joint: index(1, "joint")? },
        "coupled_transmission" => {
            let (joint, driver) = (index(1, "joint")?, index(2, "driving joint")?);
            if joint == driver {
                return Err(format!("joint {joint} cannot drive itself (that is joint_scale_error:{joint})"));
            }
            EffectSpec::CoupledTransmission { joint, driver }
        }
        "periodic_joint_error" => {
            let joint = index(1, "joint")?;
            let p = parts.get(2).ok_or("the period is missing (e.g. periodic_joint_error:2:180deg)")?;
            EffectSpec::PeriodicJointError { joint, period_si: parse_period(p)? }
        }
        "thermal_expansion" => {
            let reference_temp_c = match parts.get(1) {
                None => 20.0,
                Some(t) => {
                    let t = t.strip_suffix('C').or_else(|| t.strip_suffix("degC")).unwrap_or(t);
                    t.parse::<f64>()
                        .ok()
                        .filter(|v| v.is_finite())
                        .ok_or_else(|| format!("'{t}' is not a reference temperature in degrees Celsius"))?
                }
            };
            EffectSpec::ThermalExpansion { reference_temp_c }
        }
        "time_drift" => {
            arity(1)?;
            EffectSpec::TimeDrift
        }
        other => {
            let kind = effect_kind(other).ok_or_else(|| unknown_effect(other))?;
            return Ok(EffectSpec::Custom(CustomEffect(kind.parse(&parts[1..])?)));
        }
    };
    let expected = match spec {
        EffectSpec::PeriodicJointError { .. } | EffectSpec::CoupledTransmission { .. } => 3,
        EffectSpec::TimeDrift => 1,
        _ => 2,
    };
    arity(expected)?;
    Ok(spec)
}

/// A period with its unit, in SI (rad or m).
fn parse_period(text: &str) -> std::result::Result<f64, String> {
    let units = [("deg", std::f64::consts::PI / 180.0), ("rad", 1.0), ("mm", 1e-3), ("m", 1.0)];
    for (suffix, factor) in units {
        if let Some(v) = text.strip_suffix(suffix) {
            let v: f64 = v.trim().parse().map_err(|_| format!("'{text}' is not a period"))?;
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("the period must be positive, got '{text}'"));
            }
            return Ok(v * factor);
        }
    }
    Err(format!("the period '{text}' needs a unit: deg, rad, mm or m"))
}

/// The effects in a JSON document: a diagnose report (`findings[].spec`), a calibration file
/// (`effects[].spec`) or an array of effect objects. `source` names the document in errors.
pub fn effects_from_json(value: &serde_json::Value, source: &str) -> Result<Vec<EffectSpec>> {
    let bad = |e: serde_json::Error, what: &str| CalibError::Data(format!("{source}: {what}: {e}"));
    let specs: Vec<serde_json::Value> = if let Some(findings) = value.get("findings").and_then(|f| f.as_array()) {
        findings
            .iter()
            .enumerate()
            .map(|(k, f)| {
                f.get("spec").cloned().ok_or_else(|| {
                    CalibError::Data(format!(
                        "{source}: finding {} has no 'spec' (a report of the camera or force diagnosis has no robot effects)",
                        k + 1
                    ))
                })
            })
            .collect::<Result<_>>()?
    } else if let Some(effects) = value.get("effects").and_then(|f| f.as_array()) {
        effects.iter().map(|e| e.get("spec").cloned().unwrap_or_else(|| e.clone())).collect()
    } else if let Some(list) = value.as_array() {
        list.clone()
    } else {
        return Err(CalibError::Data(format!(
            "{source}: neither a diagnose report (findings), a calibration file (effects) nor a list of effects"
        )));
    };
    specs
        .into_iter()
        .enumerate()
        .map(|(k, v)| {
            // An effect nobody defines is named as such (serde would only say no variant matched).
            if let Some(name) = v.get("effect").and_then(|n| n.as_str()) {
                if !BUILTIN_EFFECTS.contains(&name) && effect_kind(name).is_none() {
                    return Err(CalibError::Data(format!("{source}: effect {}: {}", k + 1, unknown_effect(name))));
                }
            }
            serde_json::from_value(v).map_err(|e| bad(e, &format!("effect {}", k + 1)))
        })
        .collect()
}

/// `--effects` as given: a path to a JSON file when one exists there, else a list.
pub fn effects_from_argument(arg: &str) -> Result<Vec<EffectSpec>> {
    let path = Path::new(arg);
    if path.is_file() {
        let text = std::fs::read_to_string(path)
            .map_err(|e| CalibError::Data(format!("{}: cannot read: {e}", path.display())))?;
        let value: serde_json::Value = serde_json::from_str(&text).map_err(|e| {
            CalibError::Data(format!("{}: line {}, column {}: not JSON: {e}", path.display(), e.line(), e.column()))
        })?;
        return effects_from_json(&value, &path.display().to_string());
    }
    if arg.ends_with(".json") {
        return Err(CalibError::Data(format!("{arg}: no such file")));
    }
    parse_effect_list(arg)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lists_parse_with_units_and_defaults() {
        let e = parse_effect_list(
            "joint_compliance:2, periodic_joint_error:3:180deg,backlash:1,thermal_expansion,thermal_expansion:21.5C,time_drift,link_compliance:2,periodic_joint_error:1:5mm,coupled_transmission:5:4,axis_misalignment:3",
        )
        .unwrap();
        assert_eq!(e[0], EffectSpec::JointCompliance { joint: 2 });
        assert_eq!(e[1], EffectSpec::PeriodicJointError { joint: 3, period_si: std::f64::consts::PI });
        assert_eq!(e[2], EffectSpec::Backlash { joint: 1 });
        assert_eq!(e[3], EffectSpec::ThermalExpansion { reference_temp_c: 20.0 });
        assert_eq!(e[4], EffectSpec::ThermalExpansion { reference_temp_c: 21.5 });
        assert_eq!(e[5], EffectSpec::TimeDrift);
        assert_eq!(e[6], EffectSpec::LinkCompliance { link: 2 });
        assert_eq!(e[7], EffectSpec::PeriodicJointError { joint: 1, period_si: 5e-3 });
        assert_eq!(e[8], EffectSpec::CoupledTransmission { joint: 5, driver: 4 });
        assert_eq!(e[9], EffectSpec::AxisMisalignment { joint: 3 });
    }

    #[test]
    fn bad_items_are_named() {
        for (text, needle) in [
            ("backlash", "joint number is missing"),
            ("backlash:0", "not a joint number"),
            ("backlash:2:3", "too many fields"),
            ("periodic_joint_error:2:180", "needs a unit"),
            ("periodic_joint_error:2:-3deg", "positive"),
            ("gravity:2", "unknown effect 'gravity'"),
            ("", "names no effect"),
            ("time_drift:3", "too many fields"),
            ("coupled_transmission:2", "driving joint number is missing"),
            ("coupled_transmission:2:2", "cannot drive itself"),
            ("coupled_transmission:2:3:1", "too many fields"),
            ("axis_misalignment", "joint number is missing"),
            ("axis_misalignment:2:1", "too many fields"),
        ] {
            let e = parse_effect_list(text).unwrap_err().to_string();
            assert!(e.contains(needle), "{text}: {e}");
        }
    }

    #[test]
    fn json_documents_give_their_effects() {
        let report = serde_json::json!({"findings": [
            {"effect": "joint_compliance", "spec": {"effect": "joint_compliance", "joint": 2}},
            {"effect": "periodic_joint_error", "spec": {"effect": "periodic_joint_error", "joint": 1, "period_si": 0.5}}
        ]});
        let e = effects_from_json(&report, "diag.json").unwrap();
        assert_eq!(
            e,
            vec![EffectSpec::JointCompliance { joint: 2 }, EffectSpec::PeriodicJointError { joint: 1, period_si: 0.5 }]
        );
        let cal = serde_json::json!({"effects": [{"spec": {"effect": "backlash", "joint": 3}, "values": [1e-4]}]});
        assert_eq!(effects_from_json(&cal, "cal.json").unwrap(), vec![EffectSpec::Backlash { joint: 3 }]);
        let unknown = serde_json::json!([{"effect": "gravity", "joint": 2}]);
        assert!(effects_from_json(&unknown, "e.json").unwrap_err().to_string().contains("unknown effect 'gravity'"));
        let camera = serde_json::json!({"findings": [{"effect": "lens_distortion"}]});
        assert!(effects_from_json(&camera, "cam.json").unwrap_err().to_string().contains("no 'spec'"));
    }
}
