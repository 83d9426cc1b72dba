//! `ferrocal doctor`: are the external libraries built and answering?

use ferrocal_report::say;
use std::process::ExitCode;

use anyhow::Result;
use ferrocal_report::verdict::VerdictSettings;

/// Probes every external library, prints one line each and ends with the verdict: `fail` (exit
/// 2) when one does not answer.
pub fn run(vs: &VerdictSettings) -> Result<ExitCode> {
    let mut libraries = Vec::new();
    for b in ferrocal_vision::backends::probe_backends() {
        say!("{:<14} {:<4} {}  [{}]", b.name, if b.ok { "ok" } else { "FAIL" }, b.detail, b.role);
        libraries.push((b.name, b.ok));
    }
    Ok(vs.conclude_with(&ferrocal_calib::verdict::commands::doctor(&libraries), ExitCode::SUCCESS, 2))
}
