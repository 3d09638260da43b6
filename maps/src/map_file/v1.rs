//! Map file format version 1: the on-disk structs and their conversion to/from
//! [`ObjectMap`].

use std::collections::BTreeMap;
use std::fmt::Write as _;

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

use super::{MAP_FORMAT_NAME, MAP_FORMAT_VERSION};
use crate::landmark::{from_upper_triangle, upper_triangle};
use crate::{Landmark, ObjectMap};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MapFileV1 {
    #[allow(dead_code)] // checked by the caller before this struct is parsed
    format: String,
    #[allow(dead_code)]
    version: u32,
    frame: String,
    session: String,
    gravity_aligned: bool,
    #[serde(default)]
    notes: BTreeMap<String, String>,
    landmarks: Vec<LandmarkV1>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct LandmarkV1 {
    id: u32,
    /// Centroid, metres.
    p: [f64; 3],
    /// Upper triangle `[xx, xy, xz, yy, yz, zz]`, m².
    cov: [f64; 6],
    #[serde(default)]
    size_m: Option<f64>,
    #[serde(default = "one")]
    observations: u32,
    #[serde(default)]
    sessions: Vec<String>,
}

fn one() -> u32 {
    1
}

impl From<LandmarkV1> for Landmark {
    fn from(l: LandmarkV1) -> Self {
        Landmark {
            id: l.id,
            position: Point3::new(l.p[0], l.p[1], l.p[2]),
            covariance: from_upper_triangle(l.cov),
            size_m: l.size_m,
            observations: l.observations,
            sessions: l.sessions,
        }
    }
}

impl From<&Landmark> for LandmarkV1 {
    fn from(l: &Landmark) -> Self {
        LandmarkV1 {
            id: l.id,
            p: [l.position.x, l.position.y, l.position.z],
            cov: upper_triangle(&l.covariance),
            size_m: l.size_m,
            observations: l.observations,
            sessions: l.sessions.clone(),
        }
    }
}

/// Parse a version-1 file into the current model (no validation).
pub(super) fn parse(text: &str) -> Result<ObjectMap, serde_json::Error> {
    let file: MapFileV1 = serde_json::from_str(text)?;
    Ok(ObjectMap {
        frame: file.frame,
        session: file.session,
        gravity_aligned: file.gravity_aligned,
        landmarks: file.landmarks.into_iter().map(Landmark::from).collect(),
        notes: file.notes,
    })
}

/// Write the current model as a version-1 file: pretty header, one landmark per line.
pub(super) fn to_string(map: &ObjectMap) -> String {
    let mut s = String::with_capacity(256 + map.landmarks.len() * 200);
    s.push_str("{\n");
    let _ = writeln!(s, "  \"format\": {},", json(MAP_FORMAT_NAME));
    let _ = writeln!(s, "  \"version\": {MAP_FORMAT_VERSION},");
    let _ = writeln!(s, "  \"frame\": {},", json(&map.frame));
    let _ = writeln!(s, "  \"session\": {},", json(&map.session));
    let _ = writeln!(s, "  \"gravity_aligned\": {},", map.gravity_aligned);
    let _ = writeln!(s, "  \"notes\": {},", json(&map.notes));
    if map.landmarks.is_empty() {
        s.push_str("  \"landmarks\": []\n");
    } else {
        s.push_str("  \"landmarks\": [\n");
        for (k, l) in map.landmarks.iter().enumerate() {
            let sep = if k + 1 < map.landmarks.len() { "," } else { "" };
            let _ = writeln!(s, "    {}{sep}", json(&LandmarkV1::from(l)));
        }
        s.push_str("  ]\n");
    }
    s.push_str("}\n");
    s
}

/// Compact JSON text of a value. Serialising strings, string maps, integers and floats
/// cannot fail (non-finite floats become `null`), so the fallback is never used.
fn json<T: Serialize + ?Sized>(v: &T) -> String {
    serde_json::to_string(v).unwrap_or_else(|_| "null".to_string())
}
