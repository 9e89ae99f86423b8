//! What `robotd detect` found in one image, as JSON (`--json`) or as text.
//!
//! The report says which markers were seen and which four made the sheet (the reference
//! marker first), whether the workspace was found or why not, and every object with its pixel
//! box, its position relative to the workspace (0..1 from the upper-left corner, along the
//! upper edge and down the left edge, as the Niryo tools count), its world position, size,
//! label, colour and confidence — plus how long each step took.

use robotd_perception::labels::LabelTable;
use robotd_perception::markers::{MarkerEvidence, MarkerObservation};
use robotd_protocol::objects::DetectedObject;
use robotd_protocol::workspace::WorkspaceInfo;
use serde::Serialize;

/// The whole report.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// The image file.
    pub image: String,
    /// Its width, pixels.
    pub width: usize,
    /// Its height, pixels.
    pub height: usize,
    /// The camera model used (`ned2`, `file`, `pinhole guess`, `warped`).
    pub camera: String,
    /// The workspace whose coordinates are reported.
    pub workspace_id: String,
    /// `markers` (the sheet from its four markers), `warped` (the image is already the
    /// workspace square) or `none`.
    pub mode: String,
    /// Whether the workspace was found.
    pub workspace_found: bool,
    /// What was found, or why the workspace was not.
    pub status: String,
    /// Every marker seen.
    pub markers: Vec<MarkerReport>,
    /// The objects on the workspace.
    pub objects: Vec<ObjectReport>,
    /// Time per step.
    pub timing: Timing,
}

/// One marker.
#[derive(Debug, Clone, Serialize)]
pub struct MarkerReport {
    /// Centre, pixels.
    pub centre_px: [f64; 2],
    /// Outer radius, pixels.
    pub radius_px: f64,
    /// Concentric dark blobs counted.
    pub rings: u8,
    /// Whether its centre is white.
    pub white_centre: bool,
    /// Its corner of the sheet (`upper_left` is the reference marker), or `null` when it is
    /// not one of the sheet's four.
    pub corner: Option<String>,
    /// Whether it is the reference (origin) marker.
    pub reference: bool,
    /// The blur (Gaussian σ, pixels) its profile showed when it was found by its blurred
    /// profile, its rings too merged to see one by one; `null` when its rings were seen.
    pub blur_px: Option<f64>,
}

/// One object.
#[derive(Debug, Clone, Serialize)]
pub struct ObjectReport {
    /// Its label.
    pub label: String,
    /// Its colour in the label table, or `unknown`.
    pub colour: String,
    /// The detector's confidence.
    pub confidence: f64,
    /// Pixel box `[u_min, v_min, u_max, v_max]`.
    pub box_px: [f64; 4],
    /// Centre of mass of its pixels.
    pub centre_px: [f64; 2],
    /// Position in the workspace: 0..1 along the upper edge (from the reference marker) and
    /// 0..1 down the left edge.
    pub workspace_rel: [f64; 2],
    /// Centre in the robot's base frame, metres (z: half its height).
    pub world_m: [f64; 3],
    /// Width (along y) and length (along x) of its footprint, metres.
    pub size_m: [f64; 2],
    /// Yaw the gripper turns by to grasp it, radians.
    pub gripper_rotation_rad: f64,
}

/// Time per step, milliseconds.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Timing {
    /// Reading and decoding the file.
    pub decode_ms: f64,
    /// Finding the markers and the plane.
    pub markers_ms: f64,
    /// The detector.
    pub detect_ms: f64,
    /// Markers, plane and detector together (decoding not included).
    pub perception_ms: f64,
}

impl Report {
    /// The human-readable report.
    pub fn text(&self) -> String {
        let mut out = format!(
            "{} ({}x{}), camera: {}, workspace {}\n",
            self.image, self.width, self.height, self.camera, self.workspace_id
        );
        out += &format!("markers: {} seen\n", self.markers.len());
        for m in &self.markers {
            out += &format!(
                "  ({:7.1}, {:7.1}) r {:5.1} px, {} rings{}{}{}\n",
                m.centre_px[0],
                m.centre_px[1],
                m.radius_px,
                m.rings,
                if m.white_centre { ", white centre" } else { "" },
                m.blur_px.map_or(String::new(), |b| format!(
                    ", seen by its blurred profile (blur {b:.1} px)"
                )),
                match (&m.corner, m.reference) {
                    (Some(c), true) => format!("  -> {c} (reference)"),
                    (Some(c), false) => format!("  -> {c}"),
                    (None, _) => "  (not used)".into(),
                }
            );
        }
        out += &format!(
            "workspace: {} ({})\n",
            if self.workspace_found {
                "found"
            } else {
                "NOT found"
            },
            self.status
        );
        out += &format!("objects: {}\n", self.objects.len());
        for (k, o) in self.objects.iter().enumerate() {
            out += &format!(
                "  {:>2}. {:<16} {:<8} conf {:.2}  box [{:.0}, {:.0}, {:.0}, {:.0}] px  \
                 rel ({:.3}, {:.3})  world ({:.3}, {:.3}, {:.3}) m  size {:.0} x {:.0} mm  \
                 yaw {:.2} rad\n",
                k + 1,
                o.label,
                o.colour,
                o.confidence,
                o.box_px[0],
                o.box_px[1],
                o.box_px[2],
                o.box_px[3],
                o.workspace_rel[0],
                o.workspace_rel[1],
                o.world_m[0],
                o.world_m[1],
                o.world_m[2],
                o.size_m[0] * 1000.0,
                o.size_m[1] * 1000.0,
                o.gripper_rotation_rad,
            );
        }
        out += &format!(
            "time: decode {:.1} ms, markers + plane {:.1} ms, detector {:.1} ms, perception \
             {:.1} ms\n",
            self.timing.decode_ms,
            self.timing.markers_ms,
            self.timing.detect_ms,
            self.timing.perception_ms
        );
        out
    }
}

/// The corner names in the order `Pipeline::plane_from_markers` returns the four markers.
const CORNERS: [&str; 4] = ["upper_left", "upper_right", "lower_left", "lower_right"];

pub fn marker_reports(
    markers: &[MarkerObservation],
    corners: Option<&[MarkerObservation; 4]>,
) -> Vec<MarkerReport> {
    markers
        .iter()
        .map(|m| {
            let corner = corners
                .and_then(|c| c.iter().position(|k| k.centre_px == m.centre_px))
                .map(|k| CORNERS[k].to_owned());
            MarkerReport {
                centre_px: m.centre_px,
                radius_px: m.radius_px,
                rings: m.rings,
                white_centre: m.white_centre,
                reference: corner.as_deref() == Some("upper_left"),
                corner,
                blur_px: match m.evidence {
                    MarkerEvidence::Rings => None,
                    MarkerEvidence::Profile { blur_px, .. } => Some(blur_px),
                },
            }
        })
        .collect()
}

pub fn object_report(
    o: &DetectedObject,
    workspace: &WorkspaceInfo,
    table: &LabelTable,
    width: usize,
    height: usize,
) -> ObjectReport {
    let b = &o.image_coordinates.bounding_box_rel;
    let (w, h) = (width as f64, height as f64);
    let (ul, lr) = (workspace.upper_left, workspace.lower_right);
    let c = o.position.center;
    let colour = table
        .rules
        .iter()
        .find(|r| r.label == o.label)
        .map(|r| table.colours[r.colour].name.clone())
        .or_else(|| {
            let first = o.label.split_whitespace().next()?;
            table
                .colours
                .iter()
                .find(|c| c.name == first)
                .map(|c| c.name.clone())
        })
        .unwrap_or_else(|| "unknown".into());
    ObjectReport {
        label: o.label.clone(),
        colour,
        confidence: o.confidence,
        box_px: [b.u_min * w, b.v_min * h, b.u_max * w, b.v_max * h],
        centre_px: [
            o.image_coordinates.center_of_mass_rel.u * w,
            o.image_coordinates.center_of_mass_rel.v * h,
        ],
        workspace_rel: [
            (ul.y_m - c.y_m) / (ul.y_m - lr.y_m),
            (ul.x_m - c.x_m) / (ul.x_m - lr.x_m),
        ],
        world_m: [c.x_m, c.y_m, c.z_m],
        size_m: [o.dimensions.width_m, o.dimensions.height_m],
        gripper_rotation_rad: o.gripper_rotation_rad,
    }
}
