//! Progress on stderr for long loops: one bar style for every command.

use indicatif::{ProgressBar, ProgressStyle};

/// The style of every progress bar: elapsed time, bar, count and message.
pub fn style() -> ProgressStyle {
    ProgressStyle::with_template("{elapsed_precise} [{bar:30}] {pos}/{len} {msg}")
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> ")
}

/// A progress bar over `len` items on stderr; hidden where stderr is not a
/// terminal (callers then print plain lines, see [`note`]).
pub fn progress(len: usize, what: &str) -> ProgressBar {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len as u64);
    bar.set_style(style());
    bar.set_message(what.to_string());
    bar
}

/// A spinner with `message` for work without a count; where stderr is not a
/// terminal the message is printed once instead.
pub fn spinner(message: String) -> ProgressBar {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        eprintln!("{message}");
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new_spinner();
    bar.set_message(message);
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    bar
}

/// A line above the bar, or on stderr when the bar is hidden.
pub fn note(bar: &ProgressBar, message: String) {
    if bar.is_hidden() {
        eprintln!("{message}");
    } else {
        bar.println(message);
    }
}
