//! Recall and precision of a segmenter against hand labels of the real LAC pairs
//! (`tests/fixtures/real_rock_labels.csv`): each label is a rock's pixel centre in a left
//! image, of class `rock` (must be found) or `may` (ambiguous: neither a miss nor a false
//! positive).
//!
//! A label is found by a detection whose mask contains it or whose pixel centroid lies
//! within [`LabelMatchConfig::radius_px`] of it. A detection that finds a `rock` label is a
//! true positive; one that finds only `may` labels, or lies beyond
//! [`LabelMatchConfig::max_depth_m`] (outside the labelled range), is not counted; any
//! other detection is a false positive.

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::perception::Mask;

/// Label classes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum LabelClass {
    /// A rock that must be found.
    Rock,
    /// Ambiguous (a pebble, a shape that may be terrain, a rock near the range limit).
    May,
}

/// One labelled rock.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RockLabel {
    /// The pair's name (`1_155` for `1_155_0.png` / `1_155_1.png`).
    pub pair: String,
    /// Pixel column in the full-resolution left image.
    pub u: f64,
    /// Pixel row.
    pub v: f64,
    /// Must be found, or ambiguous.
    pub class: LabelClass,
}

/// Why a label file cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum LabelError {
    /// The file cannot be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// A line is malformed.
    #[error("{path}:{line}: {message}")]
    Format {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
}

/// Read a label CSV: `#` comment lines, a header `pair,u,v,class,...`, then one label per
/// line (extra columns are notes and ignored).
pub fn read_labels(path: &Path) -> Result<Vec<RockLabel>, LabelError> {
    let text = std::fs::read_to_string(path).map_err(|source| LabelError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let err = |line: usize, message: String| LabelError::Format {
        path: path.to_path_buf(),
        line,
        message,
    };
    let mut labels = Vec::new();
    let mut header_seen = false;
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if !header_seen {
            if fields.len() < 4 || fields[..4] != ["pair", "u", "v", "class"] {
                return Err(err(
                    i + 1,
                    format!("expected the header pair,u,v,class,... found {line:?}"),
                ));
            }
            header_seen = true;
            continue;
        }
        if fields.len() < 4 {
            return Err(err(
                i + 1,
                format!("expected at least 4 fields, found {}", fields.len()),
            ));
        }
        let number = |k: usize, name: &str| -> Result<f64, LabelError> {
            fields[k]
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite() && *x >= 0.0)
                .ok_or_else(|| {
                    err(
                        i + 1,
                        format!("{name} {:?} is not a pixel coordinate", fields[k]),
                    )
                })
        };
        let class = match fields[3] {
            "rock" => LabelClass::Rock,
            "may" => LabelClass::May,
            other => {
                return Err(err(
                    i + 1,
                    format!("class {other:?} is neither rock nor may"),
                ))
            }
        };
        labels.push(RockLabel {
            pair: fields[0].to_string(),
            u: number(1, "u")?,
            v: number(2, "v")?,
            class,
        });
    }
    if !header_seen {
        return Err(err(1, "no header line pair,u,v,class".into()));
    }
    Ok(labels)
}

/// How detections are matched to labels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LabelMatchConfig {
    /// A detection whose pixel centroid lies this close to a label finds it, pixels.
    pub radius_px: f64,
    /// Detections farther than this are outside the labelled range and not counted, metres.
    pub max_depth_m: f64,
}

impl Default for LabelMatchConfig {
    fn default() -> Self {
        LabelMatchConfig {
            radius_px: 8.0,
            max_depth_m: 9.0,
        }
    }
}

/// One detection as the scoring sees it.
#[derive(Clone, Debug)]
pub struct ScoredDetection<'a> {
    /// Its mask in full-resolution left-image pixels.
    pub mask: &'a Mask,
    /// Its pixel centroid `[u, v]`.
    pub pixel_centroid: [f64; 2],
    /// Its stereo depth, metres.
    pub depth_m: f64,
}

/// Counts on one pair (or summed over pairs).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct LabelScore {
    /// `rock` labels.
    pub rocks: usize,
    /// `rock` labels found.
    pub found: usize,
    /// Detections that found a `rock` label.
    pub true_positives: usize,
    /// Detections that found no label and lie within the labelled range.
    pub false_positives: usize,
    /// Detections that found only `may` labels or lie beyond the range (not counted).
    pub ignored: usize,
    /// Pixel centroids of the false positives.
    pub false_positive_pixels: Vec<[f64; 2]>,
    /// The `rock` labels missed, `[u, v]`.
    pub missed: Vec<[f64; 2]>,
}

impl LabelScore {
    /// Found rock labels over rock labels (1 when there is none).
    pub fn recall(&self) -> f64 {
        if self.rocks == 0 {
            1.0
        } else {
            self.found as f64 / self.rocks as f64
        }
    }

    /// Counted true positives over counted detections (1 when there is none).
    pub fn precision(&self) -> f64 {
        let n = self.true_positives + self.false_positives;
        if n == 0 {
            1.0
        } else {
            self.true_positives as f64 / n as f64
        }
    }

    /// Add another pair's counts.
    pub fn add(&mut self, other: &LabelScore) {
        self.rocks += other.rocks;
        self.found += other.found;
        self.true_positives += other.true_positives;
        self.false_positives += other.false_positives;
        self.ignored += other.ignored;
    }
}

/// Score one pair's detections against its labels.
pub fn score_pair(
    labels: &[&RockLabel],
    detections: &[ScoredDetection<'_>],
    config: &LabelMatchConfig,
) -> LabelScore {
    let finds = |d: &ScoredDetection<'_>, l: &RockLabel| {
        let (du, dv) = (d.pixel_centroid[0] - l.u, d.pixel_centroid[1] - l.v);
        d.mask.contains(l.u as usize, l.v as usize)
            || (du * du + dv * dv).sqrt() <= config.radius_px
    };
    let mut score = LabelScore::default();
    for l in labels.iter().filter(|l| l.class == LabelClass::Rock) {
        score.rocks += 1;
        if detections.iter().any(|d| finds(d, l)) {
            score.found += 1;
        } else {
            score.missed.push([l.u, l.v]);
        }
    }
    for d in detections {
        let hit_rock = labels
            .iter()
            .any(|l| l.class == LabelClass::Rock && finds(d, l));
        let hit_may = labels
            .iter()
            .any(|l| l.class == LabelClass::May && finds(d, l));
        if hit_rock {
            score.true_positives += 1;
        } else if hit_may || d.depth_m > config.max_depth_m {
            score.ignored += 1;
        } else {
            score.false_positives += 1;
            score.false_positive_pixels.push(d.pixel_centroid);
        }
    }
    score
}

#[cfg(test)]
mod tests {
    use super::*;

    fn label(u: f64, v: f64, class: LabelClass) -> RockLabel {
        RockLabel {
            pair: "p".into(),
            u,
            v,
            class,
        }
    }

    #[test]
    fn found_missed_ignored_and_false_positives() {
        let square = |x0: usize, y0: usize| {
            let px: Vec<_> = (0..10)
                .flat_map(|y| (0..10).map(move |x| (x0 + x, y0 + y)))
                .collect();
            Mask::from_pixels(&px, 1.0).unwrap()
        };
        let (a, b, c, d) = (
            square(0, 0),
            square(100, 100),
            square(200, 200),
            square(300, 0),
        );
        let labels = [
            label(5.0, 5.0, LabelClass::Rock),     // inside a
            label(112.0, 104.0, LabelClass::Rock), // 7.5 px from b's centroid
            label(205.0, 205.0, LabelClass::May),  // inside c
            label(500.0, 500.0, LabelClass::Rock), // missed
        ];
        let refs: Vec<&RockLabel> = labels.iter().collect();
        fn det(mask: &Mask, u: f64, v: f64, depth_m: f64) -> ScoredDetection<'_> {
            ScoredDetection {
                mask,
                pixel_centroid: [u, v],
                depth_m,
            }
        }
        let far = square(400, 0);
        let dets = [
            det(&a, 4.5, 4.5, 3.0),
            det(&b, 104.5, 104.5, 3.0),
            det(&c, 204.5, 204.5, 3.0),
            det(&d, 304.5, 4.5, 3.0),
            det(&far, 404.5, 4.5, 12.0),
        ];
        let s = score_pair(&refs, &dets, &LabelMatchConfig::default());
        assert_eq!((s.rocks, s.found), (3, 2));
        assert_eq!((s.true_positives, s.false_positives, s.ignored), (2, 1, 2));
        assert_eq!(s.missed, vec![[500.0, 500.0]]);
        assert!((s.recall() - 2.0 / 3.0).abs() < 1e-12);
        assert!((s.precision() - 2.0 / 3.0).abs() < 1e-12);
    }

    #[test]
    fn bad_lines_name_the_line() {
        let dir = std::env::temp_dir().join(format!("segloc-labels-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("l.csv");
        std::fs::write(
            &path,
            "# c\npair,u,v,class,note\n1_155,3,4,rock,x\n1_155,3,4,big\n",
        )
        .unwrap();
        let e = read_labels(&path).unwrap_err().to_string();
        assert!(e.contains(":4:") && e.contains("big"), "{e}");
        std::fs::write(&path, "pair,u,v,class\n1_155,3,4,may\n").unwrap();
        let l = read_labels(&path).unwrap();
        assert_eq!(l[0].class, LabelClass::May);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
