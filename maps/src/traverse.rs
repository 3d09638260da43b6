//! LunarLoc traverse CSV files (`traverse_N.csv`).
//!
//! ```text
//! frame,x,y,z,detections,boulders
//! 1,-3.5155,-6.9009,1.4826,0,[]
//! 120,-3.5185,-6.8368,1.5035,2,"[(-3.0341, -4.9741, 1.3523), (-3.5111, -4.1534, 1.3662)]"
//! ```
//!
//! `x,y,z` is the ground-truth rover position (world frame, metres); `boulders` is a
//! Python-style list of `(x, y, z)` boulder centroids in the world frame, with as many
//! tuples as `detections` says. The parser is hand-written (no regex), tolerant of spaces,
//! `\r\n` line ends, a trailing comma and `[x, y, z]` lists instead of tuples, and strict on
//! everything else: every error names the file and line.

use std::path::Path;

use nalgebra::{Isometry3, Point3};
use rayon::prelude::*;

use crate::atomic::read_text;
use crate::error::{snippet, LineError};
use crate::point_list::parse_point_list;
use crate::{Detection, DetectionSet, MapError};

/// The header line of a LunarLoc traverse CSV.
pub const TRAVERSE_HEADER: &str = "frame,x,y,z,detections,boulders";

/// One LunarLoc traverse: the rover trajectory and the boulders detected along it.
#[derive(Clone, Debug, PartialEq)]
pub struct Traverse {
    /// Name, from the file stem (e.g. "traverse_3").
    pub name: String,
    /// One entry per CSV row, in file order.
    pub frames: Vec<TraverseFrame>,
}

/// One row of a traverse: a simulator frame.
#[derive(Clone, Debug, PartialEq)]
pub struct TraverseFrame {
    /// Simulator frame index (20 Hz).
    pub frame: u64,
    /// Ground-truth rover position, world frame, metres.
    pub rover_position: Point3<f64>,
    /// Boulder centroids detected in this frame, world frame, metres (often empty).
    pub boulders: Vec<Point3<f64>>,
}

impl Traverse {
    /// All boulder detections as a [`DetectionSet`] (session = the traverse name, frame
    /// "world", gravity aligned), each carrying the rover position it was seen from.
    pub fn detections(&self) -> DetectionSet {
        let detections = self
            .frames
            .iter()
            .flat_map(|f| {
                f.boulders.iter().map(move |b| Detection {
                    frame: f.frame,
                    p_world: *b,
                    rover_position: Some(f.rover_position),
                    size_m: None,
                    score: None,
                })
            })
            .collect();
        DetectionSet {
            session: self.name.clone(),
            frame: "world".to_string(),
            gravity_aligned: true,
            detections,
        }
    }

    /// The rover positions of every frame, in order.
    pub fn trajectory(&self) -> Vec<Point3<f64>> {
        self.frames.iter().map(|f| f.rover_position).collect()
    }

    /// Total number of boulder detections over all frames.
    pub fn num_detections(&self) -> usize {
        self.frames.iter().map(|f| f.boulders.len()).sum()
    }

    /// The traverse as seen in another frame: every rover position and boulder is mapped by
    /// `a_from_b` (use this to make a traverse "another session" with a known transform).
    pub fn transformed(&self, a_from_b: &Isometry3<f64>) -> Traverse {
        Traverse {
            name: self.name.clone(),
            frames: self
                .frames
                .iter()
                .map(|f| TraverseFrame {
                    frame: f.frame,
                    rover_position: a_from_b * f.rover_position,
                    boulders: f.boulders.iter().map(|b| a_from_b * b).collect(),
                })
                .collect(),
        }
    }
}

/// Read a LunarLoc `traverse_N.csv`; the traverse is named after the file stem.
pub fn read_lunarloc_traverse(path: &Path) -> Result<Traverse, MapError> {
    let text = read_text(path)?;
    parse_lunarloc_traverse(&text, path)
}

/// Parse the text of a LunarLoc traverse CSV; `source` names it in errors and gives the
/// traverse its name (file stem).
pub fn parse_lunarloc_traverse(text: &str, source: &Path) -> Result<Traverse, MapError> {
    let name = source
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, header)) if header_matches(header, TRAVERSE_HEADER) => {}
        Some((_, header)) => {
            return Err(MapError::parse_at(
                source,
                1,
                format!(
                    "expected the LunarLoc header '{TRAVERSE_HEADER}', got '{}'",
                    snippet(header, 80)
                ),
            ))
        }
        None => {
            return Err(MapError::parse(
                source,
                format!("the file is empty; expected the LunarLoc header '{TRAVERSE_HEADER}'"),
            ))
        }
    }
    // Rows are independent: parse large files in parallel chunks split at line ends.
    // Float parsing dominates (17 traverses, 16 MB, ~700k numbers).
    let body_start = text.find('\n').map_or(text.len(), |k| k + 1);
    let body = &text[body_start..];
    let chunks = split_at_lines(body, 2, PARALLEL_CHUNK_BYTES);
    let parsed: Vec<Result<Vec<TraverseFrame>, MapError>> = chunks
        .par_iter()
        .map(|&(first_line, chunk)| parse_rows(chunk, first_line, source))
        .collect();
    let mut frames = Vec::with_capacity(body.len() / 60);
    for part in parsed {
        frames.extend(part?);
    }
    Ok(Traverse { name, frames })
}

/// Chunk size above which rows are parsed in parallel.
const PARALLEL_CHUNK_BYTES: usize = 256 * 1024;

/// Parse the data rows of `chunk`, whose first line is line `first_line` of the file.
fn parse_rows(
    chunk: &str,
    first_line: usize,
    source: &Path,
) -> Result<Vec<TraverseFrame>, MapError> {
    let mut frames = Vec::with_capacity(chunk.len() / 60);
    for (k, line) in chunk.lines().enumerate() {
        if fast_trim(line).is_empty() {
            continue;
        }
        let frame = parse_row(line).map_err(|m| MapError::parse_at(source, first_line + k, m))?;
        frames.push(frame);
    }
    Ok(frames)
}

/// Split `text` (whose first line is line `first_line`) into pieces of about `chunk_bytes`
/// ending at line ends, each with the number of its first line.
pub(crate) fn split_at_lines(
    text: &str,
    first_line: usize,
    chunk_bytes: usize,
) -> Vec<(usize, &str)> {
    let mut out = Vec::with_capacity(text.len() / chunk_bytes.max(1) + 1);
    let mut rest = text;
    let mut line = first_line;
    while !rest.is_empty() {
        let cut = if rest.len() <= chunk_bytes {
            rest.len()
        } else {
            rest.as_bytes()[chunk_bytes..]
                .iter()
                .position(|&b| b == b'\n')
                .map_or(rest.len(), |k| chunk_bytes + k + 1)
        };
        let (piece, tail) = rest.split_at(cut);
        out.push((line, piece));
        line += piece.bytes().filter(|&b| b == b'\n').count();
        rest = tail;
    }
    out
}

/// Whether a header line equals `expected`, ignoring spaces around names and a BOM.
pub(crate) fn header_matches(line: &str, expected: &str) -> bool {
    let line = line.trim_start_matches('\u{feff}');
    let mut got = line.split(',').map(str::trim);
    let mut want = expected.split(',');
    loop {
        match (got.next(), want.next()) {
            (None, None) => return true,
            (Some(g), Some(w)) if g == w => {}
            _ => return false,
        }
    }
}

fn parse_row(line: &str) -> Result<TraverseFrame, LineError> {
    // byte-level split at the first five commas (this is the hot path)
    let bytes = line.as_bytes();
    let mut comma = [0usize; 5];
    let mut start = 0;
    for (k, name) in ["x", "y", "z", "detections", "boulders"].iter().enumerate() {
        match bytes[start..].iter().position(|&c| c == b',') {
            Some(off) => comma[k] = start + off,
            None => {
                return Err(format!(
                    "expected 6 fields ({TRAVERSE_HEADER}), the row ends before '{name}'"
                )
                .into())
            }
        }
        start = comma[k] + 1;
    }
    let field = |k: usize| {
        let from = if k == 0 { 0 } else { comma[k - 1] + 1 };
        let to = if k < 5 { comma[k] } else { line.len() };
        &line[from..to]
    };
    let frame_text = field(0);
    let frame: u64 = frame_text.trim().parse().map_err(|_| {
        format!(
            "frame: expected a non-negative integer, got '{}'",
            snippet(frame_text, 30)
        )
    })?;
    let x = parse_finite(field(1), "x")?;
    let y = parse_finite(field(2), "y")?;
    let z = parse_finite(field(3), "z")?;
    let count_text = field(4);
    let count: usize = count_text.trim().parse().map_err(|_| {
        format!(
            "detections: expected a non-negative integer, got '{}'",
            snippet(count_text, 30)
        )
    })?;
    let raw = field(5).trim();
    let list = if let Some(inner) = raw.strip_prefix('"') {
        inner
            .strip_suffix('"')
            .ok_or_else(|| "boulders: unterminated quoted field".to_string())?
    } else {
        raw
    };
    // the count is the file's word: reserve no more than the list's text can hold (a
    // tuple takes at least 7 bytes), so a huge count is an error, not an allocation
    let mut boulders = Vec::with_capacity(count.min(list.len() / 7));
    parse_point_list(list, &mut boulders)?;
    if boulders.len() != count {
        return Err(format!(
            "detections says {count} but boulders lists {} tuple{}",
            boulders.len(),
            if boulders.len() == 1 { "" } else { "s" }
        )
        .into());
    }
    Ok(TraverseFrame {
        frame,
        rover_position: Point3::new(x, y, z),
        boulders,
    })
}

fn parse_finite(text: &str, name: &str) -> Result<f64, LineError> {
    let t = fast_trim(text);
    let v: f64 = t
        .parse()
        .map_err(|_| format!("{name}: expected a number, got '{}'", snippet(t, 30)))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("{name}: '{t}' is not a finite number").into())
    }
}

/// `str::trim`, skipping the work in the common case of no surrounding whitespace.
fn fast_trim(t: &str) -> &str {
    match (t.as_bytes().first(), t.as_bytes().last()) {
        (Some(a), Some(b)) if !a.is_ascii_whitespace() && !b.is_ascii_whitespace() => t,
        _ => t.trim(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    const SAMPLE: &str = "frame,x,y,z,detections,boulders\n\
        1,-3.5,-6.9,1.48,0,[]\n\
        120,-3.5185,-6.8368,1.5035,2,\"[(-3.0341, -4.9741, 1.3523), (-3.5111, -4.1534, 1.3662)]\"\n";

    fn parse(text: &str) -> Result<Traverse, MapError> {
        parse_lunarloc_traverse(text, Path::new("dir/traverse_3.csv"))
    }

    fn err(text: &str) -> String {
        parse(text).unwrap_err().to_string()
    }

    #[test]
    fn parses_sample() {
        let t = parse(SAMPLE).unwrap();
        assert_eq!(t.name, "traverse_3");
        assert_eq!(t.frames.len(), 2);
        assert!(t.frames[0].boulders.is_empty());
        assert_eq!(t.frames[1].frame, 120);
        assert_eq!(
            t.frames[1].boulders[1],
            Point3::new(-3.5111, -4.1534, 1.3662)
        );
        assert_eq!(t.num_detections(), 2);
        assert_eq!(t.trajectory()[0], Point3::new(-3.5, -6.9, 1.48));
        let d = t.detections();
        assert_eq!(d.session, "traverse_3");
        assert_eq!(d.frame, "world");
        assert!(d.gravity_aligned);
        assert_eq!(d.detections.len(), 2);
        assert_eq!(d.detections[0].frame, 120);
        assert_eq!(
            d.detections[0].rover_position,
            Some(Point3::new(-3.5185, -6.8368, 1.5035))
        );
    }

    #[test]
    fn tolerates_crlf_spaces_trailing_comma_and_lists() {
        let text = "frame, x, y, z, detections, boulders\r\n\
            7,0,0,0,2,\"[ (1,2,3) , [4.5, 5e-1, -6,] , ]\"\r\n\r\n";
        let t = parse(text).unwrap();
        assert_eq!(
            t.frames[0].boulders,
            vec![Point3::new(1.0, 2.0, 3.0), Point3::new(4.5, 0.5, -6.0)]
        );
    }

    #[test]
    fn empty_boulder_list_forms() {
        let t =
            parse("frame,x,y,z,detections,boulders\n1,0,0,0,0,\"[ ]\"\n2,0,0,0,0,[]\n").unwrap();
        assert!(t.frames.iter().all(|f| f.boulders.is_empty()));
        // an empty list where detections says 1
        let e = err("frame,x,y,z,detections,boulders\n1,0,0,0,1,[]\n");
        assert_eq!(
            e,
            "dir/traverse_3.csv:2: detections says 1 but boulders lists 0 tuples"
        );
    }

    #[test]
    fn header_only_is_an_empty_traverse() {
        assert!(parse("frame,x,y,z,detections,boulders\n")
            .unwrap()
            .frames
            .is_empty());
    }

    /// Fuzz regression (issue 25 §3): a huge `detections` count reserved that many points
    /// before reading the list (`1000000000000` aborted the process asking for 24 TB;
    /// `18446744073709551615` panicked with a capacity overflow).
    #[test]
    fn fuzz_huge_detection_count_is_an_error_not_an_allocation() {
        for count in ["1000000000000", "18446744073709551615"] {
            let e = err(&format!(
                "frame,x,y,z,detections,boulders\n1,0,0,0,{count},[]\n"
            ));
            assert_eq!(
                e,
                format!(
                    "dir/traverse_3.csv:2: detections says {count} but boulders lists 0 tuples"
                )
            );
        }
    }

    #[test]
    fn mismatched_count_names_line() {
        let text = SAMPLE.replace(",2,\"[", ",3,\"[");
        assert_eq!(
            err(&text),
            "dir/traverse_3.csv:3: detections says 3 but boulders lists 2 tuples"
        );
    }

    #[test]
    fn malformed_tuple_names_line_and_input() {
        let text = "frame,x,y,z,detections,boulders\n1,0,0,0,0,[]\n2,0,0,0,1,\"[(1.0, 2.0]\"\n";
        assert_eq!(
            err(text),
            "dir/traverse_3.csv:3: boulders: expected '(x, y, z)' tuples, got ']'"
        );
        let text = "frame,x,y,z,detections,boulders\n2,0,0,0,1,\"[(1.0, abc, 3)]\"\n";
        let e = err(text);
        assert!(
            e.starts_with("dir/traverse_3.csv:2: boulders: expected"),
            "{e}"
        );
        assert!(e.contains("abc"), "{e}");
        let text = "frame,x,y,z,detections,boulders\n2,0,0,0,1,\"[(1, 2, 3)\"\n";
        assert!(err(text).contains("got the end of the field"));
        let text = "frame,x,y,z,detections,boulders\n2,0,0,0,1,\"[(1, 2, 3)] junk\"\n";
        assert!(err(text).contains("unexpected text after the list: 'junk'"));
        let text = "frame,x,y,z,detections,boulders\n2,0,0,0,1,\"[(1, 2, 3)]\n";
        assert!(err(text).contains("unterminated"));
    }

    #[test]
    fn nan_and_inf_rejected_with_line() {
        let text = "frame,x,y,z,detections,boulders\n1,0,0,0,0,[]\n2,0,NaN,0,0,[]\n";
        assert_eq!(
            err(text),
            "dir/traverse_3.csv:3: y: 'NaN' is not a finite number"
        );
        let text = "frame,x,y,z,detections,boulders\n2,0,0,0,1,\"[(1, inf, 3)]\"\n";
        assert_eq!(
            err(text),
            "dir/traverse_3.csv:2: boulders: tuple 1 has a non-finite coordinate 'inf'"
        );
        let text = "frame,x,y,z,detections,boulders\n2,0,0,0,1,\"[(1, 2, nan)]\"\n";
        assert!(err(text).contains("non-finite coordinate 'nan'"));
    }

    #[test]
    fn short_row_and_bad_integers() {
        assert_eq!(
            err("frame,x,y,z,detections,boulders\n1,0,0\n"),
            "dir/traverse_3.csv:2: expected 6 fields (frame,x,y,z,detections,boulders), the row ends before 'z'"
        );
        assert!(
            err("frame,x,y,z,detections,boulders\n-1,0,0,0,0,[]\n").contains(":2: frame: expected")
        );
        assert!(err("frame,x,y,z,detections,boulders\n1,0,0,0,x,[]\n")
            .contains(":2: detections: expected"));
        assert!(err("frame,x,y,z,detections,boulders\n1,0,0,zz,0,[]\n")
            .contains(":2: z: expected a number, got 'zz'"));
    }

    #[test]
    fn bad_header_and_empty_file() {
        assert!(
            err("a,b,c\n1,2,3\n").starts_with("dir/traverse_3.csv:1: expected the LunarLoc header")
        );
        assert!(err("").contains("the file is empty"));
    }

    #[test]
    fn chunks_keep_line_numbers() {
        let text = "a\nbb\nccc\n\nd";
        let chunks = split_at_lines(text, 2, 3);
        let joined: String = chunks.iter().map(|c| c.1).collect();
        assert_eq!(joined, text);
        for (line, piece) in &chunks {
            let first = piece.lines().next().unwrap_or("");
            let expect = text.lines().nth(line - 2).unwrap();
            assert_eq!(first, expect);
        }
        assert!(split_at_lines("", 2, 3).is_empty());
    }

    #[test]
    fn big_file_parses_in_parallel_and_reports_the_right_line() {
        let mut text = String::from("frame,x,y,z,detections,boulders\n");
        for k in 0..40_000 {
            text.push_str(&format!("{k},1.5,2.5,3.5,1,\"[({k}.25, -1.0, 0.5)]\"\n"));
        }
        let t = parse(&text).unwrap();
        assert_eq!(t.frames.len(), 40_000);
        assert_eq!(t.frames[39_999].boulders[0].x, 39_999.25);
        assert!(t.frames.windows(2).all(|w| w[0].frame + 1 == w[1].frame));
        let bad = text.replace("\n31234,1.5,", "\n31234,nan,");
        assert_eq!(
            parse(&bad).unwrap_err().to_string(),
            "dir/traverse_3.csv:31236: x: 'nan' is not a finite number"
        );
    }

    #[test]
    fn truncated_file_names_last_line() {
        let cut = &SAMPLE[..SAMPLE.len() - 30];
        assert_eq!(
            err(cut),
            "dir/traverse_3.csv:3: boulders: unterminated quoted field"
        );
        let cut = &SAMPLE[..SAMPLE.find("120,-3.5185").unwrap() + 8];
        assert_eq!(
            err(cut),
            "dir/traverse_3.csv:3: expected 6 fields (frame,x,y,z,detections,boulders), the row ends before 'y'"
        );
    }

    #[test]
    fn missing_file_is_io_error_naming_it() {
        let e = read_lunarloc_traverse(Path::new("/nonexistent/traverse_99.csv")).unwrap_err();
        assert!(matches!(e, MapError::Io { .. }));
        assert!(
            e.to_string().contains("/nonexistent/traverse_99.csv"),
            "{e}"
        );
    }

    #[test]
    fn transformed_moves_everything() {
        let t = parse(SAMPLE).unwrap();
        let iso = Isometry3::from_parts(
            Translation3::new(1.0, -2.0, 0.5),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.7),
        );
        let moved = t.transformed(&iso);
        assert_eq!(moved.name, t.name);
        assert_eq!(moved.frames[1].frame, 120);
        let back = moved.transformed(&iso.inverse());
        for (a, b) in back.frames.iter().zip(&t.frames) {
            assert!((a.rover_position - b.rover_position).norm() < 1e-12);
            for (p, q) in a.boulders.iter().zip(&b.boulders) {
                assert!((p - q).norm() < 1e-12);
            }
        }
        assert!((moved.frames[1].boulders[0] - iso * t.frames[1].boulders[0]).norm() < 1e-15);
    }
}
