//! The `segloc` command line. Exit codes: 0 success, 1 no match (relocalization refused),
//! 2 bad input or usage.
#![warn(clippy::too_many_lines)]

mod cli;

use clap::Parser;

/// Large numeric buffers (Cholesky factors, stereo cost volumes) on transparent huge pages.
#[global_allocator]
static ALLOCATOR: segloc::memory::HugePageAllocator = segloc::memory::HugePageAllocator;

fn main() {
    restore_default_sigpipe();
    let parsed = cli::Cli::parse();
    let code = match cli::run(parsed) {
        Ok(code) => code,
        Err(error) => {
            eprintln!("error: {}", cli::error_message(&error));
            2
        }
    };
    std::process::exit(code);
}

/// Rust ignores SIGPIPE, so printing into a closed pipe (`segloc ... | head`) would make
/// `println!` panic; the default action ends the process quietly, as for any Unix tool.
fn restore_default_sigpipe() {
    #[cfg(unix)]
    // SAFETY: setting a signal's disposition to its default before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}
