//! `ferrocal`: vision-based measurement and robot calibration from the command line.
//!
//! The binary is glue: it parses arguments, calls the library crates and writes results. Every
//! command exits 0 on success and non-zero with a one-line reason on stderr on failure.

mod cli;
mod commands;
mod progress;

// The report module under its old path (`crate::report`).
use ferrocal_report::report;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    restore_sigpipe();
    let args = cli::Cli::parse();
    match commands::run(args) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("ferrocal: error: {}", one_line(&e));
            ExitCode::from(1)
        }
    }
}

/// The error on one line: its chain of causes joined with `: `, a cause whose words the line
/// already holds left out (an error that quotes its source in its own message would else say
/// it twice: `cannot read x.csv: No such file ...: No such file ...`).
fn one_line(e: &anyhow::Error) -> String {
    let mut msg = String::new();
    for cause in e.chain() {
        let text = cause.to_string().replace('\n', " ");
        if msg.contains(&text) {
            continue;
        }
        if !msg.is_empty() {
            msg.push_str(": ");
        }
        msg.push_str(&text);
    }
    msg
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

#[cfg(test)]
mod tests {
    #[test]
    fn a_cause_quoted_by_its_error_is_said_once() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "No such file or directory (os error 2)");
        let e = anyhow::Error::new(ferrocal_datasets::error::DatasetError::Io { path: "x.csv".into(), source: io });
        assert_eq!(super::one_line(&e), "cannot read x.csv: No such file or directory (os error 2)");
        let e = anyhow::anyhow!("inner\nreason").context("outer");
        assert_eq!(super::one_line(&e), "outer: inner reason");
    }
}
