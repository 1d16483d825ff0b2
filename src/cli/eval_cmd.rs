//! `probmot eval`: the arguments as the library's options, one call of
//! [`probmot::eval::job::evaluate`], the report printed and the gate's exit status.

use std::process::ExitCode;

use anyhow::Result;
use indicatif::{ProgressBar, ProgressStyle};
use probmot::eval::job::evaluate;
use probmot::eval::legend;
use probmot::pipeline::progress::Progress;

use super::eval_args::EvalArgs;
use super::{show_progress, style, READING};

/// Runs `probmot eval`.
pub fn run(a: EvalArgs) -> Result<ExitCode> {
    refuse_stray(&a)?;
    if a.explain && a.truth.is_empty() {
        print!("{}", legend::text(&legend::SECTIONS));
        return Ok(ExitCode::SUCCESS);
    }
    let bar = super::bar(show_progress(a.quiet || a.json), style(READING));
    let report = evaluate(&a.options(), &|e| on_bar(&bar, e));
    bar.finish_and_clear();
    let report = report?;
    match &report.json {
        Some(v) => println!("{}", serde_json::to_string_pretty(v)?),
        None => print!("{}", report.text),
    }
    for f in &report.gate_failures {
        eprintln!("gate failed: {f}");
    }
    Ok(match report.gate_failures.is_empty() {
        true => ExitCode::SUCCESS,
        false => ExitCode::from(3),
    })
}

/// Shows the evaluation's progress: a bar over the bytes read, then a spinner while it scores.
fn on_bar(bar: &ProgressBar, e: Progress<'_>) {
    match e {
        Progress::Length(n) => {
            bar.set_style(style(READING));
            bar.set_length(n);
        }
        Progress::Message(m) => {
            bar.set_style(ProgressStyle::default_spinner());
            bar.set_message(m.to_string());
            bar.enable_steady_tick(std::time::Duration::from_millis(120));
        }
        Progress::Done => bar.disable_steady_tick(),
        e => super::show_on_bar(bar, e),
    }
}

/// Refuses files given without an option (`probmot eval drive.tracked.mcap`), with the command
/// that names them.
fn refuse_stray(a: &EvalArgs) -> Result<()> {
    let Some(first) = a.stray.first() else {
        return Ok(());
    };
    let files: Vec<String> = a.stray.iter().map(|p| p.display().to_string()).collect();
    anyhow::bail!(
        "unexpected argument {}: `probmot eval` takes its files by option: --truth FILE (the \
         ground truth, and the tracks when one file holds both), --tracks FILE (a separate \
         tracked file); e.g. `probmot eval --truth {}`",
        files.join(" "),
        first.display()
    )
}
