//! Measuring the detector against the simulator's ground truth (feature `eval`).
//!
//! The perception actor itself never sees ground truth. This module is for the tests and for
//! `robotd bench perception`: it makes random scenes from the label table (every object a
//! rule names, at a random size within the rule, turned at random, placed apart on the
//! sheet), renders them with the simulated wrist camera at the workspace's observation pose,
//! runs the [`Pipeline`] on the pixels, and scores the detections against where the objects
//! really are. [`randomized`] does the same on thousands of frames varied as the world varies
//! them: sheet designs, light, lens, camera pose and distractors.

pub mod randomized;

use crate::detector::{ColourDetector, ColourDetectorSettings, FrameView, SQUARE_SYMMETRY_ASPECT};
use crate::labels::{HeightRule, LabelTable, ShapeClass};
use crate::pipeline::Pipeline;
use crate::rect::{normalise_half_turn, normalise_quarter_turn};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use robotd_driver::CameraDriver;
use robotd_driver_sim::faults::FaultInjector;
use robotd_driver_sim::{SimCamera, SimRobot, SimSettings};
use robotd_kinematics::{pose_to_isometry, Kinematics};
use robotd_protocol::geometry::Pose;
use robotd_protocol::objects::{DetectedObject, Detections};
use robotd_protocol::workspace::WorkspaceInfo;
use robotd_sim::{ObjectShape, ObjectSpec, Scene, SimObject};

/// Keep random objects this far inside the workspace rectangle, metres.
const EDGE_CLEARANCE_M: f64 = 0.012;
/// Keep random objects this far apart (between their enclosing circles), metres.
const OBJECT_GAP_M: f64 = 0.015;
/// A detection this close to an object counts as finding it, metres.
const MATCH_RADIUS_M: f64 = 0.02;

/// A simulated Ned2 at a workspace's observation pose, its camera and the perception pipeline.
pub struct Lab {
    robot: SimRobot,
    camera: SimCamera,
    pipeline: Pipeline,
    workspace: WorkspaceInfo,
    frame: Vec<u8>,
    next_frame_id: u64,
    /// Where the camera was for the last frame (the simulator's kinematics).
    camera_at: Option<[f64; 3]>,
}

impl std::fmt::Debug for Lab {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Lab")
            .field("workspace", &self.workspace.id)
            .finish_non_exhaustive()
    }
}

/// Errors setting up a [`Lab`].
#[derive(Debug, thiserror::Error)]
#[error("perception lab: {0}")]
pub struct LabError(pub String);

impl Lab {
    /// The default Ned2 scene without its objects, the arm at `niryo_ws`'s observation pose,
    /// the camera with `noise_stddev` and optional lens distortion, and the built-in detector.
    pub fn new(noise_stddev: f64, lens_distortion: bool) -> Result<Lab, LabError> {
        let mut scene = Scene::default_ned2();
        scene.objects.clear();
        let workspace = scene
            .workspace_infos()
            .into_iter()
            .next()
            .ok_or_else(|| LabError("the default scene has no workspace".into()))?;
        let robot = SimRobot::new(
            &scene,
            SimSettings {
                time_scale: 0.0,
                noise_stddev,
                lens_distortion,
                ..SimSettings::default()
            },
        );
        let kinematics = Kinematics::new(scene.robot);
        let joints = kinematics
            .inverse(&pose_to_isometry(&workspace.observation_pose), None)
            .map_err(|e| LabError(format!("observation pose: {e}")))?;
        robot
            .teleport(&joints)
            .map_err(|e| LabError(format!("observation pose: {e}")))?;
        let camera = robot.camera(FaultInjector::none("camera"));
        let detector =
            ColourDetector::new(LabelTable::builtin(), ColourDetectorSettings::default());
        let pipeline = Pipeline::new(
            &camera.intrinsics(),
            scene.workspace_infos(),
            Box::new(detector),
        )
        .map_err(|e| LabError(e.to_string()))?;
        let (w, h) = camera.size();
        Ok(Lab {
            robot,
            camera,
            pipeline,
            workspace,
            frame: vec![0; w as usize * h as usize * 3],
            next_frame_id: 0,
            camera_at: None,
        })
    }

    /// The camera's intrinsics (without distortion unless the lab simulates the lens).
    pub fn intrinsics(&self) -> robotd_protocol::camera::CameraIntrinsics {
        self.camera.intrinsics()
    }

    /// The workspace in view.
    pub fn workspace(&self) -> &WorkspaceInfo {
        &self.workspace
    }

    /// Replaces the objects on the table.
    pub fn set_objects(&mut self, objects: &[ObjectSpec]) -> Result<(), LabError> {
        self.robot.with_world(|world| {
            let ids: Vec<u32> = world.objects().iter().map(|o| o.id).collect();
            for id in ids {
                world.remove_object(id);
            }
            for o in objects {
                world
                    .add_object(o.clone())
                    .map_err(|e| LabError(format!("placing {}: {e}", o.label)))?;
            }
            Ok(())
        })
    }

    /// The objects on the table (ground truth).
    pub fn objects(&self) -> Vec<SimObject> {
        self.robot.with_world(|w| w.objects().to_vec())
    }

    /// Renders a frame into the lab's buffer; returns its id and capture time.
    pub fn capture(&mut self) -> Result<(u64, u64), LabError> {
        let info = self
            .camera
            .capture_into(&mut self.frame)
            .map_err(|e| LabError(format!("capture: {e}")))?;
        self.next_frame_id += 1;
        let t = info.camera_pose.translation.vector;
        self.camera_at = Some([t.x, t.y, t.z]);
        Ok((self.next_frame_id, info.timestamp_unix_ns))
    }

    /// The last captured frame (RGB8).
    pub fn frame(&self) -> &[u8] {
        &self.frame
    }

    /// The last captured frame, to change before [`Lab::detect`] (e.g. a JPEG round trip, as
    /// frames that crossed a network).
    pub fn frame_mut(&mut self) -> &mut [u8] {
        &mut self.frame
    }

    /// Runs the pipeline on the last captured frame.
    pub fn detect(
        &mut self,
        frame_id: u64,
        timestamp_unix_ns: u64,
    ) -> Result<Detections, LabError> {
        let (w, h) = self.camera.size();
        let view = FrameView {
            rgb: &self.frame,
            width: w as usize,
            height: h as usize,
            frame_id,
            timestamp_unix_ns,
        };
        let pose: Pose = self.workspace.observation_pose;
        self.pipeline.expect_camera_at(self.camera_at);
        self.pipeline
            .process(&view, Some(&pose), true)
            .map(|(d, _)| d)
            .map_err(|e| LabError(e.to_string()))
    }

    /// Captures and detects.
    pub fn capture_and_detect(&mut self) -> Result<Detections, LabError> {
        let (id, ts) = self.capture()?;
        self.detect(id, ts)
    }
}

/// A random scene of 1 … `max_objects` objects named by `table`'s rules, inside `workspace`.
pub fn random_objects(
    rng: &mut SmallRng,
    table: &LabelTable,
    workspace: &WorkspaceInfo,
    max_objects: usize,
) -> Vec<ObjectSpec> {
    let count = rng.random_range(1..=max_objects.max(1));
    let mut placed: Vec<(ObjectSpec, f64)> = Vec::new();
    let mut attempts = 0;
    while placed.len() < count && attempts < 500 {
        attempts += 1;
        let Some(rule) = table
            .rules
            .get(rng.random_range(0..table.rules.len().max(1)))
        else {
            break;
        };
        let colour = table.colours[rule.colour].rgb;
        let (lo, hi) = (rule.min_size_m.max(0.015), rule.max_size_m.min(0.09));
        if lo > hi {
            continue;
        }
        let height = |side: f64| match rule.height {
            HeightRule::Fixed(h) => h.max(0.002),
            HeightRule::Side => side,
        };
        let shape = match rule.shape {
            ShapeClass::Round => {
                let d = rng.random_range(lo..=hi.min(0.05));
                ObjectShape::Cylinder {
                    diameter_m: d,
                    height_m: height(d),
                }
            }
            ShapeClass::Bar => {
                let length = rng.random_range(lo.max(0.06)..=hi.min(0.14).max(lo.max(0.06)));
                let width = rng.random_range(0.012..=0.018);
                ObjectShape::Box {
                    length_x_m: length,
                    width_y_m: width,
                    height_z_m: height(width),
                }
            }
            ShapeClass::Square => {
                let s = rng.random_range(lo..=hi.min(0.05));
                ObjectShape::Box {
                    length_x_m: s,
                    width_y_m: s,
                    height_z_m: height(s),
                }
            }
            _ => {
                // Clearly oblong (≥ 1.35 : 1) so the side to grip across is unambiguous.
                let short = rng.random_range(lo..=(hi / 1.35).max(lo).min(0.06));
                let long = (short * rng.random_range(1.35..=1.8)).min(0.09);
                ObjectShape::Box {
                    length_x_m: long,
                    width_y_m: short,
                    height_z_m: height(short),
                }
            }
        };
        let [ex, ey, _] = shape.extents_m();
        let radius = 0.5 * ex.hypot(ey);
        let margin = radius + EDGE_CLEARANCE_M;
        let (x_lo, x_hi) = (
            workspace.lower_right.x_m + margin,
            workspace.upper_left.x_m - margin,
        );
        let (y_lo, y_hi) = (
            workspace.lower_right.y_m + margin,
            workspace.upper_left.y_m - margin,
        );
        if x_lo >= x_hi || y_lo >= y_hi {
            continue;
        }
        let (x, y) = (rng.random_range(x_lo..x_hi), rng.random_range(y_lo..y_hi));
        if placed
            .iter()
            .any(|(o, r)| (o.x_m - x).hypot(o.y_m - y) < r + radius + OBJECT_GAP_M)
        {
            continue;
        }
        let yaw = rng.random_range(0.0..std::f64::consts::PI);
        placed.push((
            ObjectSpec::new(&rule.label, shape, colour, x, y).with_yaw(yaw),
            radius,
        ));
    }
    placed.into_iter().map(|(o, _)| o).collect()
}

/// How one object was (or was not) detected.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectScore {
    /// The object's label.
    pub label: String,
    /// Its smallest side on the table, metres.
    pub min_side_m: f64,
    /// Distance from the detection's centre of mass to the object's centre, metres; `None`
    /// when not found.
    pub position_error_m: Option<f64>,
    /// Relative error of width and of height (the larger), when found.
    pub size_error: Option<f64>,
    /// Gripper-rotation error modulo the object's symmetry, radians; `None` when not found or
    /// round.
    pub rotation_error_rad: Option<f64>,
    /// Whether the label was right.
    pub label_ok: bool,
}

/// Scores of one frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameScore {
    /// One entry per object on the table.
    pub objects: Vec<ObjectScore>,
    /// Detections that matched no object.
    pub false_positives: usize,
}

/// Width (along y) and height (along x) of an upright object of ground truth, and the
/// direction of its longer side.
pub fn truth_geometry(object: &SimObject) -> (f64, f64, f64) {
    let yaw = object.yaw_rad();
    let [ex, ey, _] = object.spec.shape.extents_m();
    let (long, short, angle) = if ex >= ey {
        (ex, ey, yaw)
    } else {
        (ey, ex, yaw + std::f64::consts::FRAC_PI_2)
    };
    let angle = normalise_half_turn(angle);
    let (width, height) = if angle.sin().abs() >= angle.cos().abs() {
        (long, short)
    } else {
        (short, long)
    };
    (width, height, angle)
}

/// Matches detections to the objects (nearest first, within 2 cm) and scores them.
pub fn score(truth: &[SimObject], detections: &[DetectedObject]) -> FrameScore {
    let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
    for (i, o) in truth.iter().enumerate() {
        for (j, d) in detections.iter().enumerate() {
            let p = d.position.center_of_mass;
            let dist = (p.x_m - o.pose.translation.x).hypot(p.y_m - o.pose.translation.y);
            if dist <= MATCH_RADIUS_M {
                pairs.push((dist, i, j));
            }
        }
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut truth_match = vec![None; truth.len()];
    let mut used = vec![false; detections.len()];
    for (dist, i, j) in pairs {
        if truth_match[i].is_none() && !used[j] {
            truth_match[i] = Some((j, dist));
            used[j] = true;
        }
    }
    let objects = truth
        .iter()
        .zip(&truth_match)
        .map(|(o, m)| {
            let [ex, ey, _] = o.spec.shape.extents_m();
            let mut s = ObjectScore {
                label: o.spec.label.clone(),
                min_side_m: ex.min(ey),
                position_error_m: None,
                size_error: None,
                rotation_error_rad: None,
                label_ok: false,
            };
            if let Some((j, dist)) = m {
                let d = &detections[*j];
                let (w, h, angle) = truth_geometry(o);
                s.position_error_m = Some(*dist);
                s.size_error = Some(
                    ((d.dimensions.width_m - w).abs() / w)
                        .max((d.dimensions.height_m - h).abs() / h),
                );
                s.label_ok = d.label == o.spec.label;
                let round = matches!(o.spec.shape, ObjectShape::Cylinder { .. });
                if !round {
                    let aspect = ex.max(ey) / ex.min(ey);
                    let diff = d.gripper_rotation_rad - angle;
                    let err = if aspect < SQUARE_SYMMETRY_ASPECT {
                        normalise_quarter_turn(diff)
                    } else {
                        normalise_half_turn(diff)
                    };
                    s.rotation_error_rad = Some(err.abs());
                }
            }
            s
        })
        .collect();
    FrameScore {
        objects,
        false_positives: used.iter().filter(|u| !**u).count(),
    }
}

/// A seeded random generator for reproducible scenes.
pub fn rng(seed: u64) -> SmallRng {
    SmallRng::seed_from_u64(seed)
}

/// The `q`-quantile (0 … 1) of `values` (nearest rank); `NaN` when empty.
pub fn quantile(values: &[f64], q: f64) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let rank = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len());
    v[rank - 1]
}
