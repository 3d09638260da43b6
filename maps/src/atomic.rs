//! Atomic file writes: write a temporary file in the destination's directory, then rename.
//!
//! A reader never sees a half-written map, even if the writer is killed mid-way.

use std::io::Write;
use std::path::Path;

use crate::MapError;

/// Write `bytes` to `path` atomically (temp file in the same directory + rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), MapError> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let io = |action: &'static str| {
        move |source: std::io::Error| MapError::Io {
            action,
            path: path.to_path_buf(),
            source,
        }
    };
    let mut tmp = tempfile::Builder::new()
        .prefix(".segloc-tmp-")
        .tempfile_in(dir)
        .map_err(io("create a temporary file beside"))?;
    tmp.write_all(bytes).map_err(io("write"))?;
    tmp.as_file().sync_all().map_err(io("write"))?;
    tmp.persist(path).map_err(|e| MapError::Io {
        action: "rename a temporary file onto",
        path: path.to_path_buf(),
        source: e.error,
    })?;
    Ok(())
}

/// Read a whole text file, mapping errors to [`MapError::Io`] / [`MapError::Parse`].
pub(crate) fn read_text(path: &Path) -> Result<String, MapError> {
    let bytes = std::fs::read(path).map_err(|e| MapError::read_io(path, e))?;
    String::from_utf8(bytes).map_err(|e| {
        let valid = &e.as_bytes()[..e.utf8_error().valid_up_to()];
        let line = valid.iter().filter(|&&b| b == b'\n').count() + 1;
        MapError::parse_at(path, line, "the file is not valid UTF-8 text")
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_and_replaces() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        write_atomic(&p, b"one").unwrap();
        write_atomic(&p, b"two").unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "two");
        // no temp files left behind
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn missing_directory_is_an_io_error_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("no/such/dir/a.txt");
        let e = write_atomic(&p, b"x").unwrap_err();
        assert!(matches!(e, MapError::Io { .. }));
        assert!(e.to_string().contains("a.txt"), "{e}");
    }

    #[test]
    fn non_utf8_names_line() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.csv");
        std::fs::write(&p, b"ok\nok\n\xff\n").unwrap();
        let e = read_text(&p).unwrap_err();
        assert_eq!(e.line(), Some(3));
    }
}
