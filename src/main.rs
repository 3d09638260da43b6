//! The `segloc` command line. Exit codes: 0 success, 1 no match (relocalization refused),
//! 2 bad input or usage.

mod cli;

use clap::Parser;

fn main() {
    let parsed = cli::Cli::parse();
    let code = match cli::run(parsed) {
        Ok(code) => code,
        Err(error) => {
            eprintln!("error: {error:#}");
            2
        }
    };
    std::process::exit(code);
}
