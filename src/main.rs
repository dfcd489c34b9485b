//! The `mpgdrive` command line: [`cli`] turns each command's arguments into validated settings
//! and calls the library; errors end as one message and an exit code (2 for bad input, 1
//! otherwise, `mpgdrive::exit`).

mod cli;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    // SAFETY: the first statement of main: no other thread exists and libtorch has run nothing.
    if !unsafe { mpgdrive::policy::kernels::pin() } {
        eprintln!(
            "warning: this processor has no AVX2: libtorch runs its baseline kernels, and a \
             training gives other weights than the shipped ones (docs/REPRODUCIBILITY.md)"
        );
    }
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
