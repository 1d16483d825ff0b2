//! Whole-number options with bounds, refused in words (`0 is too small: give at least 1`)
//! rather than as clap's `0 is not in 1..18446744073709551615`.

/// The value parser of an option taking a whole number in `lo..=hi`.
pub fn count_in(
    lo: u64,
    hi: u64,
) -> impl Fn(&str) -> Result<u64, String> + Clone + Send + Sync + 'static {
    move |s| {
        let n: u64 = s
            .trim()
            .parse()
            .map_err(|_| format!("`{s}` is not a whole number"))?;
        if (lo..=hi).contains(&n) {
            Ok(n)
        } else if hi == u64::MAX {
            Err(format!("{n} is too small: give at least {lo}"))
        } else {
            Err(format!("{n} is out of range: give {lo} to {hi}"))
        }
    }
}

/// The most threads `--jobs` takes: more than any machine's cores, few enough that a typo
/// (`--jobs 100000`) is refused instead of starting that many threads.
pub const MAX_JOBS: u64 = 1024;

/// A count as a `usize`, the largest one when it does not fit (a count of threads or items
/// that large is as good as "all").
pub fn to_usize(n: u64) -> usize {
    usize::try_from(n).unwrap_or(usize::MAX)
}
