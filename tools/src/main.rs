//! `ferrocal`: vision-based measurement and robot calibration from the command line.
//!
//! The binary is glue: it parses arguments, calls the library crates and writes results. Every
//! command exits 0 on success and non-zero with a one-line reason on stderr on failure.

mod cli;
mod commands;

// The report and progress modules under their old paths (`crate::report`, `crate::progress`).
use ferrocal_report::{progress, report};

use std::process::ExitCode;

use ferrocal_report::term::{set_verbosity, Verbosity};

fn main() -> ExitCode {
    restore_sigpipe();
    let args = cli::Cli::try_parse_grouped(std::env::args_os()).unwrap_or_else(|e| e.exit());
    // Set once for the process: the demo's commands, run in-process, keep the demo's level.
    set_verbosity(match (args.quiet, args.verbose) {
        (true, _) => Verbosity::Quiet,
        (false, true) => Verbosity::Verbose,
        (false, false) => Verbosity::Normal,
    });
    // OpenCV's and Ceres' own log lines only under --verbose (docs/verdicts.md).
    ferrocal_vision::backends::show_library_logs(args.verbose);
    match commands::run(args) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("ferrocal: error: {}", ferrocal_report::error::one_line(e.as_ref()));
            ExitCode::from(1)
        }
    }
}

/// Output piped into `head` or `less` ends quietly when the reader closes the pipe, as other
/// command-line tools do (Rust ignores SIGPIPE by default, which turns it into a panic on print).
fn restore_sigpipe() {
    #[cfg(unix)]
    // SAFETY: called first thing in main, before any other thread exists; SIG_DFL is a valid
    // disposition for SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}
