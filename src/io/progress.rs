//! Progress bars on stderr (indicatif), shared by the stages.

/// A progress bar on stderr, hidden when `show` is false.
pub fn progress_bar(show: bool, len: u64, msg: &'static str) -> indicatif::ProgressBar {
    if !show {
        return indicatif::ProgressBar::hidden();
    }
    let b = indicatif::ProgressBar::new(len);
    if let Ok(style) =
        indicatif::ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} ({eta})")
    {
        b.set_style(style);
    }
    b.set_message(msg);
    b
}
