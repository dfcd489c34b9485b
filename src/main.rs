//! The `mpgdrive` command line: [`cli`] turns each command's arguments into validated settings
//! and calls the library; errors end as one message and an exit code (2 for bad input, 1
//! otherwise, `mpgdrive::exit`).

mod cli;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = cli::Cli::parse();
    match cli::run(cli) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            // 2 when the input is what is wrong, 1 when the tool failed (src/exit.rs).
            ExitCode::from(mpgdrive::exit::exit_code(e.as_ref()))
        }
    }
}
