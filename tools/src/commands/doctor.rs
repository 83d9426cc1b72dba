//! `ferrocal doctor`: are the external libraries built and answering?

use std::process::ExitCode;

use anyhow::Result;

pub fn run() -> Result<ExitCode> {
    let mut all_ok = true;
    for b in ferrocal_vision::backends::probe_backends() {
        println!("{:<14} {:<4} {}  [{}]", b.name, if b.ok { "ok" } else { "FAIL" }, b.detail, b.role);
        all_ok &= b.ok;
    }
    Ok(if all_ok { ExitCode::SUCCESS } else { ExitCode::from(2) })
}
