//! Progress bars for long steps of the commands (hidden when stderr is not a terminal, and with
//! `--quiet`, [`crate::term`]).

use indicatif::{ProgressBar, ProgressStyle};

/// A progress bar of `len` steps with a message.
pub fn bar(len: u64, msg: &str) -> ProgressBar {
    if quiet() {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template("{msg:>28} [{bar:40}] {pos}/{len} ({eta})")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    pb.set_message(msg.to_string());
    pb
}

/// A spinner with the elapsed time, for a long step that reports no progress of its own
/// (hidden when stderr is not a terminal, like the bars).
pub fn spinner(msg: &str) -> ProgressBar {
    if quiet() {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new_spinner();
    pb.set_style(
        ProgressStyle::with_template("{spinner} {msg} ({elapsed})")
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    pb.set_message(msg.to_string());
    pb.enable_steady_tick(std::time::Duration::from_millis(250));
    pb
}

/// `--quiet`: no bars.
fn quiet() -> bool {
    !crate::term::shows(crate::term::Verbosity::Normal)
}

/// Progress bars by label: a new label finishes the previous bar; a bar finishes at its length.
#[derive(Default)]
pub struct Bars(std::cell::RefCell<Option<(String, ProgressBar)>>);

impl Bars {
    /// Shows `pos` of `len` under `label`.
    pub fn tick(&self, label: &str, pos: u64, len: u64) {
        let mut cur = self.0.borrow_mut();
        if cur.as_ref().is_none_or(|(l, _)| l != label) {
            if let Some((_, b)) = cur.take() {
                b.finish_and_clear();
            }
            *cur = Some((label.to_string(), bar(len, label)));
        }
        if let Some((_, b)) = cur.as_ref() {
            b.set_length(len);
            b.set_position(pos);
        }
        if pos >= len {
            if let Some((_, b)) = cur.take() {
                b.finish_and_clear();
            }
        }
    }
}
