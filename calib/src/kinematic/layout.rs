//! The candidate vector of the kinematic calibration: its blocks, names, units and scales.

use super::*;

/// Names, units and blocks of the candidate vector.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct StateLayout {
    /// Device frame increment `f`.
    pub frame: Range<usize>,
    /// Tool increment `t` (3 or 6).
    pub tool: Range<usize>,
    /// Joint offsets.
    pub offsets: Range<usize>,
    /// Selected model parameters.
    pub model: Range<usize>,
    /// Index in the model's parameter vector of each selected model parameter.
    pub model_index: Vec<usize>,
    /// Effect parameters, one range per effect of the options.
    pub effects: Vec<Range<usize>>,
    /// Typical size of a change of every entry (for scaling).
    pub scales: Vec<f64>,
    /// Name of every entry.
    pub names: Vec<String>,
    /// Unit of every entry.
    pub units: Vec<Unit>,
}

impl StateLayout {
    pub(super) fn new(model: &RobotModel, tool_dim: usize, selection: &ModelParams, effects: &[EffectSpec]) -> Self {
        let mut names = Vec::new();
        let mut units = Vec::new();
        for (n, u) in [
            ("frame.x_m", Unit::Metre),
            ("frame.y_m", Unit::Metre),
            ("frame.z_m", Unit::Metre),
            ("frame.rx_rad", Unit::Radian),
            ("frame.ry_rad", Unit::Radian),
            ("frame.rz_rad", Unit::Radian),
        ] {
            names.push(n.to_string());
            units.push(u);
        }
        for (k, n) in ["tool.x_m", "tool.y_m", "tool.z_m", "tool.rx_rad", "tool.ry_rad", "tool.rz_rad"]
            .iter()
            .enumerate()
            .take(tool_dim)
        {
            names.push(format!("target_{n}"));
            units.push(if k < 3 { Unit::Metre } else { Unit::Radian });
        }
        let n_j = model.dof();
        for (i, k) in model.joint_kinds().iter().enumerate() {
            match k {
                JointKind::Revolute => {
                    names.push(format!("offset.q{}_rad", i + 1));
                    units.push(Unit::Radian);
                }
                JointKind::Prismatic => {
                    names.push(format!("offset.q{}_m", i + 1));
                    units.push(Unit::Metre);
                }
            }
        }
        let params = model.parameters();
        let serial = matches!(model, RobotModel::Serial(_));
        let model_index: Vec<usize> = params
            .iter()
            .enumerate()
            .filter(|(_, p)| {
                let frame_like = serial && (p.name.starts_with("base.") || p.name.starts_with("tool."));
                if frame_like || p.unit == Unit::Kilogram {
                    return false;
                }
                match selection {
                    ModelParams::Default => {
                        !serial
                            || p.name.contains(".corr_")
                            || p.name.ends_with(".coupling")
                            || (p.name.starts_with("tip") && p.unit == Unit::Metre)
                    }
                    ModelParams::All => true,
                    ModelParams::None => false,
                    ModelParams::Prefixes { prefixes } => prefixes.iter().any(|x| p.name.starts_with(x.as_str())),
                }
            })
            .map(|(i, _)| i)
            .collect();
        for &i in &model_index {
            names.push(params[i].name.clone());
            units.push(params[i].unit);
        }
        let frame = 0..6;
        let tool = 6..6 + tool_dim;
        let offsets = tool.end..tool.end + n_j;
        let model_r = offsets.end..offsets.end + model_index.len();
        let mut scales: Vec<f64> = units.iter().map(|u| u.typical_scale()).collect();
        let kinds = model.joint_kinds();
        let mut effect_ranges = Vec::new();
        for e in effects {
            let start = names.len();
            for ((n, u), sc) in e.parameters(&kinds).into_iter().zip(e.scales()) {
                names.push(n);
                units.push(u);
                scales.push(sc);
            }
            effect_ranges.push(start..names.len());
        }
        Self { frame, tool, offsets, model: model_r, model_index, effects: effect_ranges, scales, names, units }
    }

    /// Number of candidate parameters.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Whether there are no candidates.
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// Start values of every candidate: zero increments of frames, tool, offsets and effects,
    /// and the model's own values of its parameters.
    pub fn start_values(&self, model: &RobotModel) -> Vec<f64> {
        let params = model.parameters();
        let mut start = vec![0.0; self.len()];
        for (k, &pi) in self.model_index.iter().enumerate() {
            start[self.model.start + k] = params[pi].value;
        }
        start
    }
}
