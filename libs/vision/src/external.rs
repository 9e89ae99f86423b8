//! Objects an external detector found in a frame robotd published: pixels in, world objects out.
//!
//! A GPU detector in Python (OWLv2, YOLO-World, YOLOE) reads robotd's camera frames from Redis
//! and answers with labels, pixel boxes and, usually, masks. This module turns such a
//! [`PixelObject`] into the same [`DetectedObject`](robotd_protocol::objects::DetectedObject) the built-in detector makes, through the same
//! chain: the frame's workspace markers give the table plane, and [`crate::footprint::measure`]
//! maps the object's pixels onto it. So external and built-in perception are interchangeable;
//! only who found the pixels differs.
//!
//! An object's pixels are its mask when it has one, else every pixel of its box. They are mapped
//! at the height of the object's top face when its label is in the [`LabelTable`] (a fixed
//! height, or a cube's side), else on the table (a mask of a whole object, sides included, lies
//! mostly there).

use crate::detector::FrameView;
use crate::footprint::{measure, Footprint, Sighting};
use crate::labels::{HeightRule, LabelTable};
use crate::pipeline::{Pipeline, SheetStatus};
use crate::plane::TablePlane;
use crate::rect::normalise_half_turn;
use robotd_protocol::geometry::{Point2, Pose};
use robotd_protocol::objects::{Detections, RelBox, RelPoint};
use robotd_protocol::workspace::WorkspaceInfo;

/// The workspace sheet perception found in one frame: what pixels of that frame — or of any
/// frame taken from the same camera pose — map onto.
#[derive(Debug, Clone)]
pub struct KnownSheet {
    /// The frame it was found in.
    pub frame_id: u64,
    /// That frame's capture time, ns since the Unix epoch.
    pub timestamp_unix_ns: u64,
    /// That frame's header camera pose: x, y, z (m), roll, pitch, yaw (rad).
    pub camera_pose: [f64; 6],
    /// Whether the arm stood still at an observation pose.
    pub steady: bool,
    /// The workspace of the sheet.
    pub workspace: WorkspaceInfo,
    /// Its table plane.
    pub plane: TablePlane,
}

/// An object's centre may lie this far outside its workspace and still count, metres.
const OUTSIDE_TOLERANCE_M: f64 = 0.01;

/// One object as an external detector reports it, in pixels of the frame it looked at.
#[derive(Debug, Clone, PartialEq)]
pub struct PixelObject {
    /// Its label (any case; stored lower-case).
    pub label: String,
    /// The detector's confidence, 0..=1.
    pub confidence: f64,
    /// The detector's class index (−1 when it has none).
    pub class_id: i64,
    /// Bounding box `[x_min, y_min, x_max, y_max]` in pixels (max exclusive).
    pub bbox_px: [u32; 4],
    /// The object's pixels (indices `v × width + u` of the frame), from its mask; `None` uses
    /// the whole box.
    pub mask_pixels: Option<Vec<u32>>,
}

/// Why an external object gave no world object.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Skipped {
    /// Its box lies outside the frame or is empty.
    BadBox,
    /// Fewer than three pixels (or a degenerate footprint).
    TooSmall,
    /// Its footprint lies outside the workspace.
    OutsideWorkspace,
}

impl Pipeline {
    /// Turns `objects` found by detector `source` in `frame` into world detections, as
    /// [`Pipeline::process`] does with its own detector's. `tool_pose` (the arm's pose when
    /// the frame was taken) picks the workspace; `heights` names the heights of known labels.
    /// Objects that cannot be placed are left out and counted in the returned list of skips.
    pub fn locate_pixel_objects(
        &mut self,
        frame: &FrameView<'_>,
        tool_pose: Option<&Pose>,
        steady: bool,
        source: &str,
        objects: &[PixelObject],
        heights: &LabelTable,
    ) -> (Detections, SheetStatus, Vec<Skipped>) {
        let workspace = self.workspace_for(tool_pose).clone();
        let plane = match self.locate_sheet(frame, &workspace) {
            Ok(plane) => plane,
            Err(status) => {
                let detections = Detections {
                    frame_id: frame.frame_id,
                    workspace_id: String::new(),
                    timestamp_unix_ns: frame.timestamp_unix_ns,
                    source: source.to_owned(),
                    steady,
                    objects: Vec::new(),
                };
                return (detections, status, Vec::new());
            }
        };
        let sheet = KnownSheet {
            frame_id: frame.frame_id,
            timestamp_unix_ns: frame.timestamp_unix_ns,
            camera_pose: [0.0; 6],
            steady,
            workspace,
            plane,
        };
        let (detections, skipped) = self.place_pixel_objects(
            &sheet,
            (frame.width, frame.height),
            source,
            objects,
            heights,
        );
        (detections, SheetStatus::Found, skipped)
    }

    /// Places `objects` (pixels of a `size` = width × height frame) on the table of `sheet`:
    /// the detections carry the sheet's frame id, time and steadiness.
    pub fn place_pixel_objects(
        &self,
        sheet: &KnownSheet,
        size: (usize, usize),
        source: &str,
        objects: &[PixelObject],
        heights: &LabelTable,
    ) -> (Detections, Vec<Skipped>) {
        let mut detections = Detections {
            frame_id: sheet.frame_id,
            workspace_id: sheet.workspace.id.clone(),
            timestamp_unix_ns: sheet.timestamp_unix_ns,
            source: source.to_owned(),
            steady: sheet.steady,
            objects: Vec::new(),
        };
        let workspace = &sheet.workspace;
        let plane = &sheet.plane;
        let (w, h) = size;
        let mut skipped = Vec::new();
        for object in objects {
            let [x0, y0, x1, y1] = object.bbox_px;
            let (x1, y1) = (x1.min(w as u32), y1.min(h as u32));
            if x0 >= x1 || y0 >= y1 {
                skipped.push(Skipped::BadBox);
                continue;
            }
            let box_pixels;
            let pixels: &[u32] = match &object.mask_pixels {
                Some(mask) => mask,
                None => {
                    box_pixels = (y0..y1)
                        .flat_map(|v| (x0..x1).map(move |u| v * w as u32 + u))
                        .collect::<Vec<u32>>();
                    &box_pixels
                }
            };
            let label = object.label.trim().to_lowercase();
            let rule = heights.rules.iter().find(|r| r.label == label);
            let camera = &self.camera;
            let mut height_m = 0.0;
            let mut footprint: Option<Footprint> = None;
            for _ in 0..3 {
                let Some(fp) = measure(pixels, w, camera, plane, height_m) else {
                    break;
                };
                footprint = Some(fp);
                let next = match rule.map(|r| r.height) {
                    Some(HeightRule::Fixed(h)) => h,
                    Some(HeightRule::Side) => fp.rect.short,
                    None => 0.0,
                };
                if (next - height_m).abs() < 0.0003 {
                    break;
                }
                height_m = next;
            }
            let Some(fp) = footprint else {
                skipped.push(Skipped::TooSmall);
                continue;
            };
            let centre = fp.rect.centre;
            if !workspace.contains(Point2::new(centre[0], centre[1]), OUTSIDE_TOLERANCE_M) {
                skipped.push(Skipped::OutsideWorkspace);
                continue;
            }
            let (wf, hf) = (w as f64, h as f64);
            let n = pixels.len().max(1) as f64;
            let (su, sv) = pixels.iter().fold((0.0, 0.0), |(su, sv), &i| {
                (su + (i as usize % w) as f64, sv + (i as usize / w) as f64)
            });
            detections.objects.push(fp.to_object(Sighting {
                label,
                class_id: object.class_id,
                confidence: object.confidence.clamp(0.0, 1.0),
                workspace_id: workspace.id.clone(),
                timestamp_unix_s: sheet.timestamp_unix_ns as f64 / 1e9,
                bbox: RelBox {
                    u_min: f64::from(x0) / wf,
                    v_min: f64::from(y0) / hf,
                    u_max: f64::from(x1) / wf,
                    v_max: f64::from(y1) / hf,
                },
                center_of_mass_rel: RelPoint {
                    u: (su / n + 0.5) / wf,
                    v: (sv / n + 0.5) / hf,
                },
                gripper_rotation_rad: normalise_half_turn(fp.rect.angle),
            }));
        }
        (detections, skipped)
    }
}
