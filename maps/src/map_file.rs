//! The versioned segloc map file (JSON).
//!
//! ```json
//! {
//!   "format": "segloc-map",
//!   "version": 1,
//!   "frame": "world",
//!   "session": "traverse_3",
//!   "gravity_aligned": true,
//!   "notes": {"source": "traverse_3.csv"},
//!   "landmarks": [
//!     {"id": 0, "p": [-3.03, -4.97, 1.35], "cov": [0.0004, 0, 0, 0.0004, 0, 0.0009], "size_m": null, "observations": 5, "sessions": []}
//!   ]
//! }
//! ```
//!
//! - `format` must be `"segloc-map"`; `version` is the format version (this build writes
//!   [`MAP_FORMAT_VERSION`] and reads every version up to it; a newer file is refused with
//!   an "upgrade segloc" message).
//! - `p` is the landmark centroid in `frame`, metres; `cov` the upper triangle of its
//!   covariance, `[xx, xy, xz, yy, yz, zz]`, m².
//! - `size_m` (boulder diameter, m) may be `null` or absent; `observations` defaults to 1;
//!   `sessions` (provenance; empty = the map's session) and `notes` default to empty.
//! - Unknown fields are an error (a misspelt field is never silently dropped).
//! - One landmark per line when written by segloc, so error line numbers point at it.
//!
//! After parsing, the map is [validated](crate::ObjectMap::validate): finite positions,
//! PSD covariances, unique ids. The full description is in `maps/FORMAT.md`.
//!
//! Each version has its own module (`v1`) that converts the file into the current
//! [`ObjectMap`]; a future `v2` adds a module and a match arm in [`map_from_str`].

mod v1;

use std::path::Path;

use serde::Deserialize;
use serde_json::Value;

use crate::atomic::{read_text, write_atomic};
use crate::error::snippet;
use crate::{MapError, ObjectMap};

/// The map file format version this build writes (and the newest it reads).
pub const MAP_FORMAT_VERSION: u32 = 1;

/// The value of the `format` field of a segloc map file.
pub const MAP_FORMAT_NAME: &str = "segloc-map";

/// Context of errors found while reading the full version-1 structure.
const V1_CONTEXT: &str = "invalid map file";

/// Read and validate a map file.
pub fn read_map(path: &Path) -> Result<ObjectMap, MapError> {
    let text = read_text(path)?;
    map_from_str(&text, path)
}

/// Write a map file atomically (temporary file in the same directory, then rename), in the
/// current format version. The map is validated first; an invalid map writes nothing.
pub fn write_map(map: &ObjectMap, path: &Path) -> Result<(), MapError> {
    map.validate().map_err(|e| e.in_file(path))?;
    write_atomic(path, map_to_string(map).as_bytes())
}

/// Parse and validate the text of a map file; `source` names it in errors.
pub fn map_from_str(text: &str, source: &Path) -> Result<ObjectMap, MapError> {
    #[derive(Deserialize)]
    struct Header {
        format: Option<Value>,
        version: Option<Value>,
    }
    let header: Header =
        serde_json::from_str(text).map_err(|e| json_error(source, e, "not a segloc map file"))?;
    let not_a_map = |message: String| MapError::parse(source, message);
    match &header.format {
        Some(Value::String(f)) if f == MAP_FORMAT_NAME => {}
        Some(other) => {
            return Err(not_a_map(format!(
                "\"format\" is {}, expected \"{MAP_FORMAT_NAME}\": not a segloc map file",
                snippet(&other.to_string(), 40)
            )))
        }
        None => {
            return Err(not_a_map(format!(
                "no \"format\": \"{MAP_FORMAT_NAME}\" field: not a segloc map file"
            )))
        }
    }
    let version = match &header.version {
        Some(v) => v.as_u64().ok_or_else(|| {
            not_a_map(format!(
                "\"version\" is {}, expected a positive integer",
                snippet(&v.to_string(), 40)
            ))
        })?,
        None => return Err(not_a_map("no \"version\" field".to_string())),
    };
    let map = match version {
        1 => v1::parse(text).map_err(|e| json_error(source, e, V1_CONTEXT))?,
        0 => {
            return Err(not_a_map(
                "\"version\" 0 does not exist; versions start at 1".to_string(),
            ))
        }
        found => {
            return Err(MapError::UnsupportedVersion {
                what: "map file",
                path: source.to_path_buf(),
                found,
                supported: MAP_FORMAT_VERSION,
            })
        }
    };
    map.validate().map_err(|e| e.in_file(source))?;
    Ok(map)
}

/// The text of a map file in the current version (one landmark per line). No validation:
/// non-finite numbers would be written as `null` and fail to read back; use [`write_map`],
/// or call [`ObjectMap::validate`] first.
pub fn map_to_string(map: &ObjectMap) -> String {
    v1::to_string(map)
}

/// Turn a serde_json error into a [`MapError::Parse`] with the line, the column and a
/// plain-words message.
fn json_error(source: &Path, e: serde_json::Error, context: &str) -> MapError {
    use serde_json::error::Category;
    let full = e.to_string();
    // serde_json appends " at line L column C"; we report the line ourselves
    let what = full
        .rsplit_once(" at line ")
        .map_or(full.as_str(), |(head, _)| head);
    let message = match e.classify() {
        Category::Eof => format!(
            "the JSON ends early (truncated file?): {what} (column {})",
            e.column()
        ),
        // The header pass already checked the JSON syntax, so a "syntax" error while
        // reading the full structure is serde_json's report of an over-long array.
        Category::Syntax if what == "trailing characters" && context == V1_CONTEXT => format!(
            "{context}: an array has too many values (\"p\" takes 3, \"cov\" takes 6) (column {})",
            e.column()
        ),
        Category::Syntax => format!("JSON syntax error: {what} (column {})", e.column()),
        Category::Data => format!("{context}: {what} (column {})", e.column()),
        Category::Io => what.to_string(),
    };
    if e.line() == 0 {
        MapError::parse(source, message)
    } else {
        MapError::parse_at(source, e.line(), message)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Landmark;
    use nalgebra::{Matrix3, Point3};

    fn map() -> ObjectMap {
        let mut m = ObjectMap::new("world", "traverse_3", true);
        m.notes.insert("source".into(), "traverse_3.csv".into());
        m.notes.insert("quote\"d".into(), "line\nbreak".into());
        let mut a = Landmark::new(
            0,
            Point3::new(-3.034147449137282, -4.9741238220042385, 1.3523136173305819),
            Matrix3::new(4e-4, 1e-5, -2e-5, 1e-5, 3e-4, 0.0, -2e-5, 0.0, 9e-4),
        );
        a.observations = 5;
        a.size_m = Some(0.3);
        a.sessions = vec!["traverse_3".into(), "traverse_5".into()];
        m.landmarks.push(a);
        m.landmarks.push(Landmark::new(
            7,
            Point3::new(0.1, 0.2, 0.3),
            Matrix3::zeros(),
        ));
        m
    }

    fn parse(text: &str) -> Result<ObjectMap, MapError> {
        map_from_str(text, Path::new("maps/prior.json"))
    }

    fn err(text: &str) -> String {
        parse(text).unwrap_err().to_string()
    }

    #[test]
    fn round_trip_exact_through_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("prior.json");
        write_map(&map(), &p).unwrap();
        assert_eq!(read_map(&p).unwrap(), map());
        let empty = ObjectMap::new("query", "", false);
        write_map(&empty, &p).unwrap();
        assert_eq!(read_map(&p).unwrap(), empty);
    }

    #[test]
    fn round_trip_many_random_floats_bit_exact() {
        let mut m = ObjectMap::new("w", "s", true);
        let mut x: u64 = 0x1234_5678_9abc_def1;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as f64 / (1u64 << 53) as f64 * 200.0 - 100.0
        };
        for id in 0..500 {
            let d = next().abs() * 1e-3;
            m.landmarks.push(Landmark::new(
                id,
                Point3::new(next(), next(), next() * 1e-7),
                Matrix3::identity() * d,
            ));
        }
        assert_eq!(parse(&map_to_string(&m)).unwrap(), m);
    }

    #[test]
    fn written_text_is_one_landmark_per_line() {
        let text = map_to_string(&map());
        assert!(text.starts_with("{\n  \"format\": \"segloc-map\",\n  \"version\": 1,\n"));
        let lines: Vec<_> = text.lines().collect();
        let lm = lines.iter().find(|l| l.contains("\"id\":7")).unwrap();
        assert!(lm.contains("\"p\":[0.1,0.2,0.3]"), "{lm}");
        assert!(lm.contains("\"size_m\":null"), "{lm}");
    }

    #[test]
    fn minimal_landmark_uses_defaults() {
        let m = parse(
            r#"{"format":"segloc-map","version":1,"frame":"w","session":"s","gravity_aligned":false,
               "landmarks":[{"id":3,"p":[1,2,3],"cov":[1,0,0,1,0,1]}]}"#,
        )
        .unwrap();
        let l = &m.landmarks[0];
        assert_eq!(l.observations, 1);
        assert_eq!(l.size_m, None);
        assert!(l.sessions.is_empty());
        assert!(m.notes.is_empty());
        assert_eq!(l.covariance, Matrix3::identity());
    }

    #[test]
    fn future_version_refused_with_upgrade_message() {
        let text = map_to_string(&map()).replace("\"version\": 1", "\"version\": 7");
        let e = parse(&text).unwrap_err();
        assert!(matches!(
            e,
            MapError::UnsupportedVersion {
                found: 7,
                supported: 1,
                ..
            }
        ));
        assert_eq!(
            e.to_string(),
            "map file maps/prior.json has format version 7; this segloc reads versions up to 1: upgrade segloc"
        );
        assert!(err(&text.replace("\"version\": 7", "\"version\": 0")).contains("does not exist"));
        assert!(err(&text.replace("\"version\": 7", "\"version\": \"1\""))
            .contains("expected a positive integer"));
        assert!(err(&text.replace("\"version\": 7,", "")).contains("no \"version\" field"));
    }

    #[test]
    fn missing_or_wrong_format_field() {
        assert_eq!(
            err(r#"{"version": 1}"#),
            "maps/prior.json: no \"format\": \"segloc-map\" field: not a segloc map file"
        );
        assert_eq!(
            err(r#"{"format": "geojson", "version": 1}"#),
            "maps/prior.json: \"format\" is \"geojson\", expected \"segloc-map\": not a segloc map file"
        );
        assert!(err("[1, 2]").contains("not a segloc map file"));
        assert!(err("").contains("truncated"));
    }

    #[test]
    fn truncated_file_names_line() {
        let text = map_to_string(&map());
        let cut = &text[..text.len() - 20];
        let e = parse(cut).unwrap_err();
        let n_lines = cut.lines().count();
        assert_eq!(e.line(), Some(n_lines), "{e}");
        assert!(e.to_string().contains("truncated"), "{e}");
        assert!(
            e.to_string()
                .starts_with(&format!("maps/prior.json:{n_lines}: ")),
            "{e}"
        );
    }

    #[test]
    fn syntax_and_data_errors_name_line() {
        let text = map_to_string(&map());
        let bad = text.replacen("\"p\":[", "\"p\":[,", 1);
        let e = parse(&bad).unwrap_err();
        assert_eq!(e.line(), Some(9), "{e}");
        let bad = text.replacen("\"cov\":[", "\"cov\":[1,", 1);
        let e = parse(&bad).unwrap_err();
        assert_eq!(e.line(), Some(9), "{e}");
        assert!(
            e.to_string()
                .contains("invalid map file: an array has too many values"),
            "{e}"
        );
        let bad = text.replacen("\"p\":[0.1,", "\"p\":[", 1);
        let e = err(&bad);
        assert!(e.contains("invalid map file: invalid length 2"), "{e}");
        let bad = text.replacen("\"observations\"", "\"observatons\"", 1);
        assert!(err(&bad).contains("unknown field `observatons`"));
        let bad = text.replacen("\"frame\": \"world\",", "", 1);
        assert!(err(&bad).contains("missing field `frame`"));
    }

    #[test]
    fn invalid_content_names_landmark() {
        let text = map_to_string(&map());
        let bad = text.replacen("\"id\":7", "\"id\":0", 1);
        assert_eq!(
            err(&bad),
            "maps/prior.json: duplicate landmark id 0 (indices 0 and 1)"
        );
        let bad = text.replacen("\"cov\":[0.0004", "\"cov\":[-0.0004", 1);
        let e = err(&bad);
        assert!(
            e.contains("landmark id 0 (index 0): covariance has a negative variance xx"),
            "{e}"
        );
        let bad = text.replacen("\"p\":[0.1,", "\"p\":[NaN,", 1);
        assert!(err(&bad).contains("JSON syntax error"));
        let bad = text.replacen("\"p\":[0.1,", "\"p\":[1e999,", 1);
        assert!(parse(&bad).is_err());
    }

    #[test]
    fn write_refuses_invalid_and_missing_file_is_io() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.json");
        let mut m = map();
        m.landmarks[0].position.x = f64::NAN;
        let e = write_map(&m, &p).unwrap_err();
        assert!(e.to_string().contains("m.json"), "{e}");
        assert!(!p.exists());
        let e = read_map(&dir.path().join("none.json")).unwrap_err();
        assert!(matches!(e, MapError::Io { .. }));
        assert!(e.to_string().starts_with("cannot read "), "{e}");
    }
}
