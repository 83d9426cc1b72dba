//! `ferrocal doctor`: are the external libraries built and answering?

use std::process::ExitCode;

use anyhow::Result;
use ferrocal_calib::verdict::{Check, Verdict};
use ferrocal_report::verdict::VerdictSettings;

/// Probes every external library, prints one line each and ends with the verdict: `fail` (exit
/// 2) when one does not answer.
pub fn run(vs: &VerdictSettings) -> Result<ExitCode> {
    let mut checks = Vec::new();
    for b in ferrocal_vision::backends::probe_backends() {
        println!("{:<14} {:<4} {}  [{}]", b.name, if b.ok { "ok" } else { "FAIL" }, b.detail, b.role);
        let label = format!("{} answers (1 yes, 0 no)", b.name);
        checks.push(Check::at_least(&format!("doctor.{}", b.name), &label, "", f64::from(u8::from(b.ok)), 1.0, 1.0));
    }
    let v = Verdict::with_next(checks, |c| {
        match c {
        None => "every library answers: run ferrocal demo".into(),
        Some(c) => format!(
            "{} does not answer: run scripts/setup.sh (it installs the system libraries) and rebuild, or read its line above",
            c.name.trim_start_matches("doctor.")
        ),
    }
    });
    Ok(vs.conclude_with(&v, ExitCode::SUCCESS, 2))
}
