//! One frame through perception: markers → table plane → detector → [`Detections`].
//!
//! [`Pipeline`] is the whole per-frame computation without the bus, so the actor, the tests
//! and `robotd bench perception` run exactly the same code. Which workspace the camera looks
//! at is decided from the arm's pose (the configured workspace whose observation pose is
//! nearest the tool) — workspaces can share one sheet (`niryo_ws` and `gazebo_1`) — but where
//! the sheet is, and so where every object is, comes from the markers in the pixels alone.

use crate::camera::Camera;
use crate::detector::{DetectError, Detector, FrameView, SheetView};
use crate::markers::{
    sheet_candidates, CandidateTrace, MarkerFinder, MarkerObservation, SheetCheck,
};
use crate::plane::TablePlane;
use crate::sheet::{verify_sheet, Intrinsics as SheetIntrinsics};
use robotd_protocol::camera::CameraIntrinsics;
use robotd_protocol::geometry::Pose;
use robotd_protocol::location::WorkspacePoint;
use robotd_protocol::objects::{DetectedObject, Detections};
use robotd_protocol::validate::Validate;
use robotd_protocol::workspace::WorkspaceInfo;

/// The pipeline could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// The camera intrinsics are unusable.
    #[error("camera intrinsics are invalid: {0}")]
    Intrinsics(String),
    /// No workspace is configured, or one is invalid.
    #[error("workspaces: {0}")]
    Workspaces(String),
}

/// Why a frame gave no sheet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SheetStatus {
    /// The sheet was found and the detector ran.
    Found,
    /// Fewer than four ring markers were seen.
    MarkersMissing {
        /// How many markers were seen (0 to 3).
        seen: usize,
    },
    /// Four or more ring markers were seen, but no four of them pass every check that makes
    /// them the sheet; `failed` is the furthest check any four reached.
    NotASheet {
        /// How many ring markers were seen.
        seen: usize,
        /// The check that failed.
        failed: SheetCheck,
    },
    /// The markers were seen but give no sensible camera pose.
    Degenerate,
}

impl std::fmt::Display for SheetStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Found => write!(f, "the workspace sheet and its four markers are in view"),
            Self::MarkersMissing { seen: 0 } => write!(
                f,
                "no workspace in view: none of the 4 workspace markers was found"
            ),
            Self::MarkersMissing { seen } => write!(
                f,
                "no workspace in view: only {seen} of the 4 workspace markers were found (one \
                 may be covered by an object, in shadow or out of the picture)"
            ),
            Self::NotASheet { seen, failed } => write!(
                f,
                "no workspace in view: {seen} ring markers were found, but no four of them \
                 make the workspace sheet: {failed}"
            ),
            Self::Degenerate => write!(
                f,
                "the 4 markers are in view but do not give a sensible camera pose (are they \
                 the configured workspace's?)"
            ),
        }
    }
}

/// Markers, plane and detector, for one camera.
pub struct Pipeline {
    pub(crate) camera: Camera,
    /// The intrinsics `camera` was made from.
    intrinsics: CameraIntrinsics,
    workspaces: Vec<WorkspaceInfo>,
    markers: MarkerFinder,
    detector: Box<dyn Detector>,
    /// The sheet found in the last frame [`Pipeline::process`] ran (`None`: not found).
    last_sheet: Option<(TablePlane, WorkspaceInfo)>,
    /// How many distinct sheets the last marker search saw (the nearest is used).
    sheets_in_view: usize,
    /// Whether the camera's intrinsics are calibrated or a guess.
    intrinsics_known: SheetIntrinsics,
    /// Where the camera is known to be (from the arm's kinematics when the frame was taken),
    /// if known: a sheet that puts the camera farther than [`MAX_CAMERA_GAP_M`] from it is
    /// another sheet than the configured workspace.
    expected_camera: Option<[f64; 3]>,
}

/// Whether a camera with `intrinsics` can be measured with.
fn usable(intrinsics: &CameraIntrinsics) -> Result<(), PipelineError> {
    intrinsics
        .validate()
        .map_err(|e| PipelineError::Intrinsics(e.to_string()))?;
    if intrinsics.width == 0 || intrinsics.height == 0 || intrinsics.width > 8192 {
        return Err(PipelineError::Intrinsics(format!(
            "image size {}x{} is not usable",
            intrinsics.width, intrinsics.height
        )));
    }
    Ok(())
}

/// A sheet may put the camera this far from where the arm's kinematics say it is, metres
/// (mount and calibration errors, a pose a little behind the frame). Two sheets side by side
/// are at least a sheet's width (about 21 cm) apart.
pub const MAX_CAMERA_GAP_M: f64 = 0.08;

impl std::fmt::Debug for Pipeline {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pipeline")
            .field("workspaces", &self.workspaces.len())
            .field("detector", &self.detector.name())
            .finish_non_exhaustive()
    }
}

impl Pipeline {
    /// A pipeline for a camera with `intrinsics`, the configured `workspaces` and `detector`.
    pub fn new(
        intrinsics: &CameraIntrinsics,
        workspaces: Vec<WorkspaceInfo>,
        detector: Box<dyn Detector>,
    ) -> Result<Pipeline, PipelineError> {
        usable(intrinsics)?;
        if workspaces.is_empty() {
            return Err(PipelineError::Workspaces(
                "no workspace is configured, so there is no sheet to look for".into(),
            ));
        }
        for ws in &workspaces {
            ws.validate()
                .map_err(|e| PipelineError::Workspaces(format!("{}: {e}", ws.id)))?;
        }
        Ok(Pipeline {
            camera: Camera::new(intrinsics),
            intrinsics: intrinsics.clone(),
            workspaces,
            markers: MarkerFinder::new(),
            detector,
            last_sheet: None,
            sheets_in_view: 0,
            intrinsics_known: SheetIntrinsics::Known,
            expected_camera: None,
        })
    }

    /// Takes the camera's intrinsics as its driver knows them now (a Ned2 sends its own
    /// calibration when it connects, maybe long after the pipeline was made): the next frames
    /// are undistorted and measured with them. `Ok(true)` when they changed; unusable ones
    /// are refused and the current ones kept.
    pub fn set_intrinsics(&mut self, intrinsics: &CameraIntrinsics) -> Result<bool, PipelineError> {
        usable(intrinsics)?;
        if *intrinsics == self.intrinsics {
            return Ok(false);
        }
        self.camera = Camera::new(intrinsics);
        self.intrinsics = intrinsics.clone();
        // The last sheet was measured through the old lens.
        self.last_sheet = None;
        Ok(true)
    }

    /// The intrinsics the pipeline measures with.
    pub fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }

    /// The table plane and workspace of the sheet found in the last frame
    /// [`Pipeline::process`] ran, if one was found there.
    pub fn last_sheet(&self) -> Option<&(TablePlane, WorkspaceInfo)> {
        self.last_sheet.as_ref()
    }

    /// The camera model (intrinsics and lens).
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// The detector's name.
    pub fn detector_name(&self) -> &str {
        self.detector.name()
    }

    /// The labels the detector can give.
    pub fn detector_labels(&self) -> Vec<String> {
        self.detector.labels()
    }

    /// The configured workspaces.
    pub fn workspaces(&self) -> &[WorkspaceInfo] {
        &self.workspaces
    }

    /// The workspace the camera is taken to look at: the one whose observation pose is nearest
    /// `tool_pose` (the first configured one without a pose).
    pub fn workspace_for(&self, tool_pose: Option<&Pose>) -> &WorkspaceInfo {
        let first = &self.workspaces[0];
        let Some(tool) = tool_pose else {
            return first;
        };
        self.workspaces
            .iter()
            .min_by(|a, b| {
                pose_gap(&a.observation_pose, tool).total_cmp(&pose_gap(&b.observation_pose, tool))
            })
            .unwrap_or(first)
    }

    /// Whether `tool_pose` is the observation pose of the workspace the camera looks at,
    /// within [`OBSERVATION_POSE_TOLERANCE`]. Only views from there describe the table
    /// faithfully: elsewhere a held object hangs over the sheet in the wrist camera's view and
    /// the tops of tall objects project away from their bases.
    pub fn at_observation_pose(&self, tool_pose: &Pose) -> bool {
        pose_gap(
            &self.workspace_for(Some(tool_pose)).observation_pose,
            tool_pose,
        ) <= OBSERVATION_POSE_TOLERANCE
    }

    /// Finds the sheet of `workspace` in `frame`: its table plane.
    pub fn locate_sheet(
        &mut self,
        frame: &FrameView<'_>,
        workspace: &WorkspaceInfo,
    ) -> Result<TablePlane, SheetStatus> {
        self.locate_with_markers(frame, workspace)
            .1
            .map(|(plane, _)| plane)
    }

    /// Every workspace marker found in `frame`, and the sheet of `workspace` they make (as
    /// [`Pipeline::plane_from_markers`] gives it). When the markers whose rings show give no
    /// sheet, a second look finds those too blurred or too small for their rings to show, by
    /// their blurred profile ([`crate::blurred_markers`]), and the sheet is sought again among
    /// all of them.
    #[allow(clippy::type_complexity)]
    pub fn locate_with_markers(
        &mut self,
        frame: &FrameView<'_>,
        workspace: &WorkspaceInfo,
    ) -> (
        Vec<MarkerObservation>,
        Result<(TablePlane, [MarkerObservation; 4]), SheetStatus>,
    ) {
        let mut markers = self.find_markers(frame);
        self.markers.fits.clear();
        let first = self.plane_from_markers(frame, &markers, workspace);
        if first.is_ok() {
            return (markers, first);
        }
        let blurred = self.markers.find_blurred_markers(&markers);
        if blurred.is_empty() {
            return (markers, first);
        }
        markers.extend(blurred);
        let second = self.plane_from_markers(frame, &markers, workspace);
        (markers, second)
    }

    /// The blurred-profile fits of the last frame's second look for markers (empty when the
    /// first look found the sheet).
    pub fn blurred_fits(
        &self,
    ) -> &[(
        crate::disc_scan::DiscCandidate,
        Option<crate::ring_fit::ModelFit>,
    )] {
        self.markers.blurred_fits()
    }

    /// Every workspace marker in `frame`.
    pub fn find_markers(&mut self, frame: &FrameView<'_>) -> Vec<MarkerObservation> {
        self.markers
            .find_markers(frame.rgb, frame.width, frame.height)
    }

    /// What became of every marker candidate of the last marker search (to find out why a
    /// marker was missed).
    pub fn marker_candidates(&self) -> &[CandidateTrace] {
        self.markers.candidates()
    }

    /// Says that the intrinsics given to [`Pipeline::new`] are a guess (a photo from an unknown
    /// camera): the focal length is then searched when a sheet is verified.
    pub fn with_guessed_intrinsics(mut self) -> Self {
        self.intrinsics_known = SheetIntrinsics::Guessed;
        self
    }

    /// How many distinct sheets the last marker search found (0 when none; with more than
    /// one, the nearest, the largest in the image, was used).
    pub fn sheets_in_view(&self) -> usize {
        self.sheets_in_view
    }

    /// The table plane of `workspace` from the markers found in `frame`, with the four markers
    /// used (upper-left = the origin, upper-right, lower-left, lower-right).
    ///
    /// A sheet is reported only when its geometry proves it ([`crate::sheet`]): four ring
    /// markers in a plausible quadrilateral, one of them the reference, that a pinhole camera
    /// can see as the configured rectangle, whose sizes on the table agree, with the sheet's
    /// white centre between them. With several sheets in view, the nearest is used.
    pub fn plane_from_markers(
        &mut self,
        frame: &FrameView<'_>,
        markers: &[MarkerObservation],
        workspace: &WorkspaceInfo,
    ) -> Result<(TablePlane, [MarkerObservation; 4]), SheetStatus> {
        self.sheets_in_view = 0;
        let seen = markers.len();
        if seen < 4 {
            return Err(SheetStatus::MarkersMissing { seen });
        }
        let candidates =
            sheet_candidates(markers).map_err(|failed| SheetStatus::NotASheet { seen, failed })?;
        let world = corner_points(workspace);
        let mut furthest: Option<SheetCheck> = None;
        // Each verified four, in the candidates' order (best first).
        let mut verified: Vec<(TablePlane, [MarkerObservation; 4])> = Vec::new();
        for orders in candidates {
            for order in orders {
                let ideal = order.map(|m| self.camera.ideal_of(m.centre_px));
                let Some(plane) =
                    TablePlane::from_correspondences(&ideal, &world, self.camera.intrinsics())
                else {
                    continue;
                };
                let checked = verify_sheet(
                    &self.camera,
                    self.intrinsics_known,
                    frame,
                    &plane,
                    &order,
                    &world,
                )
                .and_then(|()| self.where_the_arm_is(&plane));
                match checked {
                    Ok(()) => {
                        verified.push((plane, order));
                        break;
                    }
                    Err(check) => furthest = Some(furthest.map_or(check, |f| f.max(check))),
                }
            }
        }
        // Distinct sheets: the best four of each group sharing markers.
        let mut sheets: Vec<(TablePlane, [MarkerObservation; 4])> = Vec::new();
        for (plane, four) in verified {
            let shares = |other: &[MarkerObservation; 4]| {
                four.iter()
                    .any(|m| other.iter().any(|o| o.centre_px == m.centre_px))
            };
            if !sheets.iter().any(|(_, other)| shares(other)) {
                sheets.push((plane, four));
            }
        }
        self.sheets_in_view = sheets.len();
        let mean_radius =
            |four: &[MarkerObservation; 4]| four.iter().map(|m| m.radius_px).sum::<f64>();
        sheets
            .into_iter()
            .max_by(|a, b| mean_radius(&a.1).total_cmp(&mean_radius(&b.1)))
            .ok_or(match furthest {
                Some(failed) => SheetStatus::NotASheet { seen, failed },
                None => SheetStatus::Degenerate,
            })
    }

    /// Says where the camera is for the next frames (`None`: not known), from the arm's
    /// kinematics: a frame header's `camera_pose`. A sheet found must then put the camera
    /// within [`MAX_CAMERA_GAP_M`] of it, so that another sheet in view is never taken for the
    /// configured workspace.
    pub fn expect_camera_at(&mut self, position: Option<[f64; 3]>) {
        self.expected_camera = position.filter(|p| p.iter().all(|v| v.is_finite()));
    }

    /// Whether `plane` puts the camera where the arm holds it (when that is known): a sheet
    /// that is not the configured workspace (another sheet beside it, its own reference
    /// marker covered) puts it a sheet's width away.
    fn where_the_arm_is(&self, plane: &TablePlane) -> Result<(), SheetCheck> {
        let Some(expected) = self.expected_camera else {
            return Ok(());
        };
        let c = plane.camera_centre();
        let gap = ((c[0] - expected[0]).powi(2)
            + (c[1] - expected[1]).powi(2)
            + (c[2] - expected[2]).powi(2))
        .sqrt();
        if gap > MAX_CAMERA_GAP_M {
            return Err(SheetCheck::NotThisWorkspace);
        }
        Ok(())
    }

    /// The table plane of a frame that is already the workspace square, warped so that the
    /// four marker centres are the image's corners with the origin marker top-left (what the
    /// Niryo software's "extracted workspace" images and its 200×200 crops are). The camera must
    /// be a pinhole without distortion of the frame's size.
    pub fn warped_plane(&self, workspace: &WorkspaceInfo) -> Option<TablePlane> {
        let (w, h) = self.camera.size();
        let (r, b) = (w as f64 - 0.5, h as f64 - 0.5);
        let corners = [[-0.5, -0.5], [r, -0.5], [-0.5, b], [r, b]];
        TablePlane::from_correspondences(
            &corners,
            &corner_points(workspace),
            self.camera.intrinsics(),
        )
    }

    /// Runs the detector on `frame` of the sheet of `workspace` at `plane`.
    pub fn detect_on(
        &mut self,
        frame: &FrameView<'_>,
        workspace: &WorkspaceInfo,
        plane: TablePlane,
    ) -> Result<Vec<DetectedObject>, DetectError> {
        let sheet = SheetView {
            workspace,
            plane,
            camera: &self.camera,
        };
        self.detector.detect(frame, &sheet)
    }

    /// Runs one frame. `tool_pose` (the arm's pose when the frame was taken) picks the
    /// workspace; `steady` is copied into the result.
    pub fn process(
        &mut self,
        frame: &FrameView<'_>,
        tool_pose: Option<&Pose>,
        steady: bool,
    ) -> Result<(Detections, SheetStatus), DetectError> {
        let (w, h) = self.camera.size();
        let mut detections = Detections {
            frame_id: frame.frame_id,
            workspace_id: String::new(),
            timestamp_unix_ns: frame.timestamp_unix_ns,
            source: self.detector.name().to_owned(),
            steady,
            objects: Vec::new(),
        };
        if frame.width != w || frame.height != h {
            return Err(DetectError {
                detector: self.detector.name().to_owned(),
                reason: format!(
                    "frame is {}x{} but the camera intrinsics are for {w}x{h}",
                    frame.width, frame.height
                ),
            });
        }
        let workspace = self.workspace_for(tool_pose).clone();
        self.last_sheet = None;
        let plane = match self.locate_sheet(frame, &workspace) {
            Ok(plane) => plane,
            Err(status) => return Ok((detections, status)),
        };
        self.last_sheet = Some((plane.clone(), workspace.clone()));
        let sheet = SheetView {
            workspace: &workspace,
            plane,
            camera: &self.camera,
        };
        detections.objects = self.detector.detect(frame, &sheet)?;
        detections.workspace_id = workspace.id.clone();
        Ok((detections, SheetStatus::Found))
    }
}

/// The table points of a workspace's corner markers: upper-left, upper-right, lower-left,
/// lower-right.
fn corner_points(workspace: &WorkspaceInfo) -> [[f64; 2]; 4] {
    [
        WorkspacePoint::UpperLeftCorner,
        WorkspacePoint::UpperRightCorner,
        WorkspacePoint::LowerLeftCorner,
        WorkspacePoint::LowerRightCorner,
    ]
    .map(|p| {
        let q = workspace.point(p);
        [q.x_m, q.y_m]
    })
}

/// How far from its observation pose (in `pose_gap` units: metres plus radians/10) the
/// tool may be for a view to count as taken from there: 1.5 cm, or 1 cm and 0.05 rad. Arms
/// repeat a pose to well under a millimetre.
pub const OBSERVATION_POSE_TOLERANCE: f64 = 0.015;

/// How far apart two poses are, for picking the nearest observation pose: metres plus
/// radians/10 (1 cm ≈ 0.1 rad).
fn pose_gap(a: &Pose, b: &Pose) -> f64 {
    let d = a.distance_to(b);
    let angle = |x: f64, y: f64| {
        let diff = (x - y).rem_euclid(std::f64::consts::TAU);
        diff.min(std::f64::consts::TAU - diff)
    };
    let r = angle(a.roll_rad, b.roll_rad)
        + angle(a.pitch_rad, b.pitch_rad)
        + angle(a.yaw_rad, b.yaw_rad);
    d + r / 10.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detector::{ColourDetector, ColourDetectorSettings};
    use crate::labels::LabelTable;
    use robotd_protocol::geometry::{Point2, RobotModel};

    fn workspace(id: &str, observation_pose: Pose) -> WorkspaceInfo {
        WorkspaceInfo {
            id: id.into(),
            robot: RobotModel::Ned2,
            upper_left: Point2::new(0.337, 0.087),
            lower_right: Point2::new(0.163, -0.087),
            observation_pose,
        }
    }

    #[test]
    fn only_poses_near_an_observation_pose_count_as_at_it() {
        let a = Pose::new(0.173, -0.002, 0.277, -3.042, 1.327, -3.027);
        let b = Pose::new(0.0, 0.25, 0.277, -3.042, 1.327, -1.5);
        let detector =
            ColourDetector::new(LabelTable::builtin(), ColourDetectorSettings::default());
        let pipeline = Pipeline::new(
            &robotd_render::Intrinsics::ned2().into(),
            vec![workspace("a", a), workspace("b", b)],
            Box::new(detector),
        )
        .unwrap();
        assert!(pipeline.at_observation_pose(&a));
        assert!(pipeline.at_observation_pose(&b));
        let near = Pose {
            z_m: a.z_m + 0.005,
            ..a
        };
        assert!(pipeline.at_observation_pose(&near));
        let lower = Pose {
            z_m: a.z_m - 0.03,
            ..a
        };
        assert!(!pipeline.at_observation_pose(&lower), "3 cm lower");
        let tilted = Pose {
            pitch_rad: a.pitch_rad + 0.2,
            ..a
        };
        assert!(!pipeline.at_observation_pose(&tilted), "0.2 rad tilted");
        let above_an_object = Pose::new(0.25, 0.065, 0.09, 0.0, std::f64::consts::FRAC_PI_2, 0.0);
        assert!(!pipeline.at_observation_pose(&above_an_object));
    }

    #[test]
    fn new_intrinsics_are_taken_and_unusable_ones_refused_keeping_the_current() {
        let a = Pose::new(0.173, -0.002, 0.277, -3.042, 1.327, -3.027);
        let detector =
            ColourDetector::new(LabelTable::builtin(), ColourDetectorSettings::default());
        let nominal: CameraIntrinsics = robotd_render::Intrinsics::ned2().into();
        let mut pipeline =
            Pipeline::new(&nominal, vec![workspace("a", a)], Box::new(detector)).unwrap();
        assert!(
            !pipeline.set_intrinsics(&nominal).unwrap(),
            "the same: no change"
        );
        let mut calibrated = nominal.clone();
        calibrated.cx += 3.0;
        assert!(pipeline.set_intrinsics(&calibrated).unwrap());
        assert_eq!(pipeline.intrinsics(), &calibrated);
        let mut broken = calibrated.clone();
        broken.fx = f64::NAN;
        assert!(pipeline.set_intrinsics(&broken).is_err());
        assert_eq!(
            pipeline.intrinsics(),
            &calibrated,
            "the current ones are kept"
        );
    }
}
