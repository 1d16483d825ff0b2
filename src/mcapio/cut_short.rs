//! Recordings that did not finish: what a recorder leaves when it crashes, is killed or loses
//! power. An MCAP file then ends in the middle of a record; a rosbag2 sqlite3 file (written, by
//! rosbag2's default, with its journal in memory and without syncing) is left with pages its
//! header counts but the file does not hold, or pages half written. What can be read of it is
//! whole and checked like any other record, so the commands that read recordings as they were
//! recorded (`track`, `info`) read it and say what was lost; the commands that read `track`'s
//! outputs refuse it, pointing at `track`.
//!
//! What is lost is the unfinished part: in a chunked MCAP file, the chunk being written (a
//! recorder's chunk holds about a second or less of a drive) and the summary section; in a
//! sqlite3 file, the rows after the first unreadable one.

/// A file found cut short, and where.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct CutShort {
    /// The file, named as its input is.
    pub file: String,
    /// Where it stops being readable.
    #[serde(flatten)]
    pub at: CutAt,
}

/// Where a file cut short stops being readable, by its storage.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
#[serde(tag = "storage", rename_all = "lowercase")]
pub enum CutAt {
    /// An MCAP file that ends in the middle of a record.
    Mcap {
        /// Bytes from the start of the file that are whole records; reading stopped there.
        complete_bytes: u64,
        /// Bytes in the file.
        file_bytes: u64,
        /// Whether the cut falls after the end of the data section (in the summary section or
        /// the footer), so that every message was read.
        in_summary: bool,
    },
    /// A sqlite3 file a crash left damaged.
    Sqlite3 {
        /// Whether its `messages` table could be read whole all the same (only its header
        /// counted pages the file does not hold).
        table_whole: bool,
        /// Rows of `messages` read (when not whole: in row order, before the first that could
        /// not be).
        rows_read: u64,
        /// The id of the last of them (`None`: no row was read).
        last_row: Option<i64>,
        /// The pages the file's header counts, when more than the file holds (the recorder
        /// died before writing them all).
        header_pages: Option<u64>,
        /// The pages the file holds.
        file_pages: u64,
    },
}

impl CutShort {
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
        let at = match self.at {
            CutAt::Mcap { complete_bytes, .. } => format!("at byte {complete_bytes}"),
            CutAt::Sqlite3 { .. } => "(its messages table cannot be read whole)".into(),
        };
        format!(
            "{}: not a readable MCAP file: it is cut short {at} (a recording that did not \
             finish?); `probmot track` and `probmot info` read the records before the cut (a \
             warning says what was lost), and `mcap recover IN.mcap -o OUT.mcap` (the mcap CLI, \
             https://mcap.dev) rebuilds them as a whole file",
            self.file
        )
    }

    /// What was read of the file, and what was not.
    pub fn what_was_read(&self) -> String {
        match self.at {
            CutAt::Mcap {
                complete_bytes,
                file_bytes,
                in_summary,
            } => {
                let lost = file_bytes.saturating_sub(complete_bytes);
                match (in_summary, lost) {
                    (true, _) => format!(
                        "every message was read, but its summary section is unfinished (the \
                         last {lost} bytes)"
                    ),
                    (false, 0) => format!(
                        "its records were read up to byte {complete_bytes}, where it ends \
                         without its summary section"
                    ),
                    (false, _) => format!(
                        "its records were read up to byte {complete_bytes}; the last {lost} \
                         bytes, an unfinished record (the messages of the chunk being written), \
                         were not"
                    ),
                }
            }
            CutAt::Sqlite3 {
                table_whole,
                rows_read,
                last_row,
                header_pages,
                file_pages,
            } => {
                let pages = header_pages.map_or(String::new(), |h| {
                    format!("its header counts {h} pages and the file holds {file_pages}; ")
                });
                let last = last_row.map_or("none".into(), |r| format!("row {r}"));
                match table_whole {
                    true => format!("{pages}its {rows_read} messages were all read"),
                    false => format!(
                        "{pages}{rows_read} messages were read, in row order up to {last}, and \
                         the rows after the first unreadable one were not"
                    ),
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cut(complete_bytes: u64, file_bytes: u64, in_summary: bool) -> CutShort {
        let at = CutAt::Mcap {
            complete_bytes,
            file_bytes,
            in_summary,
        };
        CutShort {
            file: "drive.mcap".into(),
            at,
        }
    }

    #[test]
    fn the_warning_says_what_was_read_and_what_was_lost() {
        let mid = cut(1000, 1500, false);
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
        let db = CutShort {
            file: "b_0.db3".into(),
            at: CutAt::Sqlite3 {
                table_whole: false,
                rows_read: 7,
                last_row: Some(9),
                header_pages: Some(30),
                file_pages: 20,
            },
        };
        let w = db.warning();
        assert!(
            w.contains(
                "header counts 30 pages and the file holds 20; 7 messages were read, in \
                        row order up to row 9"
            ),
            "{w}"
        );
        let json = serde_json::to_value(&db).unwrap();
        assert_eq!(json["storage"], "sqlite3");
        assert_eq!(json["rows_read"], 7);
        assert_eq!(serde_json::to_value(&mid).unwrap()["file_bytes"], 1500);
    }
}
