//! The `neural-cloth` command line: with no subcommand it opens the authoring app; the
//! subcommands run the same jobs headless (inspect, train, eval, simulate, bake, bench,
//! report, screenshot, soak).

mod cli;

use clap::Parser;

fn main() -> std::process::ExitCode {
    let args = cli::Cli::parse();
    if args.command.is_some() {
        cli::headless::headless_environment();
    }
    match cli::run(args) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", cli::error_text(&e));
            std::process::ExitCode::FAILURE
        }
    }
}
