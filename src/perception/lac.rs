//! `.lac` recordings of the Lunar Autonomy Challenge: a gzip-compressed tarball holding
//!
//! ```text
//! metadata.toml                       what was recorded (free-form table)
//! initial.toml                        the initial state (free-form; [rover] pose if known)
//! frames.csv                          one row per simulator frame: frame, time, pose, IMU
//! cameras/<cam>/<cam>_frames.csv      the frames at which <cam> has images
//! cameras/<cam>/grayscale/<cam>_grayscale_<frame>.png
//! cameras/<cam>/semantic/<cam>_semantic_<frame>.png
//! ```
//!
//! `frames.csv` columns are found by name: `frame` (required), `time` / `timestamp` /
//! `mission_time` (seconds), the pose `x, y, z, roll, pitch, yaw` (metres, radians; world
//! from rover) and the IMU `accel_x, accel_y, accel_z, gyro_x, gyro_y, gyro_z`; others are
//! ignored. Images are found by path: any PNG under `cameras/<cam>/` whose name ends in
//! `_<frame>.png` (semantic if its path says so, grayscale otherwise).
//!
//! [`LacRecording::open`] reads a recording for playback frame by frame; [`LacWriter`]
//! writes one (the repository builds its own small test archives with it).

use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use super::gray_image::{decode_gray_png, encode_gray_png};
use super::{GrayImage, PerceptionError};

/// The IMU reading of one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Imu {
    /// Linear acceleration (x, y, z), m/s².
    pub accel: [f64; 3],
    /// Angular rate (x, y, z), rad/s.
    pub gyro: [f64; 3],
}

/// One row of `frames.csv`.
#[derive(Clone, Debug, PartialEq)]
pub struct LacFrame {
    /// Simulator frame number.
    pub frame: u64,
    /// Mission time, seconds, when recorded.
    pub time_s: Option<f64>,
    /// Rover pose `world_from_rover`, when recorded.
    pub pose: Option<Isometry3<f64>>,
    /// IMU reading, when recorded.
    pub imu: Option<Imu>,
}

/// Image kinds stored per camera.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum ImageKind {
    /// 8-bit grayscale camera image.
    Grayscale,
    /// Semantic label image.
    Semantic,
}

impl ImageKind {
    fn dir(self) -> &'static str {
        match self {
            ImageKind::Grayscale => "grayscale",
            ImageKind::Semantic => "semantic",
        }
    }
}

/// The front stereo pair's left camera in a recording.
pub const FRONT_LEFT: &str = "FrontLeft";
/// The front stereo pair's right camera in a recording.
pub const FRONT_RIGHT: &str = "FrontRight";

/// A `.lac` recording held in memory (images stay PNG-encoded until asked for).
#[derive(Clone, Debug)]
pub struct LacRecording {
    /// Where it was read from.
    pub path: PathBuf,
    /// `metadata.toml`.
    pub metadata: toml::Table,
    /// `initial.toml`.
    pub initial: toml::Table,
    /// `frames.csv`, in file order.
    pub frames: Vec<LacFrame>,
    /// For each camera, the frames listed in its `<cam>_frames.csv`.
    pub camera_frames: BTreeMap<String, Vec<u64>>,
    images: BTreeMap<(String, ImageKind, u64), Vec<u8>>,
}

impl LacRecording {
    /// Read a recording. Truncated or corrupt archives and missing required members are
    /// errors naming the archive (and the member).
    pub fn open(path: &Path) -> Result<LacRecording, PerceptionError> {
        let file = std::fs::File::open(path).map_err(|e| PerceptionError::io(path, e))?;
        Self::from_reader(file, path)
    }

    /// Read a recording from any byte stream; `path` names it in errors.
    pub fn from_reader(reader: impl Read, path: &Path) -> Result<LacRecording, PerceptionError> {
        let mut members = read_members(reader, path)?;
        // some recordings wrap everything in one top-level folder
        let prefix = members
            .keys()
            .find(|k| k.ends_with("frames.csv") && !k.contains("cameras/"))
            .map(|k| k.trim_end_matches("frames.csv").to_string())
            .unwrap_or_default();
        let metadata = take_table(&mut members, &prefix, "metadata.toml", path)?;
        let initial = take_table(&mut members, &prefix, "initial.toml", path)?;
        let frames = take_frames(&mut members, &prefix, path)?;
        let (camera_frames, images) = camera_members(members, &prefix, path)?;
        Ok(LacRecording {
            path: path.to_path_buf(),
            metadata,
            initial,
            frames,
            camera_frames,
            images,
        })
    }

    /// The cameras that have images.
    pub fn cameras(&self) -> Vec<String> {
        let mut c: Vec<String> = self.images.keys().map(|k| k.0.clone()).collect();
        c.dedup();
        c
    }

    /// The frames at which both cameras have a grayscale image, ascending.
    pub fn stereo_frames(&self, left: &str, right: &str) -> Vec<u64> {
        self.images
            .keys()
            .filter(|(c, k, f)| {
                c == left
                    && *k == ImageKind::Grayscale
                    && self
                        .images
                        .contains_key(&(right.to_string(), ImageKind::Grayscale, *f))
            })
            .map(|k| k.2)
            .collect()
    }

    /// The image of `camera` at `frame` (`None` if not recorded; an error if undecodable).
    pub fn image(
        &self,
        camera: &str,
        kind: ImageKind,
        frame: u64,
    ) -> Result<Option<GrayImage>, PerceptionError> {
        let Some(bytes) = self.images.get(&(camera.to_string(), kind, frame)) else {
            return Ok(None);
        };
        let member = self.path.join(format!(
            "cameras/{camera}/{}/{camera}_{}_{frame}.png",
            kind.dir(),
            kind.dir()
        ));
        decode_gray_png(bytes, &member).map(Some)
    }

    /// The frames at which both front cameras ([`FRONT_LEFT`], [`FRONT_RIGHT`]) have a
    /// grayscale image, ascending; an error naming the recording's cameras when there is none.
    pub fn front_stereo_frames(&self) -> Result<Vec<u64>, PerceptionError> {
        let frames = self.stereo_frames(FRONT_LEFT, FRONT_RIGHT);
        if frames.is_empty() {
            return Err(PerceptionError::Archive {
                path: self.path.clone(),
                message: format!(
                    "no frame has both {FRONT_LEFT} and {FRONT_RIGHT} grayscale images \
                     (cameras: {:?})",
                    self.cameras()
                ),
            });
        }
        Ok(frames)
    }

    /// The front stereo pair's grayscale images (left, right) at `frame`; an error naming
    /// the missing one.
    pub fn front_pair(&self, frame: u64) -> Result<(GrayImage, GrayImage), PerceptionError> {
        let image = |camera: &str| {
            self.image(camera, ImageKind::Grayscale, frame)?
                .ok_or_else(|| PerceptionError::Archive {
                    path: self.path.clone(),
                    message: format!("frame {frame} has no {camera} grayscale image"),
                })
        };
        Ok((image(FRONT_LEFT)?, image(FRONT_RIGHT)?))
    }

    /// The `frames.csv` row of `frame`, if any.
    pub fn frame(&self, frame: u64) -> Option<&LacFrame> {
        self.frames.iter().find(|f| f.frame == frame)
    }
}

/// Images by (camera, kind, frame), PNG-encoded.
type EncodedImages = BTreeMap<(String, ImageKind, u64), Vec<u8>>;

/// The file members of the gzip tarball `reader` (`path` names it in errors), by name
/// without a leading `./`.
fn read_members(
    reader: impl Read,
    path: &Path,
) -> Result<BTreeMap<String, Vec<u8>>, PerceptionError> {
    let bad = |m: String| PerceptionError::archive(path, m);
    let mut archive = tar::Archive::new(flate2::read::GzDecoder::new(reader));
    let mut members: BTreeMap<String, Vec<u8>> = BTreeMap::new();
    let entries = archive
        .entries()
        .map_err(|e| bad(format!("not a gzip tarball: {e}")))?;
    for entry in entries {
        let mut entry = entry.map_err(|e| bad(format!("truncated or corrupt archive: {e}")))?;
        if !entry.header().entry_type().is_file() {
            continue;
        }
        let name = entry
            .path()
            .map_err(|e| bad(format!("bad member name: {e}")))?
            .to_string_lossy()
            .trim_start_matches("./")
            .to_string();
        let bytes = read_member(&mut entry, &name, path)?;
        members.insert(name, bytes);
    }
    Ok(members)
}

/// The data of archive member `name`; an error when shorter than its header says.
fn read_member<R: Read>(
    entry: &mut tar::Entry<'_, R>,
    name: &str,
    path: &Path,
) -> Result<Vec<u8>, PerceptionError> {
    let bad = |m: String| PerceptionError::archive(path, m);
    // the size is the header's word: reserve at most 1 MiB up front (the data
    // read decides the rest), and a member shorter than its header says is truncated
    let size = entry.size();
    let mut bytes = Vec::with_capacity(size.min(1 << 20) as usize);
    entry
        .read_to_end(&mut bytes)
        .map_err(|e| bad(format!("{name}: truncated or corrupt: {e}")))?;
    if bytes.len() as u64 != size {
        return Err(bad(format!(
            "{name}: truncated: the header says {size} bytes, the archive holds {}",
            bytes.len()
        )));
    }
    Ok(bytes)
}

/// Member `name`'s bytes as text.
fn member_text(bytes: Vec<u8>, name: &str, path: &Path) -> Result<String, PerceptionError> {
    String::from_utf8(bytes)
        .map_err(|_| PerceptionError::archive(path, format!("{name}: not UTF-8 text")))
}

/// Remove the required TOML member `prefix` + `name` from `members` and parse it.
fn take_table(
    members: &mut BTreeMap<String, Vec<u8>>,
    prefix: &str,
    name: &str,
    path: &Path,
) -> Result<toml::Table, PerceptionError> {
    let bad = |m: String| PerceptionError::archive(path, m);
    let bytes = members
        .remove(&format!("{prefix}{name}"))
        .ok_or_else(|| bad(format!("missing {name}")))?;
    member_text(bytes, name, path)?
        .parse::<toml::Table>()
        .map_err(|e| bad(format!("{name}: {e}")))
}

/// Remove the required member `prefix` + `frames.csv` from `members` and parse it.
fn take_frames(
    members: &mut BTreeMap<String, Vec<u8>>,
    prefix: &str,
    path: &Path,
) -> Result<Vec<LacFrame>, PerceptionError> {
    let bad = |m: String| PerceptionError::archive(path, m);
    let frames_csv = members
        .remove(&format!("{prefix}frames.csv"))
        .ok_or_else(|| bad("missing frames.csv".into()))?;
    parse_frames(&member_text(frames_csv, "frames.csv", path)?)
        .map_err(|m| bad(format!("frames.csv: {m}")))
}

/// Each camera's frame list and images (still PNG-encoded) among the members under
/// `prefix` + `cameras/`; other members are ignored.
fn camera_members(
    members: BTreeMap<String, Vec<u8>>,
    prefix: &str,
    path: &Path,
) -> Result<(BTreeMap<String, Vec<u64>>, EncodedImages), PerceptionError> {
    let mut camera_frames = BTreeMap::new();
    let mut images = BTreeMap::new();
    for (name, bytes) in members {
        let Some(rest) = name.strip_prefix(&format!("{prefix}cameras/")) else {
            continue;
        };
        let Some((camera, file)) = rest.split_once('/') else {
            continue;
        };
        let base = file.rsplit('/').next().unwrap_or(file);
        if base == format!("{camera}_frames.csv") {
            let list = parse_camera_frames(&member_text(bytes, &name, path)?)
                .map_err(|m| PerceptionError::archive(path, format!("{name}: {m}")))?;
            camera_frames.insert(camera.to_string(), list);
        } else if let Some(stem) = base.strip_suffix(".png") {
            let Some(frame) = stem.rsplit('_').next().and_then(|f| f.parse::<u64>().ok()) else {
                continue;
            };
            let kind = if file.contains("semantic") {
                ImageKind::Semantic
            } else {
                ImageKind::Grayscale
            };
            images.insert((camera.to_string(), kind, frame), bytes);
        }
    }
    Ok((camera_frames, images))
}

/// What is wrong with a CSV member of a `.lac` archive (the reader adds the member's name).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum LacCsvError {
    /// No header line.
    #[error("empty file")]
    Empty,
    /// The header has no `frame` column.
    #[error("no `frame` column")]
    NoFrameColumn,
    /// A line has a different number of fields than the header.
    #[error("line {line}: {found} fields, header has {expected}")]
    FieldCount {
        /// Line number (1-based).
        line: usize,
        /// Fields on the line.
        found: usize,
        /// Fields in the header.
        expected: usize,
    },
    /// A field that must be a number is not.
    #[error("line {line}: `{text}` is not a number")]
    NotANumber {
        /// Line number (1-based).
        line: usize,
        /// The field.
        text: String,
    },
    /// A frame number of `frames.csv` is not a non-negative integer.
    #[error("line {line}: bad frame `{text}`")]
    BadFrame {
        /// Line number (1-based).
        line: usize,
        /// The field.
        text: String,
    },
    /// A frame number of a camera's frame list is not a non-negative integer.
    #[error("bad frame `{0}`")]
    BadCameraFrame(String),
}

fn parse_frames(text: &str) -> Result<Vec<LacFrame>, LacCsvError> {
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let (_, header) = lines.next().ok_or(LacCsvError::Empty)?;
    let cols: Vec<&str> = header.split(',').map(str::trim).collect();
    let col = |names: &[&str]| cols.iter().position(|c| names.contains(c));
    let frame_col = col(&["frame"]).ok_or(LacCsvError::NoFrameColumn)?;
    let time_col = col(&["time", "timestamp", "mission_time"]);
    let pose_cols: Option<Vec<usize>> = ["x", "y", "z", "roll", "pitch", "yaw"]
        .iter()
        .map(|n| col(&[n]))
        .collect();
    let imu_cols: Option<Vec<usize>> = [
        "accel_x", "accel_y", "accel_z", "gyro_x", "gyro_y", "gyro_z",
    ]
    .iter()
    .map(|n| col(&[n]))
    .collect();
    let mut out = Vec::new();
    for (i, line) in lines {
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != cols.len() {
            return Err(LacCsvError::FieldCount {
                line: i + 1,
                found: fields.len(),
                expected: cols.len(),
            });
        }
        let num = |c: usize| -> Result<f64, LacCsvError> {
            fields[c]
                .parse::<f64>()
                .map_err(|_| LacCsvError::NotANumber {
                    line: i + 1,
                    text: fields[c].to_string(),
                })
        };
        let frame = fields[frame_col]
            .parse::<u64>()
            .map_err(|_| LacCsvError::BadFrame {
                line: i + 1,
                text: fields[frame_col].to_string(),
            })?;
        let time_s = time_col.map(num).transpose()?.filter(|t| t.is_finite());
        let pose = match &pose_cols {
            Some(c) => {
                let v: Vec<f64> = c.iter().map(|&c| num(c)).collect::<Result<_, _>>()?;
                v.iter().all(|v| v.is_finite()).then(|| {
                    Isometry3::from_parts(
                        Translation3::from(Vector3::new(v[0], v[1], v[2])),
                        UnitQuaternion::from_euler_angles(v[3], v[4], v[5]),
                    )
                })
            }
            None => None,
        };
        let imu = match &imu_cols {
            Some(c) => {
                let v: Vec<f64> = c.iter().map(|&c| num(c)).collect::<Result<_, _>>()?;
                v.iter().all(|v| v.is_finite()).then(|| Imu {
                    accel: [v[0], v[1], v[2]],
                    gyro: [v[3], v[4], v[5]],
                })
            }
            None => None,
        };
        out.push(LacFrame {
            frame,
            time_s,
            pose,
            imu,
        });
    }
    Ok(out)
}

fn parse_camera_frames(text: &str) -> Result<Vec<u64>, LacCsvError> {
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    let header = lines.next().ok_or(LacCsvError::Empty)?;
    let c = header
        .split(',')
        .position(|h| h.trim() == "frame")
        .ok_or(LacCsvError::NoFrameColumn)?;
    lines
        .map(|l| {
            let f = l.split(',').nth(c).unwrap_or("").trim();
            f.parse::<u64>()
                .map_err(|_| LacCsvError::BadCameraFrame(f.to_string()))
        })
        .collect()
}

/// Builds a `.lac` recording in memory and writes it as a gzip tarball.
#[derive(Clone, Debug, Default)]
pub struct LacWriter {
    metadata: toml::Table,
    initial: toml::Table,
    frames: Vec<LacFrame>,
    images: BTreeMap<(String, ImageKind, u64), GrayImage>,
}

impl LacWriter {
    /// A writer with these `metadata.toml` and `initial.toml` tables.
    pub fn new(metadata: toml::Table, initial: toml::Table) -> Self {
        LacWriter {
            metadata,
            initial,
            ..Default::default()
        }
    }

    /// Add a `frames.csv` row.
    pub fn add_frame(&mut self, frame: LacFrame) {
        self.frames.push(frame);
    }

    /// Add an image of `camera` at `frame`.
    pub fn add_image(&mut self, camera: &str, kind: ImageKind, frame: u64, image: GrayImage) {
        self.images.insert((camera.to_string(), kind, frame), image);
    }

    /// The archive's bytes.
    pub fn to_bytes(&self) -> Result<Vec<u8>, PerceptionError> {
        let io = |e: std::io::Error| PerceptionError::io("<lac archive>", e);
        let encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        let mut tar = tar::Builder::new(encoder);
        let add = |tar: &mut tar::Builder<_>, name: &str, bytes: &[u8]| {
            let mut header = tar::Header::new_gnu();
            header.set_size(bytes.len() as u64);
            header.set_mode(0o644);
            header.set_cksum();
            tar.append_data(&mut header, name, bytes).map_err(io)
        };
        let to_toml = |t: &toml::Table| toml::to_string(t).unwrap_or_default();
        add(
            &mut tar,
            "metadata.toml",
            to_toml(&self.metadata).as_bytes(),
        )?;
        add(&mut tar, "initial.toml", to_toml(&self.initial).as_bytes())?;
        let mut csv = String::from(
            "frame,time,x,y,z,roll,pitch,yaw,accel_x,accel_y,accel_z,gyro_x,gyro_y,gyro_z\n",
        );
        for f in &self.frames {
            let opt = |v: Option<f64>| v.map(|v| format!("{v:?}")).unwrap_or_else(|| "nan".into());
            let (t, rpy) = match &f.pose {
                Some(p) => (Some(p.translation.vector), Some(p.rotation.euler_angles())),
                None => (None, None),
            };
            let imu = f.imu.map(|i| [i.accel, i.gyro].concat());
            let mut row = vec![f.frame.to_string(), opt(f.time_s)];
            row.extend((0..3).map(|k| opt(t.map(|t| t[k]))));
            row.extend([
                opt(rpy.map(|r| r.0)),
                opt(rpy.map(|r| r.1)),
                opt(rpy.map(|r| r.2)),
            ]);
            row.extend((0..6).map(|k| opt(imu.as_ref().map(|v| v[k]))));
            csv.push_str(&row.join(","));
            csv.push('\n');
        }
        add(&mut tar, "frames.csv", csv.as_bytes())?;
        let mut per_camera: BTreeMap<&str, Vec<u64>> = BTreeMap::new();
        for ((camera, kind, frame), image) in &self.images {
            let dir = kind.dir();
            let name = format!("cameras/{camera}/{dir}/{camera}_{dir}_{frame}.png");
            add(&mut tar, &name, &encode_gray_png(image)?)?;
            per_camera.entry(camera).or_default().push(*frame);
        }
        for (camera, mut list) in per_camera {
            list.sort_unstable();
            list.dedup();
            let mut text = String::from("frame\n");
            for f in list {
                text.push_str(&format!("{f}\n"));
            }
            add(
                &mut tar,
                &format!("cameras/{camera}/{camera}_frames.csv"),
                text.as_bytes(),
            )?;
        }
        let encoder = tar.into_inner().map_err(io)?;
        encoder.finish().map_err(io)
    }

    /// Write the archive to `path`.
    pub fn write(&self, path: &Path) -> Result<(), PerceptionError> {
        let bytes = self.to_bytes()?;
        std::fs::write(path, bytes).map_err(|e| PerceptionError::io(path, e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> LacWriter {
        let mut meta = toml::Table::new();
        meta.insert("description".into(), "test".into());
        let mut w = LacWriter::new(meta, toml::Table::new());
        for f in [10u64, 20] {
            w.add_frame(LacFrame {
                frame: f,
                time_s: Some(f as f64 * 0.05),
                pose: Some(Isometry3::from_parts(
                    Translation3::new(1.0, 2.0, 0.5),
                    UnitQuaternion::from_euler_angles(0.0, 0.1, 0.3),
                )),
                imu: Some(Imu {
                    accel: [0.0, 0.0, 1.622],
                    gyro: [0.0, 0.0, 0.1],
                }),
            });
            let img = GrayImage::new(4, 2, vec![f as u8; 8]).unwrap();
            w.add_image("FrontLeft", ImageKind::Grayscale, f, img.clone());
            w.add_image("FrontRight", ImageKind::Grayscale, f, img.clone());
            w.add_image("FrontLeft", ImageKind::Semantic, f, img);
        }
        w
    }

    #[test]
    fn round_trip() {
        let bytes = sample().to_bytes().unwrap();
        let r = LacRecording::from_reader(&bytes[..], Path::new("t.lac")).unwrap();
        assert_eq!(r.metadata["description"].as_str(), Some("test"));
        assert_eq!(r.frames.len(), 2);
        let f = r.frame(20).unwrap();
        assert_eq!(f.time_s, Some(1.0));
        let p = f.pose.unwrap();
        assert!((p.translation.vector - Vector3::new(1.0, 2.0, 0.5)).norm() < 1e-12);
        assert!((p.rotation.euler_angles().2 - 0.3).abs() < 1e-12);
        assert_eq!(f.imu.unwrap().accel[2], 1.622);
        assert_eq!(r.stereo_frames("FrontLeft", "FrontRight"), vec![10, 20]);
        assert_eq!(r.camera_frames["FrontLeft"], vec![10, 20]);
        let img = r
            .image("FrontLeft", ImageKind::Grayscale, 20)
            .unwrap()
            .unwrap();
        assert_eq!(img.data, vec![20u8; 8]);
        assert!(r
            .image("FrontRight", ImageKind::Semantic, 20)
            .unwrap()
            .is_none());
    }

    /// Fuzz regression (issue 25 §3): a member header claiming 1 TiB reserved that much
    /// before reading (the process aborted); the member is now a truncation error.
    #[test]
    fn fuzz_huge_member_size_is_an_error_not_an_allocation() {
        let mut header = tar::Header::new_gnu();
        header.set_path("frames.csv").unwrap();
        header.set_size(1 << 40);
        header.set_mode(0o644);
        header.set_cksum();
        let mut tar = header.as_bytes().to_vec();
        tar.extend_from_slice(b"frame\n");
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        std::io::Write::write_all(&mut gz, &tar).unwrap();
        let bytes = gz.finish().unwrap();
        let err = LacRecording::from_reader(&bytes[..], Path::new("t.lac"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("t.lac") && err.contains("frames.csv"), "{err}");
    }

    #[test]
    fn truncated_archive_is_a_clear_error() {
        let bytes = sample().to_bytes().unwrap();
        for cut in [bytes.len() / 2, 30, 5] {
            let err = LacRecording::from_reader(&bytes[..cut], Path::new("cut.lac")).unwrap_err();
            let text = err.to_string();
            assert!(text.contains("cut.lac"), "{text}");
        }
    }
}
