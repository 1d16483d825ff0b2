//! Progress of a long run, reported through a callback: the library draws nothing, the caller
//! (the CLI's progress bar, a test, a GUI) decides what to show.

/// One progress event.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Progress<'a> {
    /// The total amount of work, in bytes read (reset when a run starts another pass).
    Length(u64),
    /// Work done so far, in the unit of [`Progress::Length`].
    Position(u64),
    /// Work done since the last event, in the unit of [`Progress::Length`] (for work done in
    /// parallel, e.g. `tune`'s configurations scored).
    Advance(u64),
    /// What the run is doing, e.g. `tracking: frame 64/800`.
    Message(&'a str),
    /// The run finished: all of the work is done.
    Done,
}

/// The progress callback of work that may report from several threads (`tune`).
pub type ProgressFn<'a> = &'a (dyn Fn(Progress<'_>) + Sync);

/// A callback that ignores every event.
pub fn no_progress(_: Progress<'_>) {}
