//! How much a command says on the terminal: `--quiet` (the verdict line, warnings and errors),
//! the default (the result, the files written and the verdict line), or `--verbose` (internals
//! as well, such as the trade-offs of the parameters a calibration fixed).
//!
//! The level is set once, by the binary, before any command runs; the library crates do not
//! print. The verdict line (`shared/spec/cli.md`) is printed at every level.

use std::path::Path;
use std::sync::atomic::{AtomicU8, Ordering};

/// How much the terminal shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Verbosity {
    /// The verdict line on stdout; warnings and errors on stderr.
    Quiet = 0,
    /// The result, the files written and the verdict line; progress on stderr.
    Normal = 1,
    /// [`Verbosity::Normal`] and the internals behind the result.
    Verbose = 2,
}

static LEVEL: AtomicU8 = AtomicU8::new(Verbosity::Normal as u8);

/// Sets the level for the rest of the process (`--quiet`, `--verbose`).
pub fn set_verbosity(v: Verbosity) {
    LEVEL.store(v as u8, Ordering::Relaxed);
}

/// The level set by [`set_verbosity`] ([`Verbosity::Normal`] when never set).
pub fn verbosity() -> Verbosity {
    match LEVEL.load(Ordering::Relaxed) {
        0 => Verbosity::Quiet,
        1 => Verbosity::Normal,
        _ => Verbosity::Verbose,
    }
}

/// Whether output meant for level `v` is shown.
pub fn shows(v: Verbosity) -> bool {
    verbosity() >= v
}

/// Prints a result line on stdout, unless `--quiet`.
#[macro_export]
macro_rules! say {
    ($($arg:tt)*) => {
        if $crate::term::shows($crate::term::Verbosity::Normal) {
            println!($($arg)*);
        }
    };
}

/// Prints an internal detail on stdout, only with `--verbose`.
#[macro_export]
macro_rules! detail {
    ($($arg:tt)*) => {
        if $crate::term::shows($crate::term::Verbosity::Verbose) {
            println!($($arg)*);
        }
    };
}

/// Prints a progress or status message on stderr, unless `--quiet` (warnings and errors use
/// `eprintln!` and are shown at every level).
#[macro_export]
macro_rules! tell {
    ($($arg:tt)*) => {
        if $crate::term::shows($crate::term::Verbosity::Normal) {
            eprintln!($($arg)*);
        }
    };
}

/// Prints each line with [`say!`].
pub fn say_lines(lines: &[String]) {
    lines.iter().for_each(|l| say!("{l}"));
}

/// The line naming the files a command wrote, in the order written: `wrote: a, b, c`.
pub fn wrote_line<'a>(paths: impl IntoIterator<Item = &'a Path>) -> Option<String> {
    let names: Vec<String> = paths.into_iter().map(|p| p.display().to_string()).collect();
    (!names.is_empty()).then(|| format!("wrote: {}", names.join(", ")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_files_line_names_every_file_in_order_and_is_absent_without_files() {
        let line = wrote_line([Path::new("cal.json"), Path::new("out/report.html")]);
        assert_eq!(line.as_deref(), Some("wrote: cal.json, out/report.html"));
        assert_eq!(wrote_line(std::iter::empty::<&Path>()), None);
    }
}
