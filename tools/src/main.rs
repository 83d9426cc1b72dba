//! `ferrocal`: vision-based measurement and robot calibration from the command line.
//!
//! The binary is glue: it parses arguments, calls the library crates and writes results. Every
//! command exits 0 on success and non-zero with a one-line reason on stderr on failure.

mod cli;
mod commands;
mod plot;
mod progress;
mod report;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let args = cli::Cli::parse();
    match commands::run(args) {
        Ok(code) => code,
        Err(e) => {
            // One line: the chain of causes joined.
            let msg = format!("{e:#}").replace('\n', " ");
            eprintln!("ferrocal: error: {msg}");
            ExitCode::from(1)
        }
    }
}
