//! Finding and loading the ONNX Runtime library (`ort` with `load-dynamic`).
//!
//! segloc does not link onnxruntime; it opens `libonnxruntime.so` at run time from
//! `ORT_DYLIB_PATH`, or else from `target/onnxruntime/` where `scripts/fetch-onnxruntime.sh`
//! puts the library taken from the `onnxruntime` wheel on PyPI. A missing library or one
//! older than [`ONNXRUNTIME_VERSION`]'s API level is a clear error saying what to run.

use std::path::PathBuf;
use std::sync::OnceLock;

use ort::environment::Environment;

use crate::perception::PerceptionError;

/// The onnxruntime release this build is pinned to (`ort` 2.0.0-rc.15 with `api-31`).
pub const ONNXRUNTIME_VERSION: &str = "1.31.1";

/// The library path to load: `ORT_DYLIB_PATH` if set, else
/// `target/onnxruntime/libonnxruntime.so` under the current directory or beside the
/// executable's target directory. Errors (naming what to run) when none exists.
pub fn onnxruntime_library() -> Result<PathBuf, PerceptionError> {
    if let Some(p) = std::env::var_os("ORT_DYLIB_PATH") {
        let p = PathBuf::from(p);
        if p.is_file() {
            return Ok(p);
        }
        return Err(PerceptionError::Runtime(format!(
            "ORT_DYLIB_PATH={} does not exist; run scripts/fetch-onnxruntime.sh to get onnxruntime {ONNXRUNTIME_VERSION}",
            p.display()
        )));
    }
    let mut candidates = vec![PathBuf::from("target/onnxruntime/libonnxruntime.so")];
    if let Ok(exe) = std::env::current_exe() {
        // target/<profile>/segloc or target/<profile>/deps/test-binary
        for up in exe.ancestors().skip(1).take(3) {
            candidates.push(up.join("onnxruntime/libonnxruntime.so"));
        }
    }
    candidates.push(PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/target/onnxruntime/libonnxruntime.so"
    )));
    candidates.into_iter().find(|p| p.is_file()).ok_or_else(|| {
        PerceptionError::Runtime(format!(
            "the onnxruntime library was not found (set ORT_DYLIB_PATH, or run \
             scripts/fetch-onnxruntime.sh to put onnxruntime {ONNXRUNTIME_VERSION} into \
             target/onnxruntime/)"
        ))
    })
}

/// The process-wide ONNX Runtime environment, loading the library on first use.
pub fn environment() -> Result<&'static Environment, PerceptionError> {
    static ENV: OnceLock<Result<Environment, String>> = OnceLock::new();
    let env = ENV.get_or_init(|| {
        let path = onnxruntime_library().map_err(|e| e.to_string())?;
        let builder = ort::init_from(&path).map_err(|e| {
            format!("ONNX Runtime: {e} (expected onnxruntime {ONNXRUNTIME_VERSION}; run scripts/fetch-onnxruntime.sh)")
        })?;
        builder
            .with_name("segloc")
            .build()
            .map_err(|e| format!("ONNX Runtime: cannot create the environment: {e}"))
    });
    env.as_ref()
        .map_err(|m| PerceptionError::Runtime(m.trim_start_matches("ONNX Runtime: ").to_string()))
}

/// An ONNX session of the model at `path`; errors name the file (missing, or not a model
/// this runtime can load).
pub fn load_session(path: &std::path::Path) -> Result<ort::session::Session, PerceptionError> {
    if !path.is_file() {
        return Err(PerceptionError::model(path, "model file not found"));
    }
    let env = environment()?;
    ort::session::Session::builder(env)
        .and_then(|mut b| b.commit_from_file(path))
        .map_err(|e| PerceptionError::model(path, format!("cannot load the model: {e}")))
}

/// Whether the library can be loaded (for tests that need it).
pub fn runtime_available() -> bool {
    environment().is_ok()
}
