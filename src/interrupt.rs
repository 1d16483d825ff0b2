//! SIGINT, SIGTERM and SIGHUP (Ctrl-C, `kill`, a closed terminal): the partial files and
//! partial directories (a split bag's) of the outputs being written are removed, one line says which outputs were left unwritten, and the
//! process exits with the conventional status 128 + signal number (130, 143, 129).
//!
//! The signals are received on a thread of their own (`signal-hook`'s iterator): the clean-up
//! runs as ordinary code there, not in a signal handler, and it knows which signal arrived (which
//! `ctrlc` does not tell), so the exit status can follow the convention shells use.
//!
//! SIGXFSZ (a file-size limit reached) is ignored, so that the write fails with an error instead.

use std::path::PathBuf;

use probmot::mcapio::partial_dir::abandon_partial_dirs;
use probmot::mcapio::writer::{abandon_in_place, abandon_partials};
use probmot::pipeline::scratch_file::remove_scratch_files;

use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};

/// Starts the thread that handles the three signals. Without it (a failure to register, which
/// should not happen) the signals keep their default action and a warning says so.
pub fn install() {
    // A file-size limit (`ulimit -f`) sends SIGXFSZ, whose default action kills the process
    // with the partial file left behind: ignored, the write fails with EFBIG instead, and the
    // error (naming the output) removes the partial file like any other write error.
    // SAFETY: setting a signal's disposition to SIG_IGN, before any other thread runs.
    unsafe {
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
    }
    {
        // A signal the parent set to be ignored stays ignored: `nohup` (SIGHUP) and background
        // jobs of a non-interactive shell (SIGINT) rely on it.
        let wanted: Vec<i32> = [SIGINT, SIGTERM, SIGHUP]
            .into_iter()
            .filter(|&sig| !ignored(sig))
            .collect();
        let mut signals = match signal_hook::iterator::Signals::new(wanted) {
            Ok(s) => s,
            Err(e) => {
                eprintln!("warning: cannot handle interrupts ({e}); an interrupted run may leave a .probmot-partial file");
                return;
            }
        };
        std::thread::Builder::new()
            .name("probmot-signals".into())
            .spawn(move || {
                if let Some(sig) = signals.forever().next() {
                    let unwritten = unwritten(abandon_partials(), abandon_partial_dirs());
                    let partly = abandon_in_place();
                    remove_scratch_files();
                    // A progress bar may be drawn on the terminal's last line: clear it, so
                    // the message starts a line of its own.
                    use std::io::IsTerminal;
                    let clear = match std::io::stderr().is_terminal() {
                        true => "\r\x1b[2K",
                        false => "",
                    };
                    eprintln!("{clear}{}", message(sig, &unwritten, &partly));
                    std::process::exit(128 + sig);
                }
            })
            .expect("start the signal thread");
    }
}

/// The outputs not written: the files, but those inside a partial directory (a split bag's)
/// are named by the directory's destination.
fn unwritten(files: Vec<PathBuf>, dirs: Vec<(PathBuf, PathBuf)>) -> Vec<PathBuf> {
    let inside = |f: &PathBuf| dirs.iter().any(|(partial, _)| f.starts_with(partial));
    let files = files.into_iter().filter(|f| !inside(f));
    files
        .chain(dirs.iter().map(|(_, dest)| dest.clone()))
        .collect()
}

/// Whether `sig` is set to be ignored (inherited from the parent process).
fn ignored(sig: i32) -> bool {
    // SAFETY: sigaction with a null new action only reads the current one into `old`, a
    // zero-initialised plain C struct.
    unsafe {
        let mut old: libc::sigaction = std::mem::zeroed();
        libc::sigaction(sig, std::ptr::null(), &mut old) == 0 && old.sa_sigaction == libc::SIG_IGN
    }
}

/// The one line printed on an interrupt: the outputs not written (their partial files or bag directories removed)
/// and those written in place (a device, FIFO or stdout) that got part of an output.
fn message(sig: i32, unwritten: &[PathBuf], partly: &[PathBuf]) -> String {
    let name = match sig {
        SIGINT => "SIGINT",
        SIGTERM => "SIGTERM",
        SIGHUP => "SIGHUP",
        _ => "a signal",
    };
    let list = |paths: &[PathBuf]| {
        let names: Vec<String> = paths.iter().map(|p| p.display().to_string()).collect();
        names.join(", ")
    };
    let mut parts = Vec::new();
    if !unwritten.is_empty() {
        parts.push(format!(
            "not written (partial output removed): {}",
            list(unwritten)
        ));
    }
    if !partly.is_empty() {
        parts.push(format!("partly written (in place): {}", list(partly)));
    }
    if parts.is_empty() {
        return format!("probmot: interrupted by {name}; no output was being written");
    }
    format!("probmot: interrupted by {name}; {}", parts.join("; "))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_message_names_the_signal_and_every_unwritten_output() {
        let m = message(
            SIGTERM,
            &[PathBuf::from("a.mcap"), PathBuf::from("out/b.mcap")],
            &[],
        );
        assert_eq!(
            m,
            "probmot: interrupted by SIGTERM; not written (partial output removed): a.mcap, out/b.mcap"
        );
        assert!(message(SIGHUP, &[], &[]).contains("SIGHUP; no output was being written"));
        let files = vec![
            PathBuf::from("a.mcap"),
            PathBuf::from(".bag.probmot-partial/b_0.mcap"),
        ];
        let dirs = vec![(PathBuf::from(".bag.probmot-partial"), PathBuf::from("bag"))];
        assert_eq!(unwritten(files, dirs), ["a.mcap", "bag"].map(PathBuf::from));
        assert_eq!(
            message(SIGINT, &[], &[PathBuf::from("/dev/stdout")]),
            "probmot: interrupted by SIGINT; partly written (in place): /dev/stdout"
        );
    }
}
