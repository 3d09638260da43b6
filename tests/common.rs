//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::PathBuf;

/// The real-data folder: `SEGLOC_DATA`, else `../shared/data` beside the repository.
/// Returns `None` (and says so) when it is missing; under `CI=true` a missing folder fails
/// the test instead of skipping it.
pub fn data_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("SEGLOC_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data")));
    if dir.join("lunarloc").is_dir() {
        return Some(dir);
    }
    if std::env::var("CI").is_ok_and(|v| v == "true") {
        panic!(
            "real data not found at {} (set SEGLOC_DATA); under CI=true this test must not skip",
            dir.display()
        );
    }
    eprintln!("SKIPPED: real data not found at {}", dir.display());
    None
}

/// The segloc binary built for these tests.
pub fn segloc() -> std::process::Command {
    std::process::Command::new(env!("CARGO_BIN_EXE_segloc"))
}

/// What a finished command wrote on stderr.
pub fn stderr_of(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Assert that a finished command exited with 0, showing its stderr otherwise.
#[track_caller]
pub fn assert_success(out: &std::process::Output) {
    assert_eq!(out.status.code(), Some(0), "{}", stderr_of(out));
}

/// Assert that a finished command was refused as bad input: exit code 2 and `needle` in its
/// stderr.
#[track_caller]
pub fn assert_refused(out: &std::process::Output, needle: &str) {
    let err = stderr_of(out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains(needle), "expected '{needle}' in: {err}");
}
