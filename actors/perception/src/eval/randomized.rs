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

use super::{score, LabError};
use crate::detector::{ColourDetector, ColourDetectorSettings, FrameView};
use crate::labels::LabelTable;
use crate::pipeline::Pipeline;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use robotd_driver_sim::solid_of;
use robotd_protocol::workspace::WorkspaceInfo;
use robotd_render::photo::PhotoEffects;
use robotd_render::sheet_art::{sheet_art, thick_line, SheetDesign, SheetPlacement};
use robotd_render::{look_at, Intrinsics, RenderOptions, RenderScene, Renderer, Shape, Solid};
use robotd_sim::{ObjectShape, ObjectSpec, Scene, SimObject};
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

/// The distractors a frame may have.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Distractor {
    PencilLines,
    TapedPaper,
    Cable,
    Hand,
    ObjectsBeside,
    SecondSheet,
    CoveredMarker,
    CornerBlobs,
    PaintedCentres,
}

const DISTRACTORS: [(Distractor, &str, f64); 9] = [
    (Distractor::PencilLines, "pencil lines on the sheet", 0.25),
    (Distractor::TapedPaper, "taped paper", 0.15),
    (Distractor::Cable, "cable", 0.2),
    (Distractor::Hand, "hand at the border", 0.15),
    (Distractor::ObjectsBeside, "objects beside the sheet", 0.3),
    (Distractor::SecondSheet, "second sheet", 0.15),
    (Distractor::CoveredMarker, "marker half covered", 0.08),
    (
        Distractor::CornerBlobs,
        "dark/green blobs near a corner",
        0.25,
    ),
    (
        Distractor::PaintedCentres,
        "marker centres painted red",
        0.05,
    ),
];

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
        let camera_from_world = case.camera.inverse();
        let corner_error = corner_points(&workspace)
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
            .fold(0f64, f64::max);
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

/// One randomized frame's scene and conditions.
struct Case {
    scene: RenderScene,
    camera: Isometry3<f64>,
    /// Where the arm holds the tool: a few centimetres from the camera, as on the wrist.
    tool_pose: robotd_protocol::geometry::Pose,
    /// How far the kinematics' camera position is off the truth (mount, calibration), metres.
    camera_error: [f64; 3],
    photo: PhotoEffects,
    jpeg_quality: u8,
    truth: Vec<SimObject>,
    design_index: usize,
    sheet_expected: bool,
    covered: bool,
    distractors: Vec<Distractor>,
}

fn corner_points(ws: &WorkspaceInfo) -> [[f64; 2]; 4] {
    let (x0, x1) = (ws.lower_right.x_m, ws.upper_left.x_m);
    let (y0, y1) = (ws.lower_right.y_m, ws.upper_left.y_m);
    [[x1, y1], [x1, y0], [x0, y1], [x0, y0]]
}

fn box_solid(x: f64, y: f64, size: [f64; 3], yaw: f64, color: [u8; 3]) -> Solid {
    Solid {
        shape: Shape::Box {
            size_m: Vector3::new(size[0], size[1], size[2]),
        },
        pose: Isometry3::from_parts(
            Translation3::new(x, y, size[2] / 2.0 + 0.0005),
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
        ),
        color,
    }
}

fn sim_object(id: u32, spec: ObjectSpec) -> SimObject {
    let [_, _, height] = spec.shape.extents_m();
    let pose = Isometry3::from_parts(
        Translation3::new(spec.x_m, spec.y_m, height / 2.0),
        UnitQuaternion::from_euler_angles(0.0, 0.0, spec.yaw_rad),
    );
    SimObject {
        id,
        spec,
        pose,
        held: false,
    }
}

fn make_case(
    rng: &mut SmallRng,
    workspace: &WorkspaceInfo,
    table: &LabelTable,
    intrinsics: &Intrinsics,
) -> Case {
    let design_index = rng.random_range(0..3);
    let design = [SheetDesign::Plain, SheetDesign::Classic, SheetDesign::Ned2][design_index];
    let corners = corner_points(workspace);
    let placement = SheetPlacement {
        x_min: corners[3][0],
        x_max: corners[0][0],
        y_min: corners[3][1],
        y_max: corners[0][1],
        marker_radius_m: if design == SheetDesign::Classic {
            0.0105
        } else {
            0.010
        },
    };
    let tables: [[u8; 3]; 4] = [
        [118, 96, 72],
        [150, 150, 145],
        [215, 212, 205],
        [60, 58, 55],
    ];
    let mut scene = RenderScene {
        background: tables[rng.random_range(0..tables.len())],
        table_z_m: 0.0,
        quads: Vec::new(),
        discs: Vec::new(),
        solids: Vec::new(),
    };
    let distractors: Vec<Distractor> = DISTRACTORS
        .iter()
        .filter(|(_, _, p)| rng.random_bool(*p))
        .map(|(d, _, _)| *d)
        .collect();
    let has = |d: Distractor| distractors.contains(&d);

    // A second sheet beside the first, drawn first (the first lies over its edge if they
    // meet).
    if has(Distractor::SecondSheet) {
        let (dx, dy) = match rng.random_range(0..3) {
            0 => (0.0, 0.235),
            1 => (0.0, -0.235),
            _ => (-0.235, 0.0),
        };
        let second = SheetPlacement {
            x_min: placement.x_min + dx,
            x_max: placement.x_max + dx,
            y_min: placement.y_min + dy,
            y_max: placement.y_max + dy,
            ..placement
        };
        let other =
            [SheetDesign::Plain, SheetDesign::Classic, SheetDesign::Ned2][rng.random_range(0..3)];
        sheet_art(other, &second, &mut scene);
    }
    sheet_art(design, &placement, &mut scene);
    let (cx, cy) = (
        0.5 * (placement.x_min + placement.x_max),
        0.5 * (placement.y_min + placement.y_max),
    );

    // Objects on the sheet: random ones of the label table, maybe a two-coloured bar.
    let mut specs = super::random_objects(rng, table, workspace, 6);
    let mut truth: Vec<SimObject> = Vec::new();
    let mut multi: Option<(SimObject, Vec<Solid>)> = None;
    if rng.random_bool(0.3) {
        let length = rng.random_range(0.05..0.08);
        let width = rng.random_range(0.018..0.03);
        let height = rng.random_range(0.01..0.02);
        let margin = 0.5 * length + 0.015;
        let x = rng.random_range(placement.x_min + margin..placement.x_max - margin);
        let y = rng.random_range(placement.y_min + margin..placement.y_max - margin);
        let clear = specs.iter().all(|s| {
            let [ex, ey, _] = s.shape.extents_m();
            (s.x_m - x).hypot(s.y_m - y) > 0.5 * ex.hypot(ey) + 0.5 * length + 0.015
        });
        if clear {
            let yaw: f64 = rng.random_range(0.0..std::f64::consts::PI);
            let colours: Vec<[u8; 3]> = table.colours.iter().map(|c| c.rgb).collect();
            let a = colours[rng.random_range(0..colours.len())];
            let mut b = colours[rng.random_range(0..colours.len())];
            if a == b {
                b = [215, 175, 60]; // gold foil
            }
            // The wrapper's colour at both ends, a band of the other across the middle third.
            let (s, c) = yaw.sin_cos();
            let third = length / 3.0;
            let pieces = vec![
                box_solid(x + c * third, y + s * third, [third, width, height], yaw, a),
                box_solid(x, y, [third, width, height], yaw, b),
                box_solid(x - c * third, y - s * third, [third, width, height], yaw, a),
            ];
            let spec = ObjectSpec::new(
                "banded bar",
                ObjectShape::Box {
                    length_x_m: length,
                    width_y_m: width,
                    height_z_m: height,
                },
                a,
                x,
                y,
            )
            .with_yaw(yaw);
            multi = Some((sim_object(1000, spec), pieces));
        }
    }
    for (k, spec) in specs.drain(..).enumerate() {
        let object = sim_object(k as u32, spec);
        scene.solids.push(solid_of(&object));
        truth.push(object);
    }
    if let Some((object, pieces)) = multi {
        scene.solids.extend(pieces);
        truth.push(object);
    }

    // Distractors.
    let r = placement.marker_radius_m;
    let (x0, x1, y0, y1) = (
        placement.x_min,
        placement.x_max,
        placement.y_min,
        placement.y_max,
    );
    if has(Distractor::TapedPaper) {
        let side = rng.random_range(0.06..0.1);
        let (px, py) = (
            cx + rng.random_range(-0.02..0.02),
            cy + rng.random_range(-0.02..0.02),
        );
        let yaw: f64 = rng.random_range(-0.3..0.3);
        let (s, c) = yaw.sin_cos();
        let corner = |u: f64, v: f64| Point3::new(px + c * u - s * v, py + s * u + c * v, 0.00045);
        let hs = side / 2.0;
        scene.quads.push((
            [
                corner(-hs, -hs),
                corner(hs, -hs),
                corner(hs, hs),
                corner(-hs, hs),
            ],
            [238, 238, 232],
        ));
    }
    if has(Distractor::PencilLines) || has(Distractor::TapedPaper) && rng.random_bool(0.5) {
        // A tic-tac-toe grid in pencil: two lines each way.
        let size = rng.random_range(0.05..0.09);
        let grey = rng.random_range(80..150) as u8;
        let width = rng.random_range(0.0004..0.0012);
        for k in [-1.0, 1.0] {
            let o = k * size / 6.0;
            thick_line(
                [cx + o, cy - size / 2.0],
                [cx + o, cy + size / 2.0],
                width,
                0.0005,
                [grey; 3],
                &mut scene,
            );
            thick_line(
                [cx - size / 2.0, cy + o],
                [cx + size / 2.0, cy + o],
                width,
                0.0005,
                [grey; 3],
                &mut scene,
            );
        }
    }
    if has(Distractor::Cable) {
        // Along the sheet's border outside the markers' rectangle, from the table onto the
        // sheet's margin.
        let off = rng.random_range(1.9..3.0) * r;
        let y_side = if rng.random_bool(0.5) {
            y1 + off
        } else {
            y0 - off
        };
        let mut last = [x0 - 0.05, y_side + rng.random_range(-0.01..0.01)];
        let width = rng.random_range(0.004..0.007);
        for k in 1..=10 {
            let next = [
                x0 - 0.05 + k as f64 * 0.03,
                y_side + rng.random_range(-0.004..0.004),
            ];
            thick_line(last, next, width, 0.0006, [35, 35, 38], &mut scene);
            last = next;
        }
    }
    if has(Distractor::Hand) {
        // A hand reaching to the sheet's lower edge: palm and fingers, skin-coloured boxes.
        let skin = [205, 150, 120];
        let y = rng.random_range(y0 + 0.03..y1 - 0.03);
        scene
            .solids
            .push(box_solid(x0 - 0.09, y, [0.08, 0.08, 0.025], 0.0, skin));
        for f in 0..4 {
            let fy = y - 0.027 + f as f64 * 0.018;
            scene
                .solids
                .push(box_solid(x0 - 0.035, fy, [0.03, 0.014, 0.014], 0.0, skin));
        }
    }
    if has(Distractor::ObjectsBeside) {
        let colours: Vec<[u8; 3]> = table.colours.iter().map(|c| c.rgb).collect();
        for _ in 0..rng.random_range(1..=3) {
            let side = rng.random_range(0.02..0.04);
            let (x, y) = if rng.random_bool(0.5) {
                (
                    rng.random_range(x0..x1),
                    if rng.random_bool(0.5) {
                        y1 + 0.06
                    } else {
                        y0 - 0.06
                    },
                )
            } else {
                (x0 - 0.06, rng.random_range(y0..y1))
            };
            let colour = colours[rng.random_range(0..colours.len())];
            scene.solids.push(box_solid(
                x,
                y,
                [side, side, side],
                rng.random_range(0.0..1.5),
                colour,
            ));
        }
    }
    if has(Distractor::CornerBlobs) {
        // Cube-sized blobs by a corner marker: a dark one just outside the sheet, a green cube
        // on the sheet just inside the corner (an object to find, not a marker).
        let k = rng.random_range(0..4);
        let [mx, my] = corners[k];
        let (sx, sy) = ((mx - cx).signum(), (my - cy).signum());
        let d = rng.random_range(0.035..0.05);
        scene.solids.push(box_solid(
            mx + sx * d,
            my + sy * d * 0.3,
            [0.025, 0.025, 0.025],
            0.3,
            [38, 38, 40],
        ));
        let (gx, gy) = (mx - sx * 0.032, my - sy * 0.032);
        let clear = truth.iter().all(|o| {
            let [ex, ey, _] = o.spec.shape.extents_m();
            (o.pose.translation.x - gx).hypot(o.pose.translation.y - gy)
                > 0.5 * ex.hypot(ey) + 0.035
        });
        if clear {
            let green = table
                .colours
                .iter()
                .find(|c| c.name == "green")
                .map_or([40, 150, 60], |c| c.rgb);
            let spec = ObjectSpec::new(
                "green cube",
                ObjectShape::Box {
                    length_x_m: 0.025,
                    width_y_m: 0.025,
                    height_z_m: 0.025,
                },
                green,
                gx,
                gy,
            )
            .with_yaw(0.2);
            let object = sim_object(2000, spec);
            scene.solids.push(solid_of(&object));
            truth.push(object);
        }
    }
    let painted = has(Distractor::PaintedCentres);
    if painted {
        // Another program painted the markers' centres red.
        for [x, y] in corners {
            scene.discs.push(robotd_render::Disc {
                center: Point3::new(x, y, 0.0006),
                radius_m: 0.3 * r,
                color: [220, 30, 30],
            });
        }
    }
    let covered = has(Distractor::CoveredMarker);
    if covered {
        // A sheet of card over half of one marker.
        let [mx, my] = corners[rng.random_range(0..4)];
        let (sx, sy) = ((mx - cx).signum(), (my - cy).signum());
        scene.solids.push(box_solid(
            mx + sx * 0.02,
            my + sy * 0.001,
            [0.04, 0.03, 0.002],
            0.0,
            [200, 60, 50],
        ));
    }

    // The camera: above the sheet, tilted up to 30° in any direction, turned any way.
    let mut camera = Isometry3::identity();
    let mut in_view = false;
    for _ in 0..40 {
        let height = rng.random_range(0.24..0.42);
        let tilt: f64 = rng.random_range(0f64..30.0).to_radians();
        let azimuth: f64 = rng.random_range(0.0..std::f64::consts::TAU);
        let target = Point3::new(
            cx + rng.random_range(-0.015..0.015),
            cy + rng.random_range(-0.015..0.015),
            0.0,
        );
        let eye = Point3::new(
            target.x + height * tilt.sin() * azimuth.cos(),
            target.y + height * tilt.sin() * azimuth.sin(),
            height * tilt.cos(),
        );
        let roll: f64 = rng.random_range(0.0..std::f64::consts::TAU);
        let up = Vector3::new(roll.cos(), roll.sin(), 0.0);
        camera = look_at(&eye, &target, &up);
        let inverse = camera.inverse();
        in_view = corners.iter().all(|&[x, y]| {
            (0..8).all(|k| {
                let a = k as f64 * std::f64::consts::FRAC_PI_4;
                intrinsics
                    .project(
                        &inverse,
                        &Point3::new(x + 1.6 * r * a.cos(), y + 1.6 * r * a.sin(), 0.0),
                    )
                    .is_some_and(|p| {
                        p.x >= 6.0
                            && p.y >= 6.0
                            && p.x <= f64::from(intrinsics.width) - 7.0
                            && p.y <= f64::from(intrinsics.height) - 7.0
                    })
            })
        });
        if in_view {
            break;
        }
    }

    let photo = PhotoEffects {
        exposure: rng.random_range(0.6..1.2),
        light_gradient: [rng.random_range(-0.35..0.35), rng.random_range(-0.35..0.35)],
        white_balance: [
            rng.random_range(0.85..1.15),
            1.0,
            rng.random_range(0.8..1.15),
        ],
        vignetting: rng.random_range(0.0..0.35),
        glare: rng.random_bool(0.3).then(|| {
            (
                [rng.random_range(0.1..0.9), rng.random_range(0.1..0.9)],
                rng.random_range(0.05..0.15),
                rng.random_range(0.2..0.5),
            )
        }),
        blur_px: [0, 0, 0, 1, 1, 2][rng.random_range(0..6)],
    };
    // The tool a few centimetres from the camera, as a wrist camera is mounted.
    let eye = camera.translation.vector;
    let tool_pose = robotd_protocol::geometry::Pose::new(
        eye.x + rng.random_range(-0.04..0.04),
        eye.y + rng.random_range(-0.04..0.04),
        eye.z + rng.random_range(-0.05..0.0),
        0.0,
        0.0,
        0.0,
    );
    let camera_error = [
        rng.random_range(-0.02..0.02),
        rng.random_range(-0.02..0.02),
        rng.random_range(-0.02..0.02),
    ];
    Case {
        scene,
        camera,
        tool_pose,
        camera_error,
        photo,
        jpeg_quality: rng.random_range(40..=95),
        truth,
        design_index,
        sheet_expected: in_view && !covered && !painted,
        covered: covered || painted,
        distractors,
    }
}
