//! Why the front end misses a rendered rock: one diagnosis per counted truth rock of a frame.
//!
//! For each rock recall counts ([`score_frame`](super::render_front_end::score_frame)), on
//! the disparity map's grid: its true protrusion above the terrain, the stereo on its pixels
//! (valid fraction, depth error against the rendered depth), the estimated height above the
//! ground, the geometric segmenter's regions covering it (kept or dropped, and why), the
//! boulder stage's verdict on their masks, and the match. A missed rock gets the first cause
//! along the pipeline ([`miss_cause`]). Whatever the segmenter, the `mask_*` fields follow
//! the front end's own mask covering most of the rock and the boulder stage's verdict on
//! it. `segloc eval render --breakdown FILE` writes them.

use crate::perception::geometric::{segment_geometric_regions, Region};
use crate::perception::ground::{height_above_ground, HeightMap};
use crate::perception::{FrameResult, GeometricConfig, RegionDrop, SegmentInput};
use crate::sim::moon::Moon;
use crate::sim::render::scoring::{FrameScore, RockOutcome};
use crate::sim::render::StereoFrame;
use serde::Serialize;

/// A counted rock of one frame, seen through the front end's stages.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RockDiagnosis {
    /// Seed of the moon.
    pub seed: u64,
    /// Sun elevation, degrees.
    pub sun_elevation_deg: f64,
    /// Simulator tick of the frame.
    pub tick: usize,
    /// Rock index in the moon.
    pub id: usize,
    /// Diameter, metres.
    pub size_m: f64,
    /// Range of its visible centre, metres.
    pub range_m: f64,
    /// Top of the rock above the terrain under its centre, metres.
    pub protrusion_m: f64,
    /// Its pixels on the disparity map's grid.
    pub pixels: usize,
    /// Fraction of them with a valid disparity.
    pub valid_fraction: f64,
    /// Median |stereo depth − rendered depth| on them, metres (NaN without depth).
    pub depth_error_m: f64,
    /// Highest estimated height above the local ground on them, metres (NaN: none).
    pub peak_height_m: f64,
    /// The seed threshold at its range, metres.
    pub seed_threshold_m: f64,
    /// Pixels above the seed threshold.
    pub seed_pixels: usize,
    /// Fraction of its pixels darker than the segmenter's shadow level.
    pub shadow_fraction: f64,
    /// Fraction of its pixels brighter than the segmenter's sunlit level.
    pub lit_fraction: f64,
    /// Fraction of its pixels in the region covering most of it (0: none).
    pub region_cover: f64,
    /// Fraction of that region's pixels on this rock.
    pub region_purity: f64,
    /// Fraction of that region's pixels on other rocks.
    pub region_other_rocks: f64,
    /// Regions (kept or not) covering at least a quarter of its pixels.
    pub regions_over_quarter: usize,
    /// Distance of the nearest boulder (from the main region's mask) to its visible centre,
    /// metres (NaN: no boulder).
    pub boulder_error_m: f64,
    /// Range of that boulder minus the range of the visible centre, metres (the error's
    /// component along the line of sight; NaN: no boulder).
    pub boulder_range_error_m: f64,
    /// Fraction of its left-image pixels in the front end's mask covering most of it,
    /// whatever the segmenter (0: none).
    pub mask_cover: f64,
    /// Fraction of that mask's pixels on this rock.
    pub mask_purity: f64,
    /// The boulder stage's verdict on that mask: "boulder", the rejection, or "no mask".
    pub mask_verdict: String,
    /// Distance of that mask's boulder to its visible centre, metres (NaN: no boulder).
    pub mask_boulder_error_m: f64,
    /// Whether a detection matched it.
    pub detected: bool,
    /// The first cause along the pipeline for a missed rock; "detected" otherwise.
    pub cause: String,
}

/// The diagnoses of every counted rock of a frame (`score` is the frame's score,
/// `result` the front end's output on `frame`, `geometric` its segmenter's settings).
pub fn diagnose_frame(
    moon: &Moon,
    frame: &StereoFrame,
    result: &FrameResult,
    score: &FrameScore,
    geometric: &GeometricConfig,
) -> Vec<RockDiagnosis> {
    let grid = FrameGrid::new(frame, result, geometric);
    score
        .rocks
        .iter()
        .filter(|r| r.counted)
        .map(|rock| diagnose_rock(moon, score, &grid, rock))
        .collect()
}

/// A frame seen on the disparity map's grid: its pixels' rock instances, the estimated
/// heights and the geometric segmenter's regions.
struct FrameGrid<'a> {
    /// The rendered frame.
    frame: &'a StereoFrame,
    /// The front end's output on it.
    result: &'a FrameResult,
    /// The segmenter's settings.
    geometric: &'a GeometricConfig,
    /// Width of the disparity map.
    w: usize,
    /// Left-image pixels per disparity-map pixel.
    s: usize,
    /// Width of the left image.
    full_w: usize,
    /// Estimated heights above the local ground (None: no ground estimate).
    heights: Option<HeightMap>,
    /// The geometric segmenter's regions.
    regions: Vec<Region>,
    /// Each grid pixel's region index (`u32::MAX`: none).
    region_of: Vec<u32>,
    /// Each grid pixel's rock instance (rock id + 1; 0: no rock).
    instance: Vec<u32>,
    /// Each instance's grid pixels.
    pixels_of: std::collections::HashMap<u32, Vec<usize>>,
}

/// Stereo depth and estimated height on a rock's pixels.
struct PixelStats {
    /// Pixels with a valid disparity.
    valid: usize,
    /// Median |stereo depth − rendered depth| on them, metres (NaN without depth).
    depth_error_m: f64,
    /// Pixels above the seed threshold.
    seeds: usize,
    /// Highest estimated height above the local ground, metres (NaN: none).
    peak: f64,
}

impl<'a> FrameGrid<'a> {
    /// Segment `frame` as the front end did (`result`, `geometric`) and sample its rock
    /// instances on the disparity map's grid.
    fn new(
        frame: &'a StereoFrame,
        result: &'a FrameResult,
        geometric: &'a GeometricConfig,
    ) -> Self {
        let disparity = &result.disparity;
        let (w, h, s) = (disparity.width, disparity.height, disparity.scale);
        let full_w = frame.left.width;
        let heights = height_above_ground(disparity, &geometric.ground);
        let input = SegmentInput {
            left: &frame.left,
            disparity,
            camera: &disparity.camera,
        };
        let regions = segment_geometric_regions(&input, geometric);
        let region_of = region_index(&regions, w * h);
        let instance: Vec<u32> = (0..w * h)
            .map(|p| frame.instance[grid_sample(w, s, full_w, p)])
            .collect();
        let pixels_of = pixels_by_instance(&instance);
        FrameGrid {
            frame,
            result,
            geometric,
            w,
            s,
            full_w,
            heights,
            regions,
            region_of,
            instance,
            pixels_of,
        }
    }

    /// The left-image pixel at the centre of grid pixel `p`.
    fn sample(&self, p: usize) -> usize {
        grid_sample(self.w, self.s, self.full_w, p)
    }

    /// The grid pixels of rock `id`.
    fn pixels_of_rock(&self, id: usize) -> &[usize] {
        self.pixels_of
            .get(&(id as u32 + 1))
            .map_or(&[], Vec::as_slice)
    }

    /// Stereo depth against the rendered depth, and estimated height, on `mine`.
    fn pixel_stats(&self, mine: &[usize]) -> PixelStats {
        let (disparity, w, geometric) = (&self.result.disparity, self.w, self.geometric);
        let mut errors = Vec::new();
        let (mut valid, mut seeds, mut peak) = (0usize, 0usize, f64::NAN);
        for &p in mine {
            if let Some(z) = disparity.depth_m(p % w, p / w) {
                valid += 1;
                errors.push((z - self.frame.depth_m[self.sample(p)] as f64).abs());
            }
            if let Some(hm) = &self.heights {
                let v = hm.above_ground_m[p] as f64;
                if v.is_finite() {
                    peak = if peak.is_nan() { v } else { peak.max(v) };
                    if v > geometric.threshold_at(geometric.seed_height_m, hm.depth_m[p] as f64) {
                        seeds += 1;
                    }
                }
            }
        }
        errors.sort_by(f64::total_cmp);
        PixelStats {
            valid,
            depth_error_m: errors.get(errors.len() / 2).copied().unwrap_or(f64::NAN),
            seeds,
            peak,
        }
    }

    /// Fractions of the shadowed and of the sunlit pixels among `mine`.
    fn shade_fractions(&self, mine: &[usize]) -> (f64, f64) {
        let gray = |p: usize| self.frame.left.data[self.sample(p)];
        self.geometric
            .shade_fractions(mine.iter().map(|&p| gray(p)))
    }

    /// Region `k` covering `c` of rock `id`'s `n` pixels: the fraction of the rock it
    /// covers, the fraction of it on the rock, and the fraction of it on other rocks.
    fn region_fractions(&self, k: usize, c: usize, n: f64, id: usize) -> (f64, f64, f64) {
        let r = &self.regions[k];
        let others = r
            .pixels
            .iter()
            .filter(|&&p| self.instance[p] != 0 && self.instance[p] != id as u32 + 1)
            .count();
        (
            c as f64 / n,
            c as f64 / r.pixels.len() as f64,
            others as f64 / r.pixels.len() as f64,
        )
    }
}

/// The left-image pixel at the centre of pixel `p` of a grid `w` wide, each of its pixels
/// `s` × `s` pixels of a left image `full_w` wide.
fn grid_sample(w: usize, s: usize, full_w: usize, p: usize) -> usize {
    ((p / w) * s + s / 2) * full_w + (p % w) * s + s / 2
}

/// Top of rock `id` above the terrain under its centre, metres.
fn protrusion_m(moon: &Moon, id: usize) -> f64 {
    let truth = &moon.rocks()[id];
    truth.center.z + truth.shape.top_m(truth.radius_m)
        - moon.height_at(truth.center.x, truth.center.y)
}

/// The diagnosis of one counted rock of the frame `grid` holds (`score` its score).
fn diagnose_rock(
    moon: &Moon,
    score: &FrameScore,
    grid: &FrameGrid,
    rock: &RockOutcome,
) -> RockDiagnosis {
    let mine = grid.pixels_of_rock(rock.id);
    let n = mine.len().max(1) as f64;
    let protrusion_m = protrusion_m(moon, rock.id);
    let geometric = grid.geometric;
    let threshold = geometric.threshold_at(geometric.seed_height_m, rock.range_m);
    let stats = grid.pixel_stats(mine);
    let (shadow_fraction, lit_fraction) = grid.shade_fractions(mine);
    let regions_cover = region_overlaps(mine, &grid.region_of);
    let main = regions_cover.first().copied();
    let (region_cover, region_purity, region_other_rocks) = main
        .map_or((0.0, 0.0, 0.0), |(k, c)| {
            grid.region_fractions(k, c, n, rock.id)
        });
    let (boulder_error_m, boulder_range_error_m, verdict) = main
        .map(|(k, _)| main_verdict(k, &grid.regions, grid.result, grid.frame, rock.id))
        .unwrap_or((f64::NAN, f64::NAN, Verdict::NoMask));
    let mask = front_end_mask(grid.result, grid.frame, rock);
    let mut d = RockDiagnosis {
        seed: score.seed,
        sun_elevation_deg: score.sun_elevation_deg,
        tick: score.tick,
        id: rock.id,
        size_m: rock.size_m,
        range_m: rock.range_m,
        protrusion_m,
        pixels: mine.len(),
        valid_fraction: stats.valid as f64 / n,
        depth_error_m: stats.depth_error_m,
        peak_height_m: stats.peak,
        seed_threshold_m: threshold,
        seed_pixels: stats.seeds,
        shadow_fraction,
        lit_fraction,
        region_cover,
        region_purity,
        region_other_rocks,
        regions_over_quarter: regions_cover
            .iter()
            .filter(|(_, c)| *c as f64 >= 0.25 * n)
            .count(),
        boulder_error_m,
        boulder_range_error_m,
        mask_cover: mask.cover,
        mask_purity: mask.purity,
        mask_verdict: mask.verdict,
        mask_boulder_error_m: mask.boulder_error_m,
        detected: rock.error_m.is_some(),
        cause: String::new(),
    };
    d.cause = miss_cause(&d, &verdict, main.map(|(k, _)| &grid.regions[k].outcome));
    d
}

/// For each of `pixels` pixels, the index of the region holding it (`u32::MAX`: none).
fn region_index(regions: &[Region], pixels: usize) -> Vec<u32> {
    let mut region_of = vec![u32::MAX; pixels];
    for (k, r) in regions.iter().enumerate() {
        for &p in &r.pixels {
            region_of[p] = k as u32;
        }
    }
    region_of
}

/// Each instance's pixels (instance id = rock id + 1; 0 is no rock), in one pass.
fn pixels_by_instance(instance: &[u32]) -> std::collections::HashMap<u32, Vec<usize>> {
    let mut pixels_of: std::collections::HashMap<u32, Vec<usize>> = Default::default();
    for (p, &id) in instance.iter().enumerate().filter(|(_, &id)| id != 0) {
        pixels_of.entry(id).or_default().push(p);
    }
    pixels_of
}

/// The regions covering `pixels`, with how many of them each covers, most first.
fn region_overlaps(pixels: &[usize], region_of: &[u32]) -> Vec<(usize, usize)> {
    let mut counts: Vec<(usize, usize)> = Vec::new();
    for &p in pixels {
        let k = region_of[p];
        if k == u32::MAX {
            continue;
        }
        match counts.iter_mut().find(|(r, _)| *r == k as usize) {
            Some(c) => c.1 += 1,
            None => counts.push((k as usize, 1)),
        }
    }
    counts.sort_by_key(|c| std::cmp::Reverse(c.1));
    counts
}

/// What the boulder stage made of a region's mask.
#[derive(Clone, Debug, PartialEq)]
pub enum Verdict {
    /// No region / mask.
    NoMask,
    /// The mask was rejected (the rejection's name).
    Rejected(String),
    /// A boulder.
    Boulder,
}

/// The boulder stage's verdict on region `k`'s mask, and the boulder's distance to rock
/// `rock`'s visible centre.
fn main_verdict(
    k: usize,
    regions: &[crate::perception::Region],
    result: &FrameResult,
    frame: &StereoFrame,
    rock: usize,
) -> (f64, f64, Verdict) {
    let Ok(mask) = &regions[k].outcome else {
        return (f64::NAN, f64::NAN, Verdict::NoMask);
    };
    match result.masks.iter().position(|x| x == mask) {
        Some(m) => mask_verdict(m, result, frame, rock),
        None => (f64::NAN, f64::NAN, Verdict::NoMask),
    }
}

/// The boulder stage's verdict on the front end's mask `m`, and its boulder's distance to
/// rock `rock`'s visible centre and range error (NaN without a boulder).
fn mask_verdict(
    m: usize,
    result: &FrameResult,
    frame: &StereoFrame,
    rock: usize,
) -> (f64, f64, Verdict) {
    match &result.verdicts[m] {
        Err(rejection) => (
            f64::NAN,
            f64::NAN,
            Verdict::Rejected(format!("{rejection:?}")),
        ),
        Ok(b) => {
            let [x, y, z] = result.boulders[*b].position_camera;
            let p_left = nalgebra::Point3::new(x, y, z);
            let Some(truth) = frame.rocks.iter().find(|r| r.id == rock) else {
                return (f64::NAN, f64::NAN, Verdict::Boulder);
            };
            let c_world = nalgebra::Point3::from(truth.visible_center_world);
            let c_left = frame.world_from_left.inverse() * c_world;
            let e = (frame.world_from_left * p_left - c_world).norm();
            (
                e,
                p_left.coords.norm() - c_left.coords.norm(),
                Verdict::Boulder,
            )
        }
    }
}

/// The front end's mask covering most of a rock, whatever the segmenter.
struct MaskOnRock {
    cover: f64,
    purity: f64,
    verdict: String,
    boulder_error_m: f64,
}

/// The front end's mask (left-image pixels) covering most of `rock`, and what the boulder
/// stage made of it.
fn front_end_mask(result: &FrameResult, frame: &StereoFrame, rock: &RockOutcome) -> MaskOnRock {
    let (w, target) = (frame.left.width, rock.id as u32 + 1);
    let on_rock = |m: &crate::perception::Mask| {
        let (mut on, mut all) = (0usize, 0usize);
        for (x, y) in m.pixels() {
            all += 1;
            on += usize::from(frame.instance.get(y * w + x) == Some(&target));
        }
        (on, all)
    };
    let best = result
        .masks
        .iter()
        .enumerate()
        .map(|(k, m)| (k, on_rock(m)))
        .filter(|(_, (on, _))| *on > 0)
        .max_by_key(|(_, (on, _))| *on);
    let Some((k, (on, all))) = best else {
        return MaskOnRock {
            cover: 0.0,
            purity: 0.0,
            verdict: "no mask".into(),
            boulder_error_m: f64::NAN,
        };
    };
    let (boulder_error_m, _, verdict) = mask_verdict(k, result, frame, rock.id);
    let verdict = match verdict {
        Verdict::Rejected(rejection) => rejection,
        Verdict::Boulder => "boulder".into(),
        Verdict::NoMask => "no mask".into(),
    };
    MaskOnRock {
        cover: on as f64 / rock.pixels.max(1) as f64,
        purity: on as f64 / all.max(1) as f64,
        verdict,
        boulder_error_m,
    }
}

/// The first cause along the pipeline why a rock was missed ("detected" when it was not).
pub fn miss_cause(
    d: &RockDiagnosis,
    verdict: &Verdict,
    main_outcome: Option<&Result<crate::perception::Mask, RegionDrop>>,
) -> String {
    if d.detected {
        return "detected".into();
    }
    if d.valid_fraction < 0.3 {
        return "stereo: < 30 % valid disparity".into();
    }
    if d.seed_pixels == 0 {
        return if d.protrusion_m < d.seed_threshold_m {
            "threshold: protrudes less than the seed height".into()
        } else {
            "height: protrudes enough, estimated too low".into()
        };
    }
    match main_outcome {
        None => return "segmenter: seed pixels but no region".into(),
        Some(Err(drop)) => return format!("segmenter: region dropped ({drop:?})"),
        Some(Ok(_)) => {}
    }
    if d.region_other_rocks > 0.25 {
        return "segmenter: merged with another rock".into();
    }
    if d.region_purity < 0.35 {
        return "segmenter: merged with the ground".into();
    }
    if d.regions_over_quarter >= 2 {
        return "segmenter: split".into();
    }
    match verdict {
        Verdict::Rejected(r) => format!("boulders: rejected ({r})"),
        Verdict::NoMask => "segmenter: no mask".into(),
        Verdict::Boulder if d.region_cover < 0.5 => {
            "centroid: region covers < 50 % of the rock".into()
        }
        Verdict::Boulder => "centroid: off by more than 0.3 × size".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rock() -> RockDiagnosis {
        RockDiagnosis {
            seed: 1,
            sun_elevation_deg: 15.0,
            tick: 0,
            id: 0,
            size_m: 0.12,
            range_m: 4.0,
            protrusion_m: 0.07,
            pixels: 40,
            valid_fraction: 0.9,
            depth_error_m: 0.02,
            peak_height_m: 0.07,
            seed_threshold_m: 0.06,
            seed_pixels: 5,
            shadow_fraction: 0.3,
            lit_fraction: 0.2,
            region_cover: 0.8,
            region_purity: 0.8,
            region_other_rocks: 0.0,
            regions_over_quarter: 1,
            boulder_error_m: 0.05,
            boulder_range_error_m: 0.04,
            mask_cover: 0.8,
            mask_purity: 0.8,
            mask_verdict: "boulder".into(),
            mask_boulder_error_m: 0.05,
            detected: false,
            cause: String::new(),
        }
    }

    #[test]
    fn the_first_failing_stage_is_the_cause() {
        let ok: Result<crate::perception::Mask, RegionDrop> =
            Ok(crate::perception::Mask::from_pixels(&[(0, 0)], 1.0).unwrap());
        let cause = |d: &RockDiagnosis, v: &Verdict| miss_cause(d, v, Some(&ok));
        assert_eq!(
            cause(&rock(), &Verdict::Boulder),
            "centroid: off by more than 0.3 × size"
        );
        let detected = RockDiagnosis {
            detected: true,
            ..rock()
        };
        assert_eq!(cause(&detected, &Verdict::Boulder), "detected");
        let no_depth = RockDiagnosis {
            valid_fraction: 0.1,
            ..rock()
        };
        assert!(cause(&no_depth, &Verdict::Boulder).starts_with("stereo"));
        let low = RockDiagnosis {
            seed_pixels: 0,
            protrusion_m: 0.05,
            ..rock()
        };
        assert!(cause(&low, &Verdict::Boulder).starts_with("threshold"));
        let under = RockDiagnosis {
            seed_pixels: 0,
            ..rock()
        };
        assert!(cause(&under, &Verdict::Boulder).starts_with("height"));
        let merged = RockDiagnosis {
            region_other_rocks: 0.5,
            ..rock()
        };
        assert!(cause(&merged, &Verdict::Boulder).contains("another rock"));
        let rejected = Verdict::Rejected("Size".into());
        assert_eq!(cause(&rock(), &rejected), "boulders: rejected (Size)");
        let dropped = Err(RegionDrop::Shadow);
        assert!(miss_cause(&rock(), &Verdict::NoMask, Some(&dropped)).contains("Shadow"));
    }
}
