//! Object maps of boulder landmarks and the file formats around them.
//!
//! - [`ObjectMap`] / [`Landmark`]: boulder centroids with covariance and provenance, in one
//!   frame; read and written as a versioned JSON file ([`read_map`], [`write_map`]; format
//!   in `maps/FORMAT.md` and [`map_file`]).
//! - [`Traverse`]: a LunarLoc `traverse_N.csv` (rover trajectory + boulder detections),
//!   [`read_lunarloc_traverse`].
//! - [`DetectionSet`]: boulder detections of one session; segloc's own detections CSV
//!   ([`read_detections`], [`write_detections`]) and [`read_any_detections`], which also
//!   takes a traverse.
//! - [`LacGrid`]: the Lunar Autonomy Challenge 180 × 180 height / rock grid and its CSV
//!   ([`read_grid_csv`], [`write_grid_csv`]).
//! - [`RockRaster`]: a rock mask from above (PNG or CSV) placed by its corner and cell size,
//!   with optional heights ([`read_rock_mask`], [`read_heights_into`]).
//! - [`StreamFrame`]: one camera frame of a recorded drive (odometry pose, gravity, boulder
//!   detections in the rover frame), for replaying it through the online localizer; the
//!   JSON Lines frames file ([`read_frames`], [`write_frames`]).
//! - [`isometry_from_matrix`]: a rigid transform from a 4 × 4 homogeneous matrix.
//! - TUM trajectories (`t tx ty tz qx qy qz qw`, as `evo` reads them): [`read_tum`],
//!   [`write_tum`].
//!
//! Every reader returns a [`MapError`] naming the file (and line) on bad input; every writer
//! is atomic (temporary file in the same directory, then rename).
#![warn(missing_docs)]
#![warn(clippy::too_many_lines)]

pub mod atomic;
pub mod detections;
pub mod error;
pub mod frames;
pub mod grid;
pub mod landmark;
pub mod map_file;
pub mod object_map;
pub mod point_list;
pub mod raster;
pub mod rigid;
pub mod traverse;
pub mod tum;

pub use atomic::write_atomic;
pub use detections::{
    detections_to_string, parse_detections, read_any_detections, read_detections, write_detections,
    Detection, DetectionSet, DETECTIONS_FORMAT_VERSION, DETECTIONS_HEADER,
};
pub use error::{LineError, MapError};
pub use frames::{
    frame_to_json_line, parse_frames, read_frames, write_frames, FrameDetection, FramePath,
    FramesFile, StreamFrame, FRAMES_FORMAT_NAME, FRAMES_FORMAT_VERSION,
};
pub use grid::{
    grid_to_string, parse_grid_csv, read_grid_csv, write_grid_csv, LacGrid, GRID_HEADER,
    LAC_CELLS_PER_SIDE, LAC_CELL_SIZE_M,
};
pub use landmark::{check_covariance, CovarianceError, Landmark, LandmarkError};
pub use map_file::{
    map_from_str, map_to_string, read_map, write_map, MAP_FORMAT_NAME, MAP_FORMAT_VERSION,
};
pub use object_map::ObjectMap;
pub use point_list::parse_point_list;
pub use raster::{read_heights_into, read_rock_mask, RockRaster};
pub use rigid::{isometry_from_matrix, RigidError, RIGID_TOLERANCE};
pub use traverse::{
    parse_lunarloc_traverse, read_lunarloc_traverse, Traverse, TraverseFrame, TRAVERSE_HEADER,
};
pub use tum::{parse_tum, read_tum, tum_to_string, write_tum, TUM_HEADER};
