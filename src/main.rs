//! The `probmot` command-line tool.

mod cli;
#[cfg(unix)]
mod interrupt;

use std::process::ExitCode;

fn main() -> ExitCode {
    restore_sigpipe();
    #[cfg(unix)]
    interrupt::install();
    let args = cli::Cli::parse_args();
    match cli::run(args) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}

/// Rust ignores SIGPIPE, so writing to a closed pipe (`probmot info --json | head`) makes
/// `println!` panic. Restore the default action: the process ends quietly, as other command-line
/// tools do, when the reader goes away.
fn restore_sigpipe() {
    #[cfg(unix)]
    // SAFETY: called first thing in main, before any other thread exists; SIG_DFL is a valid
    // disposition for SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}
