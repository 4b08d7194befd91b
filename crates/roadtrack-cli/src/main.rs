//! The `roadtrack` command: a thin layer that parses arguments, calls the library and maps
//! errors to exit codes (0 success, 1 the input or a run failed, 2 wrong usage).

mod cmd;
mod common;
mod demo;
mod flags;
mod onnx_detector;
mod overlay;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use std::process::ExitCode;

/// Trajectories of vehicles and pedestrians from traffic imagery.
#[derive(Debug, Parser)]
#[command(name = "roadtrack", version, about, long_about = None, propagate_version = true)]
struct Cli {
    /// Print nothing but errors (no progress bars, no summaries).
    #[arg(short, long, global = true, conflicts_with = "verbose")]
    quiet: bool,
    /// Print more detail (repeat for more).
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    verbose: u8,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    Analyze(cmd::analyze::Args),
    Demo(cmd::demo::Args),
    Detect(cmd::detect::Args),
    Bench(cmd::bench::Args),
    Check(cmd::check::Args),
    Plot(cmd::plot::Args),
    Render(cmd::render::Args),
    Evaluate(cmd::evaluate::Args),
    Experiment(cmd::experiment::Args),
    Filter(cmd::filter::Args),
    Match(cmd::matching::Args),
    Simulate(cmd::simulate::Args),
    Sweep(cmd::sweep::Args),
    Track(cmd::track::Args),
    Train(cmd::train::Args),
}

/// On SIGINT or SIGTERM: stop the ffmpeg encoders, remove every temporary output, and exit
/// with 128 + the signal (130, 143), so an interrupted run leaves nothing behind.
#[cfg(unix)]
fn remove_outputs_on_signals() {
    use signal_hook::consts::{SIGINT, SIGTERM};
    let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM]) else {
        return;
    };
    std::thread::spawn(move || {
        if let Some(sig) = signals.forever().next() {
            roadtrack::io::video::kill_ffmpeg_processes();
            roadtrack::io::atomic::remove_pending_outputs_and_exit(128 + sig);
        }
    });
}

#[cfg(not(unix))]
fn remove_outputs_on_signals() {}

/// The command line, with every flag's value allowed to be a negative number.
///
/// Choice: so that `--fps -5` reaches the flag's value parser and is reported as a bad
/// value of `--fps` (exit 2), not as an unknown argument `-5`.
fn command() -> clap::Command {
    let mut cmd = Cli::command();
    let subcommands: Vec<String> = cmd
        .get_subcommands()
        .map(|s| s.get_name().to_owned())
        .collect();
    for name in subcommands {
        cmd = cmd.mut_subcommand(name, |sub| {
            let ids: Vec<clap::Id> = sub
                .get_arguments()
                .filter(|a| !a.is_positional() && a.get_action().takes_values())
                .map(|a| a.get_id().clone())
                .collect();
            ids.into_iter().fold(sub, |sub, id| {
                sub.mut_arg(id, |a| a.allow_negative_numbers(true))
            })
        });
    }
    cmd
}

fn main() -> ExitCode {
    remove_outputs_on_signals();
    let matches = command().get_matches();
    let subcommand = matches.subcommand_name().unwrap_or_default().to_owned();
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    let ui = common::Ui::new(cli.quiet, cli.verbose);
    let result = match cli.command {
        Command::Analyze(args) => cmd::analyze::run(args, &ui),
        Command::Demo(args) => cmd::demo::run(args, &ui),
        Command::Detect(args) => cmd::detect::run(args, &ui),
        Command::Bench(args) => cmd::bench::run(args, &ui),
        Command::Check(args) => cmd::check::run(args, &ui),
        Command::Plot(args) => cmd::plot::run(args, &ui),
        Command::Render(args) => cmd::render::run(args, &ui),
        Command::Evaluate(args) => cmd::evaluate::run(args, &ui),
        Command::Experiment(args) => cmd::experiment::run(args, &ui),
        Command::Filter(args) => cmd::filter::run(args, &ui),
        Command::Match(args) => cmd::matching::run(args, &ui),
        Command::Simulate(args) => cmd::simulate::run(args, &ui),
        Command::Sweep(args) => cmd::sweep::run(args, &ui),
        Command::Track(args) => cmd::track::run(args, &ui),
        Command::Train(args) => cmd::train::run(args, &ui),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            if let Some(usage) = err.downcast_ref::<flags::UsageError>() {
                // Wrong flags found after parsing: reported as clap reports its own (exit 2).
                let mut cmd = Cli::command();
                cmd.build();
                let error = match cmd.find_subcommand_mut(&subcommand) {
                    Some(sub) => sub.error(usage.kind, &usage.message),
                    None => cmd.error(usage.kind, &usage.message),
                };
                error.exit();
            }
            eprintln!("roadtrack: error: {err:#}");
            ExitCode::from(1)
        }
    }
}
