//! Command-line parsing and the subcommands' front ends.

mod choice;
mod config_cmd;
mod count;
mod eval_args;
mod eval_cmd;
mod fit_cmd;
mod import_cmd;
mod info_cmd;
mod layer_topics;
mod plot_cmd;
mod simulate_cmd;
mod track_cmd;
mod tune_cmd;
mod viz_cmd;

use std::process::ExitCode;

use anyhow::Result;
use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use probmot::pipeline::progress::Progress;

/// probmot: probabilistic 3D multi-object tracking for MCAP drive recordings.
///
/// Reads 3D detections from an MCAP file, tracks them with the method of Chiu et al. (2019)
/// (Kalman filter, Mahalanobis distance, greedy matching, noise from data) and writes the
/// recording back with a tracks channel added.
///
/// Exit status: 0 success, 2 error (bad input, missing file, invalid config), 3 the evaluation
/// gate failed (eval --max-drop); 130, 143 or 129 when interrupted by SIGINT, SIGTERM or SIGHUP
/// (nothing half-written is left behind).
///
/// Examples:
///   probmot track sample_logs/city.mcap -o city.tracked.mcap
///   probmot eval --truth city.tracked.mcap
///   probmot track --help
#[derive(Debug, Parser)]
#[command(name = "probmot", version, about, long_about, verbatim_doc_comment)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Largest MCAP chunk (uncompressed) and largest record read, in MiB [default: 512]. A
    /// guard against a small file that expands to gigabytes; memory grows with the largest
    /// record, not with this limit.
    #[arg(long, global = true, value_name = "MIB",
          value_parser = count::count_in(1, 1 << 40))]
    max_chunk_mib: Option<u64>,
}

impl Cli {
    /// Parses the command line, reading a negative number after an option that takes a value as
    /// that value (`--score-floor -2` for PointRCNN's logits, `--min-hits -1` refused as out of
    /// range), for every option of every command, instead of as an unknown flag.
    pub fn parse_args() -> Cli {
        let matches = negative_numbers_as_values(Cli::command()).get_matches();
        Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit())
    }
}

/// `cmd` and its subcommands with every option that takes a value allowing negative numbers.
fn negative_numbers_as_values(cmd: clap::Command) -> clap::Command {
    cmd.mut_args(|a| match a.get_action().takes_values() {
        true => a.allow_negative_numbers(true),
        false => a,
    })
    .mut_subcommands(negative_numbers_as_values)
}

#[derive(Debug, Subcommand)]
enum Command {
    Track(track_cmd::TrackArgs),
    Info(info_cmd::InfoArgs),
    Simulate(simulate_cmd::SimulateArgs),
    Config(config_cmd::ConfigArgs),
    Eval(eval_args::EvalArgs),
    Fit(fit_cmd::FitArgs),
    Import(import_cmd::ImportArgs),
    Export(import_cmd::ExportArgs),
    Plot(plot_cmd::PlotArgs),
    Viz(viz_cmd::VizArgs),
    Tune(tune_cmd::TuneArgs),
}

/// Runs a parsed command line; the exit code on success.
pub fn run(cli: Cli) -> Result<ExitCode> {
    if let Some(mib) = cli.max_chunk_mib {
        probmot::mcapio::chunk_stream::set_size_limit(mib << 20);
    }
    match cli.command {
        Command::Track(a) => track_cmd::run(a),
        Command::Info(a) => info_cmd::run(a),
        Command::Simulate(a) => simulate_cmd::run(a),
        Command::Config(a) => config_cmd::run(a),
        Command::Eval(a) => eval_cmd::run(a),
        Command::Fit(a) => fit_cmd::run(a),
        Command::Import(a) => import_cmd::run_import(a),
        Command::Export(a) => import_cmd::run_export(a),
        Command::Plot(a) => plot_cmd::run(a),
        Command::Viz(a) => viz_cmd::run(a),
        Command::Tune(a) => tune_cmd::run(a),
    }
}

/// The template of a bar over bytes read.
pub const READING: &str =
    "{spinner} reading {wide_bar} {binary_bytes}/{binary_total_bytes} ETA {eta}";

/// The style of `template`.
pub fn style(template: &str) -> ProgressStyle {
    ProgressStyle::with_template(template).expect("valid template")
}

/// A bar in `style`, its length set by the library's progress events (hidden unless `show`).
pub fn bar(show: bool, style: ProgressStyle) -> ProgressBar {
    match show {
        true => ProgressBar::new(0).with_style(style),
        false => ProgressBar::hidden(),
    }
}

/// A spinner for the library's progress events ([`show_on_spinner`]), hidden unless `show`.
pub fn spinner(show: bool) -> ProgressBar {
    match show {
        true => ProgressBar::new_spinner(),
        false => ProgressBar::hidden(),
    }
}

/// Shows a progress event on a spinner: a message starts it with that message, done clears it.
pub fn show_on_spinner(bar: &ProgressBar, e: Progress<'_>) {
    match e {
        Progress::Message(m) => {
            bar.set_message(m.to_string());
            if !bar.is_hidden() {
                bar.enable_steady_tick(std::time::Duration::from_millis(120));
            }
        }
        Progress::Done => bar.finish_and_clear(),
        _ => {}
    }
}

/// Whether progress bars should be drawn: stderr is a terminal and not `--quiet`.
pub fn show_progress(quiet: bool) -> bool {
    use std::io::IsTerminal;
    !quiet && std::io::stderr().is_terminal()
}

/// Shows a progress event of the library on an indicatif bar.
pub fn show_on_bar(bar: &ProgressBar, e: Progress<'_>) {
    match e {
        Progress::Length(n) => bar.set_length(n),
        Progress::Position(n) => bar.set_position(n),
        Progress::Advance(n) => bar.inc(n),
        Progress::Message(m) => bar.set_message(m.to_string()),
        Progress::Done => bar.set_position(bar.length().unwrap_or(0)),
    }
}
