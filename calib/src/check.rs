//! Checks of studies and reports: a named result that can pass, fail, be skipped (its input is
//! absent) or only be reported (there is no pass/fail criterion).
//!
//! A report counts a section as passing only when its check has [`CheckStatus::Pass`]; skipped
//! and reported sections say so and are not counted either way.

use serde::{Deserialize, Serialize};

use crate::design::kinematic::MonteCarloReport;

/// The outcome of a check.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CheckStatus {
    /// The criterion holds.
    Pass,
    /// The criterion does not hold.
    Fail,
    /// The check could not run (for example its input file is absent).
    Skipped,
    /// Numbers are shown without a pass/fail criterion.
    Reported,
}

impl CheckStatus {
    /// `pass`, `fail`, `skipped` or `reported`.
    pub fn name(self) -> &'static str {
        match self {
            CheckStatus::Pass => "pass",
            CheckStatus::Fail => "fail",
            CheckStatus::Skipped => "skipped",
            CheckStatus::Reported => "reported",
        }
    }
}

/// A named check with its outcome and a one-line detail (the numbers against the criterion).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Check {
    /// What is checked.
    pub name: String,
    /// The outcome.
    pub status: CheckStatus,
    /// The numbers and the criterion, or why the check was skipped.
    pub detail: String,
}

impl Check {
    /// A check with the given outcome.
    pub fn new(name: impl Into<String>, status: CheckStatus, detail: impl Into<String>) -> Self {
        Self { name: name.into(), status, detail: detail.into() }
    }

    /// [`CheckStatus::Pass`] when `ok`, else [`CheckStatus::Fail`].
    pub fn from_bool(name: impl Into<String>, ok: bool, detail: impl Into<String>) -> Self {
        Self::new(name, if ok { CheckStatus::Pass } else { CheckStatus::Fail }, detail)
    }

    /// A check that could not run; `detail` says why.
    pub fn skipped(name: impl Into<String>, detail: impl Into<String>) -> Self {
        Self::new(name, CheckStatus::Skipped, detail)
    }

    /// Numbers shown without a criterion.
    pub fn reported(name: impl Into<String>, detail: impl Into<String>) -> Self {
        Self::new(name, CheckStatus::Reported, detail)
    }

    /// True only for [`CheckStatus::Pass`].
    pub fn passed(&self) -> bool {
        self.status == CheckStatus::Pass
    }

    /// True only for [`CheckStatus::Fail`].
    pub fn failed(&self) -> bool {
        self.status == CheckStatus::Fail
    }

    /// True when the check has a criterion (it passed or failed).
    pub fn has_criterion(&self) -> bool {
        matches!(self.status, CheckStatus::Pass | CheckStatus::Fail)
    }

    /// All of `checks` at once: fails when any fails, passes when at least one passed and none
    /// failed, else skipped (all skipped) or reported. The details are joined with `; `.
    pub fn all(name: impl Into<String>, checks: &[Check]) -> Self {
        let status = if checks.iter().any(Check::failed) {
            CheckStatus::Fail
        } else if checks.iter().any(Check::passed) {
            CheckStatus::Pass
        } else if !checks.is_empty() && checks.iter().all(|c| c.status == CheckStatus::Skipped) {
            CheckStatus::Skipped
        } else {
            CheckStatus::Reported
        };
        let detail = checks.iter().map(|c| c.detail.as_str()).filter(|d| !d.is_empty()).collect::<Vec<_>>().join("; ");
        Self::new(name, status, detail)
    }
}

/// Counts of outcomes over a set of checks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct CheckCounts {
    /// Checks that passed.
    pub passed: usize,
    /// Checks that failed.
    pub failed: usize,
    /// Checks that were skipped.
    pub skipped: usize,
    /// Checks that only report numbers.
    pub reported: usize,
}

impl CheckCounts {
    /// Counts the outcomes of `checks`.
    pub fn of<'a>(checks: impl IntoIterator<Item = &'a Check>) -> Self {
        let mut c = Self::default();
        for k in checks {
            match k.status {
                CheckStatus::Pass => c.passed += 1,
                CheckStatus::Fail => c.failed += 1,
                CheckStatus::Skipped => c.skipped += 1,
                CheckStatus::Reported => c.reported += 1,
            }
        }
        c
    }
}

/// The largest `|simulated / predicted - 1|` of a parameter's standard deviation the Monte Carlo
/// check of a plan accepts.
pub const MONTE_CARLO_MAX_RATIO_DEVIATION: f64 = 0.2;

/// The Monte Carlo check of a plan: every parameter's simulated scatter within
/// [`MONTE_CARLO_MAX_RATIO_DEVIATION`] of the predicted standard deviation.
pub fn monte_carlo(m: &MonteCarloReport) -> Check {
    Check::from_bool(
        "simulated against predicted parameter deviations",
        m.worst_ratio_deviation <= MONTE_CARLO_MAX_RATIO_DEVIATION,
        format!("worst |sim/pred - 1| = {:.2}", m.worst_ratio_deviation),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn skipped_and_reported_do_not_pass() {
        assert!(Check::from_bool("a", true, "").passed());
        assert!(Check::from_bool("a", false, "").failed());
        for c in [Check::skipped("a", "absent"), Check::reported("a", "numbers")] {
            assert!(!c.passed() && !c.failed() && !c.has_criterion());
        }
    }

    #[test]
    fn all_fails_when_one_fails_and_passes_only_with_a_pass() {
        let p = Check::from_bool("p", true, "p ok");
        let f = Check::from_bool("f", false, "f bad");
        let s = Check::skipped("s", "absent");
        let r = Check::reported("r", "shown");
        assert_eq!(Check::all("x", &[p.clone(), f.clone(), s.clone()]).status, CheckStatus::Fail);
        assert_eq!(Check::all("x", &[p.clone(), s.clone()]).status, CheckStatus::Pass);
        assert_eq!(Check::all("x", &[s.clone(), s.clone()]).status, CheckStatus::Skipped);
        assert_eq!(Check::all("x", &[s.clone(), r.clone()]).status, CheckStatus::Reported);
        assert_eq!(Check::all("x", &[]).status, CheckStatus::Reported);
        assert_eq!(Check::all("x", &[p, f]).detail, "p ok; f bad");
        let n = CheckCounts::of(&[s, r, Check::from_bool("q", true, "")]);
        assert_eq!((n.passed, n.failed, n.skipped, n.reported), (1, 0, 1, 1));
    }
}
