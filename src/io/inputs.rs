//! A map from any input file: a segloc map file, a segloc detections CSV, or a LunarLoc
//! traverse CSV (detections are fused into landmarks with the given parameters).

use crate::landmarks::{fuse_detections, FusionConfig};
use segloc_maps::{read_any_detections, read_map, MapError, ObjectMap};
use std::io::Read;
use std::path::Path;

/// What kind of file an input was.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputKind {
    /// A segloc map file (JSON).
    MapFile,
    /// Detections (segloc CSV or LunarLoc traverse), fused into a map.
    Detections,
}

/// Load `path` as a map: map files are read as they are; detection files are fused.
pub fn load_map(path: &Path, fusion: &FusionConfig) -> Result<(ObjectMap, InputKind), MapError> {
    if looks_like_json(path)? {
        return Ok((read_map(path)?, InputKind::MapFile));
    }
    let set = read_any_detections(path)?;
    let mut map = fuse_detections(&set, fusion);
    map.notes
        .insert("source".into(), path.display().to_string());
    Ok((map, InputKind::Detections))
}

/// Whether the file's first non-blank byte opens a JSON object.
fn looks_like_json(path: &Path) -> Result<bool, MapError> {
    let mut head = [0u8; 256];
    let mut file = std::fs::File::open(path).map_err(|e| MapError::read_io(path, e))?;
    let n = file
        .read(&mut head)
        .map_err(|e| MapError::read_io(path, e))?;
    Ok(head[..n]
        .iter()
        .find(|b| !b.is_ascii_whitespace())
        .is_some_and(|&b| b == b'{'))
}
