//! Boulder detections of one session, and segloc's own detections CSV.
//!
//! The detections CSV (see `maps/FORMAT.md`):
//!
//! ```text
//! # segloc-detections version=1
//! # session=rover_a
//! # frame=odom
//! # gravity_aligned=true
//! frame,x,y,z,size_m,score,rover_x,rover_y,rover_z
//! 120,-3.0341,-4.9741,1.3523,0.42,0.93,-3.5185,-6.8368,1.5035
//! 140,-3.5111,-4.1534,1.3662,,,,,
//! ```
//!
//! Comment lines (`#`) before the header hold `key=value` metadata, one per line; unknown
//! keys and comments without `=` are ignored. Missing keys default to: session = the file
//! stem, frame = "world", gravity_aligned = false. Optional columns (`size_m`, `score`,
//! `rover_*`) may be empty; the three rover columns are all set or all empty.

use std::fmt::Write as _;
use std::path::Path;

use nalgebra::{Isometry3, Point3};

use crate::atomic::{read_text, write_atomic};
use crate::error::{snippet, LineError};
use crate::traverse::{header_matches, parse_lunarloc_traverse, TRAVERSE_HEADER};
use crate::MapError;

/// The header line of a segloc detections CSV.
pub const DETECTIONS_HEADER: &str = "frame,x,y,z,size_m,score,rover_x,rover_y,rover_z";

/// The detections CSV format version this build writes and reads up to.
pub const DETECTIONS_FORMAT_VERSION: u32 = 1;

/// The first comment line of a segloc detections CSV (followed by ` version=N`).
const MAGIC: &str = "segloc-detections";

/// One boulder detection.
#[derive(Clone, Debug, PartialEq)]
pub struct Detection {
    /// Frame / timestamp index it was made in.
    pub frame: u64,
    /// Boulder centroid in the session frame, metres.
    pub p_world: Point3<f64>,
    /// Where the rover was, in the session frame (for range-dependent noise).
    pub rover_position: Option<Point3<f64>>,
    /// Boulder diameter in metres, when estimated.
    pub size_m: Option<f64>,
    /// Detector confidence, when available.
    pub score: Option<f64>,
}

/// The detections of one session, in one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct DetectionSet {
    /// Session / agent id.
    pub session: String,
    /// Frame the positions are expressed in.
    pub frame: String,
    /// Whether z is up (gravity known).
    pub gravity_aligned: bool,
    /// The detections, in file order.
    pub detections: Vec<Detection>,
}

impl DetectionSet {
    /// An empty set.
    pub fn new(
        session: impl Into<String>,
        frame: impl Into<String>,
        gravity_aligned: bool,
    ) -> Self {
        DetectionSet {
            session: session.into(),
            frame: frame.into(),
            gravity_aligned,
            detections: Vec::new(),
        }
    }

    /// Number of detections.
    pub fn len(&self) -> usize {
        self.detections.len()
    }

    /// Whether there is no detection.
    pub fn is_empty(&self) -> bool {
        self.detections.is_empty()
    }

    /// The detection centroids, in order.
    pub fn positions(&self) -> Vec<Point3<f64>> {
        self.detections.iter().map(|d| d.p_world).collect()
    }

    /// The set expressed in another frame: `a_from_b` maps this set's frame into `new_frame`
    /// (centroids and rover positions are moved).
    pub fn transformed(&self, a_from_b: &Isometry3<f64>, new_frame: &str) -> DetectionSet {
        DetectionSet {
            session: self.session.clone(),
            frame: new_frame.to_string(),
            gravity_aligned: self.gravity_aligned,
            detections: self
                .detections
                .iter()
                .map(|d| Detection {
                    p_world: a_from_b * d.p_world,
                    rover_position: d.rover_position.map(|r| a_from_b * r),
                    ..d.clone()
                })
                .collect(),
        }
    }

    /// Check every value is finite (sizes also non-negative) and the names are writable
    /// (one line, no surrounding spaces).
    pub fn validate(&self) -> Result<(), MapError> {
        let bad = |message: String| MapError::InvalidData {
            what: "detection set",
            message,
        };
        for (key, value) in [("session", &self.session), ("frame", &self.frame)] {
            if value.contains(['\n', '\r']) || value.trim() != value {
                return Err(bad(format!(
                    "{key} name {value:?} must be one line without leading or trailing spaces"
                )));
            }
        }
        for (index, d) in self.detections.iter().enumerate() {
            let finite = |p: &Point3<f64>| p.iter().all(|v| v.is_finite());
            let problem = if !finite(&d.p_world) {
                Some("position is not finite")
            } else if d.rover_position.as_ref().is_some_and(|r| !finite(r)) {
                Some("rover position is not finite")
            } else if d.size_m.is_some_and(|s| !(s.is_finite() && s >= 0.0)) {
                Some("size_m is not a finite non-negative number")
            } else if d.score.is_some_and(|s| !s.is_finite()) {
                Some("score is not finite")
            } else {
                None
            };
            if let Some(p) = problem {
                return Err(bad(format!("detection {index} (frame {}): {p}", d.frame)));
            }
        }
        Ok(())
    }
}

/// Read a segloc detections CSV.
pub fn read_detections(path: &Path) -> Result<DetectionSet, MapError> {
    let text = read_text(path)?;
    parse_detections(&text, path)
}

/// Read either a LunarLoc traverse CSV (converted with [`crate::Traverse::detections`]) or a
/// segloc detections CSV, deciding from the first line.
pub fn read_any_detections(path: &Path) -> Result<DetectionSet, MapError> {
    let text = read_text(path)?;
    let first = text.lines().find(|l| !l.trim().is_empty()).unwrap_or("");
    if first.trim_start().starts_with('#') || header_matches(first, DETECTIONS_HEADER) {
        parse_detections(&text, path)
    } else if header_matches(first, TRAVERSE_HEADER) {
        Ok(parse_lunarloc_traverse(&text, path)?.detections())
    } else if text.trim().is_empty() {
        Err(MapError::parse(
            path,
            "the file is empty; expected a LunarLoc traverse or segloc detections CSV",
        ))
    } else {
        let line = text.lines().position(|l| !l.trim().is_empty()).unwrap_or(0) + 1;
        Err(MapError::parse_at(
            path,
            line,
            format!(
                "unrecognised header '{}': expected a LunarLoc traverse ('{TRAVERSE_HEADER}') \
                 or segloc detections ('{DETECTIONS_HEADER}')",
                snippet(first, 60)
            ),
        ))
    }
}

/// Write a segloc detections CSV atomically. Fails (writing nothing) if the set does not
/// [validate](DetectionSet::validate). Numbers are written in Rust's shortest round-trip
/// form, (`{:?}`: `0.1`, `-7.0`, `1e-300`), so reading back gives identical values.
pub fn write_detections(set: &DetectionSet, path: &Path) -> Result<(), MapError> {
    set.validate().map_err(|e| e.in_file(path))?;
    write_atomic(path, detections_to_string(set).as_bytes())
}

/// The text of a segloc detections CSV (no validation; see [`write_detections`]).
pub fn detections_to_string(set: &DetectionSet) -> String {
    let mut s = String::with_capacity(128 + set.detections.len() * 96);
    // writing to a String cannot fail
    let _ = writeln!(s, "# {MAGIC} version={DETECTIONS_FORMAT_VERSION}");
    let _ = writeln!(s, "# session={}", set.session);
    let _ = writeln!(s, "# frame={}", set.frame);
    let _ = writeln!(s, "# gravity_aligned={}", set.gravity_aligned);
    s.push_str(DETECTIONS_HEADER);
    s.push('\n');
    let opt = |s: &mut String, v: Option<f64>| {
        s.push(',');
        if let Some(v) = v {
            let _ = write!(s, "{v:?}");
        }
    };
    for d in &set.detections {
        let p = &d.p_world;
        let _ = write!(s, "{},{:?},{:?},{:?}", d.frame, p.x, p.y, p.z);
        opt(&mut s, d.size_m);
        opt(&mut s, d.score);
        opt(&mut s, d.rover_position.map(|r| r.x));
        opt(&mut s, d.rover_position.map(|r| r.y));
        opt(&mut s, d.rover_position.map(|r| r.z));
        s.push('\n');
    }
    s
}

/// Parse the text of a segloc detections CSV; `source` names it in errors and gives the
/// default session name (file stem).
pub fn parse_detections(text: &str, source: &Path) -> Result<DetectionSet, MapError> {
    let mut set = DetectionSet::new(
        source
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default(),
        "world",
        false,
    );
    let mut lines = text.lines().enumerate();
    // metadata comments, then the header
    loop {
        let Some((index, line)) = lines.next() else {
            return Err(MapError::parse(
                source,
                format!("no header line; expected '{DETECTIONS_HEADER}'"),
            ));
        };
        let line_no = index + 1;
        let trimmed = line.trim().trim_start_matches('\u{feff}');
        if trimmed.is_empty() {
            continue;
        }
        if let Some(comment) = trimmed.strip_prefix('#') {
            parse_meta(comment.trim(), &mut set).map_err(|m| {
                if let MetaError::Version(found) = m {
                    MapError::UnsupportedVersion {
                        what: "detections file",
                        path: source.to_path_buf(),
                        found,
                        supported: DETECTIONS_FORMAT_VERSION,
                    }
                } else {
                    MapError::parse_at(source, line_no, m.to_string())
                }
            })?;
            continue;
        }
        if header_matches(trimmed, DETECTIONS_HEADER) {
            break;
        }
        return Err(MapError::parse_at(
            source,
            line_no,
            format!(
                "expected the header '{DETECTIONS_HEADER}', got '{}'",
                snippet(trimmed, 80)
            ),
        ));
    }
    for (index, line) in lines {
        let trimmed = line.trim();
        if trimmed.is_empty() || trimmed.starts_with('#') {
            continue;
        }
        let d =
            parse_detection_row(trimmed).map_err(|m| MapError::parse_at(source, index + 1, m))?;
        set.detections.push(d);
    }
    Ok(set)
}

enum MetaError {
    Version(u64),
    Other(String),
}

impl std::fmt::Display for MetaError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            MetaError::Version(v) => write!(f, "unsupported version {v}"),
            MetaError::Other(m) => f.write_str(m),
        }
    }
}

fn parse_meta(comment: &str, set: &mut DetectionSet) -> Result<(), MetaError> {
    if let Some(rest) = comment.strip_prefix(MAGIC) {
        let rest = rest.trim();
        let v = rest.strip_prefix("version=").ok_or_else(|| {
            MetaError::Other(format!(
                "expected '# {MAGIC} version=N', got '# {}'",
                snippet(comment, 60)
            ))
        })?;
        let v: u64 = v.trim().parse().map_err(|_| {
            MetaError::Other(format!(
                "version: expected an integer, got '{}'",
                snippet(v, 20)
            ))
        })?;
        if v == 0 {
            return Err(MetaError::Other(
                "version 0 does not exist; versions start at 1".to_string(),
            ));
        }
        if v > u64::from(DETECTIONS_FORMAT_VERSION) {
            return Err(MetaError::Version(v));
        }
        return Ok(());
    }
    let Some((key, value)) = comment.split_once('=') else {
        return Ok(()); // a free comment
    };
    let value = value.trim();
    match key.trim() {
        "session" => set.session = value.to_string(),
        "frame" => set.frame = value.to_string(),
        "gravity_aligned" => {
            set.gravity_aligned = parse_bool(value).ok_or_else(|| {
                MetaError::Other(format!(
                    "gravity_aligned: expected true or false, got '{}'",
                    snippet(value, 20)
                ))
            })?
        }
        _ => {}
    }
    Ok(())
}

fn parse_bool(v: &str) -> Option<bool> {
    match v.to_ascii_lowercase().as_str() {
        "true" | "1" | "yes" => Some(true),
        "false" | "0" | "no" => Some(false),
        _ => None,
    }
}

const COLUMNS: [&str; 9] = [
    "frame", "x", "y", "z", "size_m", "score", "rover_x", "rover_y", "rover_z",
];

fn parse_detection_row(line: &str) -> Result<Detection, LineError> {
    let mut f = [""; 9];
    let mut n = 0;
    for field in line.split(',') {
        if n == 9 {
            return Err(format!("expected 9 fields ({DETECTIONS_HEADER}), got more").into());
        }
        f[n] = field.trim();
        n += 1;
    }
    if n < 9 {
        return Err(format!("expected 9 fields ({DETECTIONS_HEADER}), got {n}").into());
    }
    let frame: u64 = f[0].parse().map_err(|_| {
        format!(
            "frame: expected a non-negative integer, got '{}'",
            snippet(f[0], 30)
        )
    })?;
    let num = |k: usize| -> Result<Option<f64>, LineError> {
        if f[k].is_empty() {
            return Ok(None);
        }
        let v: f64 = f[k].parse().map_err(|_| {
            format!(
                "{}: expected a number, got '{}'",
                COLUMNS[k],
                snippet(f[k], 30)
            )
        })?;
        if v.is_finite() {
            Ok(Some(v))
        } else {
            Err(format!("{}: '{}' is not a finite number", COLUMNS[k], f[k]).into())
        }
    };
    let req = |k: usize| num(k)?.ok_or_else(|| format!("{} is required", COLUMNS[k]));
    let p_world = Point3::new(req(1)?, req(2)?, req(3)?);
    let size_m = num(4)?;
    if let Some(s) = size_m {
        if s < 0.0 {
            return Err(format!("size_m: {s} is negative").into());
        }
    }
    let score = num(5)?;
    let rover_position = match (num(6)?, num(7)?, num(8)?) {
        (Some(x), Some(y), Some(z)) => Some(Point3::new(x, y, z)),
        (None, None, None) => None,
        _ => return Err("rover_x, rover_y, rover_z must be all set or all empty".into()),
    };
    Ok(Detection {
        frame,
        p_world,
        rover_position,
        size_m,
        score,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn set() -> DetectionSet {
        let mut s = DetectionSet::new("rover_a", "odom", true);
        s.detections.push(Detection {
            frame: 120,
            p_world: Point3::new(-3.034147449137282, -4.9741238220042385, 1.3523136173305819),
            rover_position: Some(Point3::new(-3.518490791320801, -6.836832046508789, 1.5)),
            size_m: Some(0.42),
            score: Some(0.93),
        });
        s.detections.push(Detection {
            frame: 140,
            p_world: Point3::new(0.1, 1e-300, -7.0),
            rover_position: None,
            size_m: None,
            score: Some(-2.5),
        });
        s
    }

    fn parse(text: &str) -> Result<DetectionSet, MapError> {
        parse_detections(text, Path::new("d/dets.csv"))
    }

    #[test]
    fn round_trip_exact() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("dets.csv");
        write_detections(&set(), &p).unwrap();
        assert_eq!(read_detections(&p).unwrap(), set());
        assert_eq!(read_any_detections(&p).unwrap(), set());
        let empty = DetectionSet::new("e", "world", false);
        write_detections(&empty, &p).unwrap();
        assert_eq!(read_detections(&p).unwrap(), empty);
    }

    #[test]
    fn text_looks_as_documented() {
        let text = detections_to_string(&set());
        let lines: Vec<_> = text.lines().collect();
        assert_eq!(lines[0], "# segloc-detections version=1");
        assert_eq!(lines[3], "# gravity_aligned=true");
        assert_eq!(lines[4], DETECTIONS_HEADER);
        assert_eq!(lines[6], "140,0.1,1e-300,-7.0,,-2.5,,,");
    }

    #[test]
    fn defaults_without_metadata() {
        let s = parse("frame,x,y,z,size_m,score,rover_x,rover_y,rover_z\n3,1,2,3,,,,,\n").unwrap();
        assert_eq!(s.session, "dets");
        assert_eq!(s.frame, "world");
        assert!(!s.gravity_aligned);
        assert_eq!(s.detections[0].p_world, Point3::new(1.0, 2.0, 3.0));
    }

    #[test]
    fn bad_rows_name_line() {
        let h = "# segloc-detections version=1\nframe,x,y,z,size_m,score,rover_x,rover_y,rover_z\n";
        let e = |row: &str| parse(&format!("{h}{row}\n")).unwrap_err().to_string();
        assert_eq!(e("1,2,3"), "d/dets.csv:3: expected 9 fields (frame,x,y,z,size_m,score,rover_x,rover_y,rover_z), got 3");
        assert_eq!(
            e("1,nan,0,0,,,,,"),
            "d/dets.csv:3: x: 'nan' is not a finite number"
        );
        assert_eq!(e("1,,0,0,,,,,"), "d/dets.csv:3: x is required");
        assert_eq!(e("1,0,0,0,-1,,,,"), "d/dets.csv:3: size_m: -1 is negative");
        assert!(e("1,0,0,0,,,1,2,").contains("all set or all empty"));
        assert!(e("1,0,0,0,,,,,,").contains("got more"));
        assert!(e("x,0,0,0,,,,,").contains("frame: expected"));
    }

    #[test]
    fn bad_metadata_and_headers() {
        let e = parse(
            "# segloc-detections version=7\nframe,x,y,z,size_m,score,rover_x,rover_y,rover_z\n",
        )
        .unwrap_err();
        assert!(matches!(e, MapError::UnsupportedVersion { found: 7, .. }));
        assert!(
            e.to_string()
                .contains("detections file d/dets.csv has format version 7"),
            "{e}"
        );
        let e = parse("# segloc-detections version=0\n")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "d/dets.csv:1: version 0 does not exist; versions start at 1"
        );
        let e = parse("# segloc-detections\n").unwrap_err().to_string();
        assert!(
            e.contains("expected '# segloc-detections version=N'"),
            "{e}"
        );
        let e = parse("# gravity_aligned=maybe\n").unwrap_err().to_string();
        assert!(e.starts_with("d/dets.csv:1: gravity_aligned"), "{e}");
        let e = parse("# just a comment\n").unwrap_err().to_string();
        assert!(e.contains("no header line"), "{e}");
        let e = parse("frame,x,y\n").unwrap_err().to_string();
        assert!(e.starts_with("d/dets.csv:1: expected the header"), "{e}");
    }

    #[test]
    fn write_refuses_invalid() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("dets.csv");
        let mut s = set();
        s.detections[1].p_world.z = f64::INFINITY;
        let e = write_detections(&s, &p).unwrap_err().to_string();
        assert!(
            e.contains("detection 1 (frame 140): position is not finite"),
            "{e}"
        );
        assert!(!p.exists());
        let mut s = set();
        s.session = "a\nb".into();
        assert!(write_detections(&s, &p).is_err());
    }

    #[test]
    fn any_detections_sniffs_formats() {
        let dir = tempfile::tempdir().unwrap();
        let t = dir.path().join("traverse_9.csv");
        std::fs::write(
            &t,
            "frame,x,y,z,detections,boulders\n1,0,0,0,1,\"[(1, 2, 3)]\"\n",
        )
        .unwrap();
        let s = read_any_detections(&t).unwrap();
        assert_eq!(s.session, "traverse_9");
        assert!(s.gravity_aligned);
        assert_eq!(s.detections[0].rover_position, Some(Point3::origin()));
        let u = dir.path().join("u.csv");
        std::fs::write(&u, "\na,b\n").unwrap();
        let e = read_any_detections(&u).unwrap_err().to_string();
        assert!(e.contains("u.csv:2: unrecognised header 'a,b'"), "{e}");
        std::fs::write(&u, "").unwrap();
        assert!(read_any_detections(&u)
            .unwrap_err()
            .to_string()
            .contains("empty"));
        let e = read_any_detections(&dir.path().join("missing.csv")).unwrap_err();
        assert!(matches!(e, MapError::Io { .. }));
    }

    #[test]
    fn transform_moves_rover_too() {
        let iso = Isometry3::translation(1.0, 0.0, 0.0);
        let t = set().transformed(&iso, "world");
        assert_eq!(t.frame, "world");
        assert_eq!(
            t.detections[0].rover_position.unwrap().x,
            -3.518490791320801 + 1.0
        );
        assert_eq!(t.detections[1].rover_position, None);
        assert_eq!(t.positions().len(), 2);
    }
}
