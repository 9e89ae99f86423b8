//! Perception measured on thousands of randomized frames, not on a handful of photos.
//!
//! A few real photos are too few to trust a detector with: thresholds end up fitting them.
//! [`run`] makes frames the way the world varies them and scores every one against ground
//! truth:
//!
//! - **the sheet**: the simulator's plain one, Niryo's classic striped one or the Ned2's
//!   black-framed one ([`robotd_render::sheet_art`]), seen from 24–42 cm, the camera tilted
//!   up to 30° in any direction and turned any way about its axis, through one of several
//!   lenses (none, the Ned2's, a stronger barrel);
//! - **the light and the camera** ([`robotd_render::photo`]): exposure, a light gradient in
//!   any direction, colour temperature and white balance, vignetting, glare, blur, sensor
//!   noise, JPEG quality 40–95;
//! - **the objects**: random objects of the label table, and multi-coloured objects (a bar in
//!   a wrapper of one colour with a band of another across it), all of 15 mm and more;
//! - **distractors**: pencil lines drawn on the sheet, a taped paper, a cable, a hand at the
//!   border, objects beside the sheet, a second sheet beside the first, a marker half covered
//!   or the markers' centres painted red (then the sheet may rightly be missed), cube-sized
//!   dark and green blobs near a corner.
//!
//! Each frame is scored: was the workspace found; was it **wrong** (any corner more than
//! 1 cm from where it really is); object recall and precision; position error.

pub mod breakdown;
mod case;

use super::{score, LabError};
use crate::detector::{ColourDetector, ColourDetectorSettings, FrameView};
use crate::labels::LabelTable;
use crate::pipeline::Pipeline;
use breakdown::{Breakdown, TrueMarker};
use case::{corner_points, make_case, DISTRACTORS};
use nalgebra::Point3;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use robotd_render::{Intrinsics, RenderOptions, Renderer};
use robotd_sim::Scene;
use std::time::{Duration, Instant};

/// A found workspace is wrong when a corner is farther than this from the truth, metres.
pub const WRONG_CORNER_M: f64 = 0.01;
/// Objects at least this large (smaller side) count for recall.
pub const MIN_COUNTED_SIDE_M: f64 = 0.015;

/// What was measured over the frames.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RandomizedFigures {
    /// Frames made.
    pub frames: usize,
    /// Frames where the whole sheet was in view and no marker covered.
    pub sheet_expected: usize,
    /// Of those, how many found it.
    pub sheet_found: usize,
    /// Frames (of all) where a workspace was reported more than 1 cm off at a corner.
    pub wrong_workspaces: usize,
    /// Frames with a marker half covered or painted over where the sheet was still found
    /// (correctly).
    pub covered_found: usize,
    /// Frames with a marker half covered or painted over (the sheet may rightly be missed).
    pub covered: usize,
    /// Objects of 15 mm and more on found sheets.
    pub objects: usize,
    /// Of those, found.
    pub objects_found: usize,
    /// Detections on found sheets.
    pub detections: usize,
    /// Detections that matched no object.
    pub false_positives: usize,
    /// Position errors of the objects found, metres.
    pub position_errors_m: Vec<f64>,
    /// Time in the pipeline (markers, sheet, detector), summed.
    pub pipeline_time: Duration,
    /// The floor beside it, measured on the same frames: reading each frame's bytes once.
    pub read_floor_time: Duration,
    /// Frames per design: (design, expected, found).
    pub by_design: Vec<(String, usize, usize)>,
    /// False positives per distractor present in the frame: (distractor, frames, false
    /// positives in them).
    pub by_distractor: Vec<(String, usize, usize)>,
    /// Seeds of the frames with a wrong workspace, to look at.
    pub wrong_seeds: Vec<u64>,
    /// Where the frames with the sheet in view lost it, and the found rates by blur, marker
    /// size and tilt.
    pub breakdown: Breakdown,
}

impl RandomizedFigures {
    /// Share of the frames with the sheet in view that found it.
    pub fn found_rate(&self) -> f64 {
        self.sheet_found as f64 / self.sheet_expected.max(1) as f64
    }
    /// Object recall (15 mm and more).
    pub fn recall(&self) -> f64 {
        self.objects_found as f64 / self.objects.max(1) as f64
    }
    /// Object precision.
    pub fn precision(&self) -> f64 {
        1.0 - self.false_positives as f64 / self.detections.max(1) as f64
    }
    /// Frames per second of the pipeline on this (one) thread.
    pub fn frames_per_second(&self) -> f64 {
        self.frames as f64 / self.pipeline_time.as_secs_f64().max(1e-9)
    }
    /// Mean time to read a frame's bytes once (the floor), milliseconds.
    pub fn read_floor_ms(&self) -> f64 {
        self.read_floor_time.as_secs_f64() * 1e3 / self.frames.max(1) as f64
    }
}

/// One camera: its lens, renderer and pipeline.
struct Lens {
    intrinsics: Intrinsics,
    renderer: Renderer,
    pipeline: Pipeline,
}

/// Runs `frames` randomized frames from `seed` and scores them. With `dump`, every frame that
/// went wrong (wrong workspace, sheet in view but not found, a false positive, an object
/// missed) is written there as a PNG named by its seed and what went wrong.
pub fn run(
    frames: usize,
    seed: u64,
    dump: Option<&std::path::Path>,
) -> Result<RandomizedFigures, LabError> {
    let seeds: Vec<u64> = (0..frames as u64)
        .map(|i| seed.wrapping_mul(1_000_003).wrapping_add(i))
        .collect();
    run_frames(&seeds, dump)
}

/// Runs the frames of the given frame seeds (as [`run`] names them in
/// [`RandomizedFigures::wrong_seeds`] and in dumped file names), to look at one again.
pub fn run_frames(
    frame_seeds: &[u64],
    dump: Option<&std::path::Path>,
) -> Result<RandomizedFigures, LabError> {
    let scene = Scene::default_ned2();
    let workspace = scene
        .workspace_infos()
        .into_iter()
        .next()
        .ok_or_else(|| LabError("the default scene has no workspace".into()))?;
    let table = LabelTable::builtin();
    let ned2 = Intrinsics::ned2();
    let seed = frame_seeds.first().copied().unwrap_or(0);
    let lenses_k = [
        Intrinsics {
            distortion: [0.0; 5],
            ..ned2
        },
        ned2,
        Intrinsics {
            distortion: [-0.28, 0.08, 0.0, 0.0, 0.0],
            ..ned2
        },
    ];
    let mut lenses = Vec::new();
    for (k, intrinsics) in lenses_k.into_iter().enumerate() {
        let detector = ColourDetector::new(table.clone(), ColourDetectorSettings::default());
        let pipeline = Pipeline::new(
            &intrinsics.into(),
            vec![workspace.clone()],
            Box::new(detector),
        )
        .map_err(|e| LabError(e.to_string()))?;
        let renderer = Renderer::new(
            intrinsics,
            RenderOptions {
                noise_stddev: 2.5,
                lens_distortion: intrinsics.distortion.iter().any(|d| *d != 0.0),
                seed: seed ^ k as u64,
                shading: true,
            },
        );
        lenses.push(Lens {
            intrinsics,
            renderer,
            pipeline,
        });
    }
    let mut figures = RandomizedFigures {
        by_design: ["plain", "classic", "ned2"]
            .iter()
            .map(|d| (d.to_string(), 0, 0))
            .collect(),
        by_distractor: DISTRACTORS
            .iter()
            .map(|(_, name, _)| (name.to_string(), 0, 0))
            .collect(),
        ..RandomizedFigures::default()
    };
    let (w, h) = (ned2.width as usize, ned2.height as usize);
    let mut rgb = vec![0u8; w * h * 3];
    for (i, &frame_seed) in frame_seeds.iter().enumerate() {
        let mut rng = SmallRng::seed_from_u64(frame_seed);
        let lens = &mut lenses[rng.random_range(0..3)];
        let case = make_case(&mut rng, &workspace, &table, &lens.intrinsics);
        lens.renderer
            .render_into(&case.scene, &case.camera, &mut rgb)
            .map_err(|e| LabError(format!("rendering: {e}")))?;
        case.photo.apply(&mut rgb, w, h);
        let jpeg = robotd_render::encode_jpeg(&rgb, w as u32, h as u32, case.jpeg_quality)
            .map_err(|e| LabError(format!("JPEG: {e}")))?;
        let decoded = robotd_vision::still::decode(&jpeg, "frame")
            .map_err(|e| LabError(format!("JPEG: {e}")))?;
        let view = FrameView {
            rgb: &decoded.rgb,
            width: w,
            height: h,
            frame_id: i as u64,
            timestamp_unix_ns: 0,
        };
        // The kinematics' idea of where the camera is: a little off, as a real mount is.
        let eye = case.camera.translation.vector;
        lens.pipeline.expect_camera_at(Some([
            eye.x + case.camera_error[0],
            eye.y + case.camera_error[1],
            eye.z + case.camera_error[2],
        ]));
        let started = Instant::now();
        let sum: u64 = decoded.rgb.iter().map(|b| u64::from(*b)).sum();
        std::hint::black_box(sum);
        figures.read_floor_time += started.elapsed();
        let started = Instant::now();
        let (detections, status) = lens
            .pipeline
            .process(&view, Some(&case.tool_pose), true)
            .map_err(|e| LabError(e.to_string()))?;
        figures.pipeline_time += started.elapsed();
        figures.frames += 1;

        let found = lens.pipeline.last_sheet().map(|(plane, _)| plane.clone());
        let camera_from_world = case.camera.inverse();
        let true_corner_error = |plane: &crate::plane::TablePlane| {
            corner_points(&workspace)
                .iter()
                .map(|&[x, y]| {
                    let Some(px) = lens
                        .intrinsics
                        .project(&camera_from_world, &Point3::new(x, y, 0.0))
                    else {
                        return f64::INFINITY;
                    };
                    let seen = plane.pixel_to_table([px.x, px.y]);
                    (seen[0] - x).hypot(seen[1] - y)
                })
                .fold(0f64, f64::max)
        };
        if case.sheet_expected {
            let truth = true_markers(
                &lens.intrinsics,
                &camera_from_world,
                &corner_points(&workspace),
                case.marker_radius_m,
            );
            let right = found
                .as_ref()
                .is_some_and(|p| true_corner_error(p) <= WRONG_CORNER_M);
            figures.breakdown.record(
                case.design_index,
                case.photo.blur_px,
                case.tilt_deg,
                &truth,
                lens.pipeline.marker_candidates(),
                lens.pipeline.blurred_fits(),
                &status,
                right,
            );
        }
        let mut problems: Vec<String> = Vec::new();
        let save = |problems: &[String]| {
            if let (Some(dir), false) = (dump, problems.is_empty()) {
                let path = dir.join(format!(
                    "{frame_seed}-{}-{}-blur{}-q{}.png",
                    problems.join("-"),
                    ["plain", "classic", "ned2"][case.design_index],
                    case.photo.blur_px,
                    case.jpeg_quality
                ));
                let truth: Vec<String> = case
                    .truth
                    .iter()
                    .map(|o| {
                        format!(
                            "{} at ({:.3}, {:.3}) {:?}",
                            o.spec.label, o.pose.translation.x, o.pose.translation.y, o.spec.shape
                        )
                    })
                    .collect();
                let seen: Vec<String> = detections
                    .objects
                    .iter()
                    .map(|d| {
                        let c = d.position.center_of_mass;
                        format!(
                            "{} at ({:.3}, {:.3}) {:.0} x {:.0} mm",
                            d.label,
                            c.x_m,
                            c.y_m,
                            d.dimensions.width_m * 1e3,
                            d.dimensions.height_m * 1e3
                        )
                    })
                    .collect();
                let _ = std::fs::write(
                    path.with_extension("txt"),
                    format!(
                        "{status}\ndistractors: {:?}\ntruth:\n  {}\ndetected:\n  {}\n",
                        case.distractors,
                        truth.join("\n  "),
                        seen.join("\n  ")
                    ),
                );
                let _ = image::save_buffer_with_format(
                    &path,
                    &decoded.rgb,
                    w as u32,
                    h as u32,
                    image::ExtendedColorType::Rgb8,
                    image::ImageFormat::Png,
                );
            }
        };
        let design_row = &mut figures.by_design[case.design_index];
        if case.sheet_expected {
            figures.sheet_expected += 1;
            design_row.1 += 1;
        }
        if case.covered {
            figures.covered += 1;
        }
        let Some(plane) = found else {
            if case.sheet_expected {
                problems.push(format!("notfound_{}", status_word(&status)));
            }
            save(&problems);
            continue;
        };
        // Where the found plane puts the true corners' pixels.
        let corner_error = true_corner_error(&plane);
        if corner_error > WRONG_CORNER_M {
            figures.wrong_workspaces += 1;
            figures.wrong_seeds.push(frame_seed);
            problems.push(format!("wrong{:.0}mm", corner_error * 1000.0));
            save(&problems);
            continue;
        }
        if case.sheet_expected {
            figures.sheet_found += 1;
            figures.by_design[case.design_index].2 += 1;
        }
        if case.covered {
            figures.covered_found += 1;
        }
        let frame_score = score(&case.truth, &detections.objects);
        figures.detections += detections.objects.len();
        figures.false_positives += frame_score.false_positives;
        for (k, (distractor, _, _)) in DISTRACTORS.iter().enumerate() {
            if case.distractors.contains(distractor) {
                figures.by_distractor[k].1 += 1;
                figures.by_distractor[k].2 += frame_score.false_positives;
            }
        }
        if frame_score.false_positives > 0 {
            problems.push(format!("fp{}", frame_score.false_positives));
        }
        for o in &frame_score.objects {
            if o.min_side_m < MIN_COUNTED_SIDE_M {
                continue;
            }
            figures.objects += 1;
            if let Some(e) = o.position_error_m {
                figures.objects_found += 1;
                figures.position_errors_m.push(e);
                if e > 0.003 {
                    problems.push(format!("off{:.0}mm", e * 1000.0));
                }
            } else {
                problems.push(format!("missed_{}", o.label.replace(' ', "_")));
            }
        }
        save(&problems);
    }
    Ok(figures)
}

/// Where the four markers really are in the (distorted) image and how large they look.
fn true_markers(
    intrinsics: &Intrinsics,
    camera_from_world: &nalgebra::Isometry3<f64>,
    corners: &[[f64; 2]; 4],
    radius_m: f64,
) -> [TrueMarker; 4] {
    let raw = |x: f64, y: f64| {
        intrinsics
            .project(camera_from_world, &Point3::new(x, y, 0.0))
            .map(|p| intrinsics.distort(p))
    };
    corners.map(|[x, y]| {
        let Some(c) = raw(x, y) else {
            return TrueMarker {
                centre_px: [f64::NAN; 2],
                radius_px: 0.0,
            };
        };
        let radii: Vec<f64> = (0..8)
            .filter_map(|k| {
                let a = f64::from(k) * std::f64::consts::FRAC_PI_4;
                raw(x + radius_m * a.cos(), y + radius_m * a.sin())
                    .map(|p| (p.x - c.x).hypot(p.y - c.y))
            })
            .collect();
        TrueMarker {
            centre_px: [c.x, c.y],
            radius_px: radii.iter().sum::<f64>() / radii.len().max(1) as f64,
        }
    })
}

/// A word for why no sheet was found, for file names.
fn status_word(status: &crate::pipeline::SheetStatus) -> String {
    use crate::pipeline::SheetStatus;
    match status {
        SheetStatus::Found => "found".into(),
        SheetStatus::MarkersMissing { seen } => format!("markers{seen}"),
        SheetStatus::NotASheet { seen, failed } => format!("markers{seen}_{failed:?}"),
        SheetStatus::Degenerate => "degenerate".into(),
    }
}
