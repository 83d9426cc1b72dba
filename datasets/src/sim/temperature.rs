//! The temperature history of a simulated session.
//!
//! Either an exponential warm-up `T(t) = T_end + (T_start - T_end) exp(-t / tau)` or a table of
//! `(t_s, temp_c)` points interpolated linearly (held constant outside the table).

use serde::{Deserialize, Serialize};

/// Temperature over time (TOML table `[environment]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Environment {
    /// Temperature at the start.
    #[serde(default = "default_temp")]
    pub temp_start_c: f64,
    /// Temperature approached during the session (equal to the start: constant).
    #[serde(default = "default_temp")]
    pub temp_end_c: f64,
    /// Time constant of the warm-up.
    #[serde(default = "default_tau")]
    pub warmup_tau_s: f64,
    /// Optional explicit history `[[t_s, temp_c], ...]`; overrides the warm-up when given.
    #[serde(default)]
    pub temperature_table: Vec<[f64; 2]>,
    /// Payload at the tool for every pose (a plan may override per pose).
    #[serde(default)]
    pub payload_kg: f64,
}

fn default_temp() -> f64 {
    20.0
}
fn default_tau() -> f64 {
    1800.0
}

impl Default for Environment {
    fn default() -> Self {
        Self {
            temp_start_c: 20.0,
            temp_end_c: 20.0,
            warmup_tau_s: 1800.0,
            temperature_table: Vec::new(),
            payload_kg: 0.0,
        }
    }
}

impl Environment {
    /// Temperature at time `t_s`.
    pub fn temperature_c(&self, t_s: f64) -> f64 {
        let tab = &self.temperature_table;
        if !tab.is_empty() {
            if t_s <= tab[0][0] {
                return tab[0][1];
            }
            for w in tab.windows(2) {
                if t_s <= w[1][0] {
                    let f = (t_s - w[0][0]) / (w[1][0] - w[0][0]).max(1e-12);
                    return w[0][1] + f * (w[1][1] - w[0][1]);
                }
            }
            return tab[tab.len() - 1][1];
        }
        if self.warmup_tau_s <= 0.0 {
            return self.temp_end_c;
        }
        self.temp_end_c + (self.temp_start_c - self.temp_end_c) * (-t_s / self.warmup_tau_s).exp()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn warmup_and_table() {
        let e = Environment { temp_start_c: 20.0, temp_end_c: 24.0, warmup_tau_s: 100.0, ..Default::default() };
        assert!((e.temperature_c(0.0) - 20.0).abs() < 1e-12);
        assert!((e.temperature_c(100.0) - (24.0 - 4.0 / std::f64::consts::E)).abs() < 1e-12);
        let t = Environment { temperature_table: vec![[0.0, 20.0], [10.0, 22.0]], ..Default::default() };
        assert!((t.temperature_c(5.0) - 21.0).abs() < 1e-12);
        assert_eq!(t.temperature_c(50.0), 22.0);
    }
}
