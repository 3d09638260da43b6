//! Scoring boulder detections of a rendered stereo pair against the renderer's truth.
//!
//! A detection is true when its centroid is within `match_size_fraction` × size (the rock's
//! diameter) of a rock's visible surface centre and within `match_max_range_m` of the
//! camera; each rock matches at most one detection (nearest first). Recall counts the rocks
//! of at least `min_size_m` within `max_range_m` that are seen whole (not cut by the image
//! border, at least `min_visible_fraction` unoccluded); precision counts the detections
//! within `max_range_m`.
//!
//! Shared by the front end's evaluation on rendered frames (`eval::render_front_end`) and
//! the mission on rendered images ([`crate::sim::rendered_boulders`]).

use super::truth::{StereoFrame, LANDER_INSTANCE};
use crate::perception::Boulder;
use nalgebra::Point3;
use serde::{Deserialize, Serialize};

/// What counts and what matches (every field has a default: the definition).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MatchConfig {
    /// Smallest rock size (diameter) counted for recall, metres.
    pub min_size_m: f64,
    /// Farthest rock (visible centre) or detection counted, metres from the left camera.
    pub max_range_m: f64,
    /// A detection matches a rock within this fraction of the rock's size.
    pub match_size_fraction: f64,
    /// A detection farther than this from the camera is never true, metres.
    pub match_max_range_m: f64,
    /// Rocks less visible than this (occluded) are not counted for recall.
    pub min_visible_fraction: f64,
    /// Rocks with a pixel within this many pixels of the image border are not counted.
    pub border_margin_px: usize,
}

impl Default for MatchConfig {
    fn default() -> Self {
        MatchConfig {
            min_size_m: 0.10,
            max_range_m: 6.0,
            match_size_fraction: 0.3,
            match_max_range_m: 8.0,
            min_visible_fraction: 0.5,
            border_margin_px: 3,
        }
    }
}

/// A truth rock of one frame and what became of it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RockOutcome {
    /// Rock index in the moon.
    pub id: usize,
    /// Distance of its visible centre from the left camera, metres.
    pub range_m: f64,
    /// Diameter, metres.
    pub size_m: f64,
    /// Pixels in the left image.
    pub pixels: usize,
    /// Whether recall counts it (size, range, visibility, border).
    pub counted: bool,
    /// Distance from the matched detection's centroid to the visible centre, metres.
    pub error_m: Option<f64>,
}

/// A detection of one frame and what it matched.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DetectionOutcome {
    /// Distance of its centroid from the left camera, metres.
    pub range_m: f64,
    /// Its size, metres.
    pub size_m: f64,
    /// Centroid, left-image pixels.
    pub pixel_centroid: [f64; 2],
    /// Index of the matched rock in the moon, if any.
    pub rock: Option<usize>,
    /// Whether the centroid lies on the lander or a rock's pixels, else ground (for the
    /// false positives' causes): "rock", "lander", "ground" or "sky".
    pub on: &'static str,
    /// The rock under the centroid pixel when it matched none: its id, its size (metres)
    /// and the detection's distance to its visible centre (metres). Tells a depth error on
    /// a rock from a rock below the counted size.
    pub unmatched_on_rock: Option<(usize, f64, f64)>,
}

/// The score of one frame.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FrameScore {
    /// Seed of the moon.
    pub seed: u64,
    /// Sun elevation, degrees.
    pub sun_elevation_deg: f64,
    /// Simulator tick of the frame.
    pub tick: usize,
    /// The rocks seen.
    pub rocks: Vec<RockOutcome>,
    /// The detections.
    pub detections: Vec<DetectionOutcome>,
    /// Rendering time of the pair, milliseconds.
    pub render_ms: f64,
    /// Front-end time of the pair, milliseconds.
    pub front_end_ms: f64,
}

/// Median and tail of a set of values (timings, centroid errors).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Quantiles {
    /// 50th percentile.
    pub median: f64,
    /// 90th percentile.
    pub p90: f64,
    /// 99th percentile.
    pub p99: f64,
}

impl Quantiles {
    /// The [`quantile`]s 0.5, 0.9 and 0.99 of `values` (NaN when empty), sorting once.
    pub fn of(values: &[f64]) -> Quantiles {
        let sorted = sorted(values);
        Quantiles {
            median: quantile_of_sorted(&sorted, 0.5),
            p90: quantile_of_sorted(&sorted, 0.9),
            p99: quantile_of_sorted(&sorted, 0.99),
        }
    }
}

/// The `q` quantile (0–1) of `values`: the value at rank `round(q · (n − 1))` of the sorted
/// values; NaN when empty.
pub fn quantile(values: &[f64], q: f64) -> f64 {
    quantile_of_sorted(&sorted(values), q)
}

fn sorted(values: &[f64]) -> Vec<f64> {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    v
}

fn quantile_of_sorted(sorted: &[f64], q: f64) -> f64 {
    sorted
        .get(((sorted.len().max(1) - 1) as f64 * q).round() as usize)
        .copied()
        .unwrap_or(f64::NAN)
}

/// Score `boulders` (the front end's output on `frame`) against the frame's truth.
pub fn score_frame(frame: &StereoFrame, boulders: &[Boulder], config: &MatchConfig) -> FrameScore {
    let eye = Point3::from(frame.world_from_left.translation.vector);
    let mut rocks = rock_outcomes(frame, eye, config);
    let p_world = detections_in_world(frame, boulders);
    let pairs = candidate_pairs(frame, &p_world, eye, config);
    let matched_rock = assign_pairs(pairs, boulders.len(), &mut rocks);
    let detections = boulders
        .iter()
        .zip(&p_world)
        .zip(&matched_rock)
        .map(|((b, p), m)| detection_outcome(frame, b, p, *m, eye))
        .collect();
    FrameScore {
        seed: 0,
        sun_elevation_deg: 0.0,
        tick: 0,
        rocks,
        detections,
        render_ms: frame.render_ms,
        front_end_ms: 0.0,
    }
}

/// The frame's truth rocks seen from `eye` (the left camera), unmatched, and whether recall
/// counts each.
fn rock_outcomes(frame: &StereoFrame, eye: Point3<f64>, config: &MatchConfig) -> Vec<RockOutcome> {
    let touching = rocks_near_border(frame, config.border_margin_px);
    frame
        .rocks
        .iter()
        .map(|r| {
            let c = Point3::from(r.visible_center_world);
            let range_m = (c - eye).norm();
            let size_m = 2.0 * r.radius_m;
            let counted = size_m >= config.min_size_m
                && range_m <= config.max_range_m
                && r.visible_fraction >= config.min_visible_fraction
                && !touching.contains(&r.id);
            RockOutcome {
                id: r.id,
                range_m,
                size_m,
                pixels: r.pixels,
                counted,
                error_m: None,
            }
        })
        .collect()
}

/// The boulders' positions in the world frame.
fn detections_in_world(frame: &StereoFrame, boulders: &[Boulder]) -> Vec<Point3<f64>> {
    boulders
        .iter()
        .map(|b| {
            let [x, y, z] = b.position_camera;
            frame.world_from_left * Point3::new(x, y, z)
        })
        .collect()
}

/// The (distance, detection, rock) pairs within the match gate, nearest first.
fn candidate_pairs(
    frame: &StereoFrame,
    p_world: &[Point3<f64>],
    eye: Point3<f64>,
    config: &MatchConfig,
) -> Vec<(f64, usize, usize)> {
    let mut pairs = Vec::new();
    for (d, p) in p_world.iter().enumerate() {
        if (p - eye).norm() > config.match_max_range_m {
            continue;
        }
        for (k, r) in frame.rocks.iter().enumerate() {
            let e = (p - Point3::from(r.visible_center_world)).norm();
            if e <= config.match_size_fraction * 2.0 * r.radius_m {
                pairs.push((e, d, k));
            }
        }
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    pairs
}

/// Match each of `detections` detections and each of `rocks` at most once, taking `pairs`
/// in order; sets the matched rocks' errors and returns each detection's rock (index in
/// the frame's rocks).
fn assign_pairs(
    pairs: Vec<(f64, usize, usize)>,
    detections: usize,
    rocks: &mut [RockOutcome],
) -> Vec<Option<usize>> {
    let mut matched_rock = vec![None; detections];
    for (e, d, k) in pairs {
        if matched_rock[d].is_none() && rocks[k].error_m.is_none() {
            matched_rock[d] = Some(k);
            rocks[k].error_m = Some(e);
        }
    }
    matched_rock
}

/// What became of detection `b` (at `p` in the world frame, matched to the frame's rock
/// `m`), seen from `eye`.
fn detection_outcome(
    frame: &StereoFrame,
    b: &Boulder,
    p: &Point3<f64>,
    m: Option<usize>,
    eye: Point3<f64>,
) -> DetectionOutcome {
    let width = frame.left.width;
    let [u, v] = b.pixel_centroid;
    let idx = (v.round().max(0.0) as usize).min(frame.left.height - 1) * width
        + (u.round().max(0.0) as usize).min(width - 1);
    let under = frame.instance[idx];
    let unmatched_on_rock = (m.is_none() && under != 0 && under != LANDER_INSTANCE)
        .then(|| frame.rocks.iter().find(|r| r.id + 1 == under as usize))
        .flatten()
        .map(|r| {
            let e = (p - Point3::from(r.visible_center_world)).norm();
            (r.id, 2.0 * r.radius_m, e)
        });
    let on = match (under, frame.depth_m[idx]) {
        (LANDER_INSTANCE, _) => "lander",
        (0, d) if d <= 0.0 => "sky",
        (0, _) => "ground",
        _ => "rock",
    };
    DetectionOutcome {
        range_m: (p - eye).norm(),
        size_m: b.size_m,
        pixel_centroid: b.pixel_centroid,
        rock: m.map(|k| frame.rocks[k].id),
        on,
        unmatched_on_rock,
    }
}

/// Ids of the rocks with a pixel within `margin` pixels of the image border.
fn rocks_near_border(frame: &StereoFrame, margin: usize) -> Vec<usize> {
    let (w, h) = (frame.left.width, frame.left.height);
    let mut out = Vec::new();
    for y in 0..h {
        let edge_row = y < margin || y + margin >= h;
        for x in 0..w {
            if !(edge_row || x < margin || x + margin >= w) {
                continue;
            }
            let i = frame.instance[y * w + x];
            if i != 0 && i != LANDER_INSTANCE {
                let id = i as usize - 1;
                if !out.contains(&id) {
                    out.push(id);
                }
            }
        }
    }
    out
}

/// Recall, precision and centroid error of a set of frames.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Summary {
    /// Frames.
    pub frames: usize,
    /// Counted truth rocks (sum over frames).
    pub rocks: usize,
    /// Detections within range (sum over frames).
    pub detections: usize,
    /// Matched counted rocks over counted rocks.
    pub recall: f64,
    /// True detections over detections within range.
    pub precision: f64,
    /// Centroid error of the matched counted rocks, metres: median.
    pub centroid_error_median_m: f64,
    /// Centroid error, 90th percentile, metres.
    pub centroid_error_p90_m: f64,
}

/// Summarize the rocks and detections of `frames` whose range lies in `band` (metres).
pub fn summarize(frames: &[&FrameScore], band: (f64, f64), config: &MatchConfig) -> Summary {
    let in_band = |r: f64| r >= band.0 && r < band.1 && r <= config.max_range_m;
    let rocks: Vec<&RockOutcome> = frames
        .iter()
        .flat_map(|f| f.rocks.iter())
        .filter(|r| r.counted && in_band(r.range_m))
        .collect();
    let detections: Vec<&DetectionOutcome> = frames
        .iter()
        .flat_map(|f| f.detections.iter())
        .filter(|d| in_band(d.range_m))
        .collect();
    let mut errors: Vec<f64> = rocks.iter().filter_map(|r| r.error_m).collect();
    errors.sort_by(f64::total_cmp);
    let ratio = |a: usize, b: usize| {
        if b == 0 {
            f64::NAN
        } else {
            a as f64 / b as f64
        }
    };
    let quantile = |q: f64| quantile_of_sorted(&errors, q);
    Summary {
        frames: frames.len(),
        rocks: rocks.len(),
        detections: detections.len(),
        recall: ratio(errors.len(), rocks.len()),
        precision: ratio(
            detections.iter().filter(|d| d.rock.is_some()).count(),
            detections.len(),
        ),
        centroid_error_median_m: quantile(0.5),
        centroid_error_p90_m: quantile(0.9),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_of_nothing_are_nan() {
        let q = Quantiles::of(&[]);
        assert!(q.median.is_nan() && q.p99.is_nan());
        let q = Quantiles::of(&[3.0, 1.0, 2.0]);
        assert_eq!((q.median, q.p90, q.p99), (2.0, 3.0, 3.0));
        assert_eq!(quantile(&[4.0, 1.0, 3.0, 2.0], 0.5), 3.0);
        assert!(quantile(&[], 0.9).is_nan());
    }

    fn rock(range_m: f64, error_m: Option<f64>) -> RockOutcome {
        RockOutcome {
            id: 0,
            range_m,
            size_m: 0.2,
            pixels: 100,
            counted: true,
            error_m,
        }
    }

    #[test]
    fn summary_counts_rocks_and_detections_by_band() {
        let det = |range_m: f64, rock: Option<usize>| DetectionOutcome {
            range_m,
            size_m: 0.2,
            pixel_centroid: [0.0; 2],
            rock,
            on: "rock",
            unmatched_on_rock: None,
        };
        let f = FrameScore {
            seed: 1,
            sun_elevation_deg: 15.0,
            tick: 0,
            rocks: vec![rock(1.0, Some(0.01)), rock(3.0, None), rock(7.0, None)],
            detections: vec![det(1.0, Some(0)), det(3.0, None), det(7.5, None)],
            render_ms: 0.0,
            front_end_ms: 0.0,
        };
        let c = MatchConfig::default();
        let all = summarize(&[&f], (0.0, f64::INFINITY), &c);
        assert_eq!((all.rocks, all.detections), (2, 2));
        assert_eq!((all.recall, all.precision), (0.5, 0.5));
        assert_eq!(all.centroid_error_median_m, 0.01);
        let near = summarize(&[&f], (0.0, 2.0), &c);
        assert_eq!((near.recall, near.precision), (1.0, 1.0));
    }
}
