//! The console's progress bar: every bar of this crate is made here, and
//! messages go above it (or to stderr when there is none).

use indicatif::ProgressBar;

/// A bar of `len` steps at `position`, or a hidden one when `show` is false
/// or stderr or stdout is not a terminal: a bar only redraws one terminal
/// line, and where the output is captured (a log file, CI) periodic plain
/// lines are what is wanted instead.
pub fn bar(show: bool, position: usize, len: usize) -> ProgressBar {
    use std::io::IsTerminal;
    if !show || !std::io::stderr().is_terminal() || !std::io::stdout().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len as u64);
    bar.set_style(field_ops::progress::style());
    bar.set_position(position as u64);
    bar
}

/// Prints above the progress bar, or to stderr when there is none.
pub fn say(bar: &ProgressBar, message: String) {
    if bar.is_hidden() {
        eprintln!("{message}");
    } else {
        bar.println(message);
    }
}
