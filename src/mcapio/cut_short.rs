//! MCAP files that end in the middle of a record: what a recorder leaves when it crashes, is
//! killed or loses power. Their records up to the cut are whole and checked like any other, so
//! the commands that read recordings as they were recorded (`track`, `info`) read them, and say
//! what was lost; the commands that read `track`'s outputs refuse them, pointing at `track`.
//!
//! What is lost is the unfinished record: in a chunked file, the chunk being written (a
//! recorder's chunk holds about a second or less of a drive), and always the summary section.

/// Where a file cut short stops being readable.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct CutShort {
    /// The file, named as its input is.
    pub file: String,
    /// Bytes from the start of the file that are whole records; reading stopped there.
    pub complete_bytes: u64,
    /// Bytes in the file.
    pub file_bytes: u64,
    /// Whether the cut falls after the end of the data section (in the summary section or the
    /// footer), so that every message was read.
    pub in_summary: bool,
}

impl CutShort {
    /// Bytes after the last whole record: the unfinished record, not read.
    pub fn lost_bytes(&self) -> u64 {
        self.file_bytes.saturating_sub(self.complete_bytes)
    }

    /// What a command that reads the file says: what it read, and what it could not.
    pub fn warning(&self) -> String {
        format!(
            "{}: the file is cut short (a recording that did not finish?); {}",
            self.file,
            self.what_was_read()
        )
    }

    /// The error of a command that reads only whole files (`track`'s outputs).
    pub fn error(&self) -> String {
        format!(
            "{}: not a readable MCAP file: it is cut short at byte {} (a recording that did not \
             finish?); `probmot track` and `probmot info` read the records before the cut (a \
             warning says what was lost), and `mcap recover IN.mcap -o OUT.mcap` (the mcap CLI, \
             https://mcap.dev) rebuilds them as a whole file",
            self.file, self.complete_bytes
        )
    }

    /// What was read of the file, and what was not.
    pub fn what_was_read(&self) -> String {
        let lost = self.lost_bytes();
        match (self.in_summary, lost) {
            (true, _) => format!(
                "every message was read, but its summary section is unfinished (the last {lost} \
                 bytes)"
            ),
            (false, 0) => format!(
                "its records were read up to byte {}, where it ends without its summary section",
                self.complete_bytes
            ),
            (false, _) => format!(
                "its records were read up to byte {}; the last {lost} bytes, an unfinished \
                 record (the messages of the chunk being written), were not",
                self.complete_bytes
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cut(complete_bytes: u64, file_bytes: u64, in_summary: bool) -> CutShort {
        CutShort {
            file: "drive.mcap".into(),
            complete_bytes,
            file_bytes,
            in_summary,
        }
    }

    #[test]
    fn the_warning_says_what_was_read_and_what_was_lost() {
        let mid = cut(1000, 1500, false);
        assert_eq!(mid.lost_bytes(), 500);
        let w = mid.warning();
        assert!(w.starts_with("drive.mcap: the file is cut short"), "{w}");
        assert!(w.contains("up to byte 1000; the last 500 bytes"), "{w}");
        let w = cut(1500, 1500, false).warning();
        assert!(w.contains("up to byte 1500, where it ends without"), "{w}");
        let w = cut(1400, 1500, true).warning();
        assert!(
            w.contains("every message was read") && w.contains("last 100 bytes"),
            "{w}"
        );
        let e = mid.error();
        assert!(
            e.contains("cut short at byte 1000") && e.contains("probmot track"),
            "{e}"
        );
    }
}
