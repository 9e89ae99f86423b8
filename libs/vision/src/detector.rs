//! Detectors: what turns a frame of a workspace into objects, and the built-in one.
//!
//! A [`Detector`] gets the frame and the [`SheetView`] the marker stage found (which workspace,
//! its table plane, the camera) and returns world-frame objects. Detectors differ in how they
//! find an object's pixels — [`ColourDetector`] (built in) by colour and shape, a neural
//! network behind a cargo feature by inference, an external detector by the masks it sends
//! over Redis — and share [`crate::footprint::measure`] for everything after that, so the
//! geometry is the same whoever found the object.
//!
//! The colour detector, per frame:
//! 1. looks only inside the sheet (the workspace rectangle grown by a margin, projected into
//!    the image): outside lies the table, whose brown would look like an orange object;
//! 2. classifies each pixel with enough hue by its nearest colour of the label table (by hue
//!    signature, so shading and anti-aliasing against the white sheet do not change it); a
//!    pixel whose hue is far from every colour of the table, or (where the sheet is plain,
//!    inside its markers) one much darker than the sheet around it ([`crate::shade`]), is of
//!    the *unknown* class;
//! 3. groups touching pixels of one class into blobs, and blobs that are fragments of one object
//!    (a wrapper's letters, a pad's rim, a cube's deep shadow) into one ([`crate::groups`]);
//! 4. keeps of each coloured object its top face — the pixels nearly as bright and as saturated
//!    as its brightest, since side faces are lit less — and measures it at the object's height
//!    (first guess the table, then the label rule's height) to name it by the label table.
//!    Unknown objects are measured on all their pixels and reported as [`UNKNOWN_LABEL`] with
//!    their geometry, for an external detector or the user to name.

use crate::background::SheetBackground;
use crate::camera::Camera;
use crate::components::Components;
use crate::footprint::{measure, Footprint, Sighting};
use crate::groups::{group_fragments, Gaps};
use crate::labels::{hue_signature, HeightRule, LabelTable, ShapeClass};
use crate::plane::TablePlane;
use crate::rect::{normalise_half_turn, normalise_quarter_turn};
use crate::shade::LocalMean;
use crate::spans::sheet_spans;
use robotd_protocol::objects::{DetectedObject, RelBox, RelPoint};
use robotd_protocol::workspace::WorkspaceInfo;

/// Hue signatures closer than this are neighbouring hues (blue–cyan 0.69, red–pink 0.46,
/// red–orange 0.48; red–blue 1.44, green–cyan 0.83): pieces of neighbouring hues may be one
/// object.
const NEIGHBOUR_HUE_DISTANCE: f32 = 0.75;

/// One frame, as row-major RGB8.
#[derive(Debug, Clone, Copy)]
pub struct FrameView<'a> {
    /// The pixels (`width × height × 3` bytes).
    pub rgb: &'a [u8],
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// The camera's frame id.
    pub frame_id: u64,
    /// Capture time, nanoseconds since the Unix epoch.
    pub timestamp_unix_ns: u64,
}

/// The workspace sheet found in a frame: which workspace it is and how to map its pixels.
#[derive(Debug, Clone)]
pub struct SheetView<'a> {
    /// The workspace.
    pub workspace: &'a WorkspaceInfo,
    /// The table plane from its markers.
    pub plane: TablePlane,
    /// The camera.
    pub camera: &'a Camera,
}

/// A detector failed on a frame (the frame is skipped; the detector is used again).
#[derive(Debug, thiserror::Error)]
#[error("{detector}: {reason}")]
pub struct DetectError {
    /// Which detector.
    pub detector: String,
    /// What went wrong.
    pub reason: String,
}

/// Finds objects in frames of a workspace.
pub trait Detector: Send {
    /// Its name, the `source` of the detections it makes.
    fn name(&self) -> &str;
    /// The labels it can give.
    fn labels(&self) -> Vec<String>;
    /// The objects in `frame`, in world coordinates (ids left empty: the workspace model
    /// assigns them).
    fn detect(
        &mut self,
        frame: &FrameView<'_>,
        sheet: &SheetView<'_>,
    ) -> Result<Vec<DetectedObject>, DetectError>;
}

/// Settings of the colour detector.
#[derive(Debug, Clone, PartialEq)]
pub struct ColourDetectorSettings {
    /// How far beyond the workspace rectangle to look, metres (the sheet reaches 18 mm
    /// beyond its marker centres).
    pub sheet_margin_m: f64,
    /// Smallest blob considered, pixels.
    pub min_blob_px: u32,
    /// Smallest top face considered, pixels.
    pub min_top_px: usize,
    /// Height assumed for objects no label rule names, metres.
    pub unknown_height_m: f64,
    /// Objects whose centre lies farther than this outside the workspace are dropped, metres.
    pub outside_tolerance_m: f64,
    /// Dark objects are looked for only this far inside the workspace rectangle, metres,
    /// where the sheet is plain white (clear of the markers and the border's stripes), or
    /// farther when the sheet's printed border is measured wider in the frame.
    pub plain_inset_m: f64,
    /// Nothing smaller than this along its longer side is an object, metres.
    pub min_size_m: f64,
    /// Nothing thinner than this is an object, metres (pencil and pen lines, paper edges,
    /// printing): twice the area over the outline's length, which is a line's width and half
    /// a square's side.
    pub min_thickness_m: f64,
}

impl Default for ColourDetectorSettings {
    fn default() -> Self {
        Self {
            sheet_margin_m: 0.016,
            min_blob_px: 25,
            min_top_px: 12,
            unknown_height_m: 0.02,
            outside_tolerance_m: 0.01,
            plain_inset_m: 0.012,
            min_size_m: 0.008,
            min_thickness_m: 0.0025,
        }
    }
}

/// Pixels need at least this much chroma (max − min of r, g, b) to be part of an object.
const MIN_CHROMA: u8 = 35;
/// Pixels without hue are part of an object when darker than this share (per cent) of the
/// sheet around them: black plastic, a dark wrapper — not the shadows objects cast.
const DARK_OBJECT_PERCENT: u32 = 45;
/// A pixel's hue signature must be this close to a colour of the table to take its class.
const MAX_HUE_DISTANCE: f32 = 0.45;

/// The label of an object whose colour is not in the label table (or that is much darker than
/// the sheet): reported with its geometry, for an external detector or the user to name.
pub const UNKNOWN_LABEL: &str = "unknown object";
/// The confidence given to such objects.
const UNKNOWN_CONFIDENCE: f64 = 0.3;

/// Top faces closer to square than this (long/short) are treated as squares for the gripper
/// rotation: it is reported modulo 90°.
pub const SQUARE_SYMMETRY_ASPECT: f64 = 1.1;

/// The built-in detector: coloured objects on a white sheet.
#[derive(Debug)]
pub struct ColourDetector {
    table: LabelTable,
    settings: ColourDetectorSettings,
    classes: Vec<u8>,
    spans: Vec<(u16, u16)>,
    inner_spans: Vec<(u16, u16)>,
    dark_candidates: Vec<u32>,
    shade: LocalMean,
    components: Components,
}

impl ColourDetector {
    /// A detector naming objects with `table`.
    pub fn new(table: LabelTable, settings: ColourDetectorSettings) -> Self {
        Self {
            table,
            settings,
            classes: Vec::new(),
            spans: Vec::new(),
            inner_spans: Vec::new(),
            dark_candidates: Vec::new(),
            shade: LocalMean::default(),
            components: Components::new(),
        }
    }

    /// The label table.
    pub fn table(&self) -> &LabelTable {
        &self.table
    }

    /// The class of pixels that belong to an object of no colour in the table: another hue,
    /// or much darker than the sheet.
    fn unknown_class(&self) -> u8 {
        (self.table.colours.len() + 1).min(255) as u8
    }

    /// Classifies the pixels inside the sheet; colours are judged after `gains` (the white
    /// balance that makes the sheet's paper grey).
    fn classify_pixels(&mut self, frame: &FrameView<'_>, gains: [f32; 3]) {
        let (w, h) = (frame.width, frame.height);
        self.classes.clear();
        self.classes.resize(w * h, 0);
        let signatures: Vec<[f32; 3]> = self.table.colours.iter().map(|c| c.signature).collect();
        let unknown = self.unknown_class();
        self.dark_candidates.clear();
        for v in 0..h {
            let (start, end) = self.spans[v];
            let row = v * w;
            for u in start as usize..end as usize {
                let i = row + u;
                let p = &frame.rgb[i * 3..i * 3 + 3];
                let q = [
                    (f32::from(p[0]) * gains[0]).min(255.0),
                    (f32::from(p[1]) * gains[1]).min(255.0),
                    (f32::from(p[2]) * gains[2]).min(255.0),
                ];
                let max = q[0].max(q[1]).max(q[2]);
                let min = q[0].min(q[1]).min(q[2]);
                let chroma = max - min;
                if chroma < f32::from(MIN_CHROMA) || chroma * 4.0 < max {
                    // No hue: the white sheet, its grey stripes and logo, shadows — or a dark
                    // object, far darker than the sheet around it (only where the sheet is
                    // plain: inside its markers, clear of the stripes and the markers).
                    let (a, b) = self.inner_spans[v];
                    let grey =
                        (u32::from(p[0]) * 77 + u32::from(p[1]) * 150 + u32::from(p[2]) * 29) >> 8;
                    if (a as usize..b as usize).contains(&u)
                        && grey * 100 < 255 * DARK_OBJECT_PERCENT
                    {
                        self.dark_candidates.push(i as u32);
                    }
                    continue;
                }
                let inv = 1.0 / chroma;
                let s = [(q[0] - min) * inv, (q[1] - min) * inv, (q[2] - min) * inv];
                let mut best = (0usize, f32::MAX);
                for (k, r) in signatures.iter().enumerate() {
                    let d = (r[0] - s[0]).powi(2) + (r[1] - s[1]).powi(2) + (r[2] - s[2]).powi(2);
                    if d < best.1 {
                        best = (k, d);
                    }
                }
                self.classes[i] = if best.1 <= MAX_HUE_DISTANCE * MAX_HUE_DISTANCE {
                    best.0 as u8 + 1
                } else {
                    unknown
                };
            }
        }
        // Only pixels dark enough to be part of a dark object need the sheet's brightness
        // around them (on the simulator's sheets there are none).
        if !self.dark_candidates.is_empty() {
            self.shade.compute(frame.rgb, w, h);
            let half = (w.min(h) / 6).max(8);
            for &i in &self.dark_candidates {
                let (u, v) = (i as usize % w, i as usize / w);
                if self.shade.darker_than(u, v, half, DARK_OBJECT_PERCENT) {
                    self.classes[i as usize] = unknown;
                }
            }
        }
    }
}

/// How many pixels a metre on the table spans at the workspace's centre (raw image).
fn pixels_per_metre(sheet: &SheetView<'_>) -> f64 {
    let c = sheet.workspace.center();
    let at = |x: f64, y: f64| sheet.camera.raw_of(sheet.plane.table_to_pixel(x, y));
    let (a, b) = (at(c.x_m, c.y_m), at(c.x_m + 0.01, c.y_m));
    let d = (a[0] - b[0]).hypot(a[1] - b[1]) / 0.01;
    if d.is_finite() {
        d
    } else {
        1000.0
    }
}

/// Twice the area over the outline's length, pixels: the width of a line, half the side of a
/// square. The outline is the pixels with a 4-neighbour that is no object (class 0).
fn thickness_px(classes: &[u8], width: usize, height: usize, pixels: &[u32]) -> f64 {
    let mut outline = 0usize;
    for &i in pixels {
        let i = i as usize;
        let (u, v) = (i % width, i / width);
        let open = |j: usize| classes.get(j).is_none_or(|c| *c == 0);
        let at_frame_edge = u == 0 || v == 0 || u + 1 == width || v + 1 == height;
        if at_frame_edge || open(i - 1) || open(i + 1) || open(i - width) || open(i + width) {
            outline += 1;
        }
    }
    2.0 * pixels.len() as f64 / outline.max(1) as f64
}

/// The pixels of a blob that belong to its top face: nearly as bright and as saturated as the
/// blob's brightest (95th percentile).
fn top_face(rgb: &[u8], pixels: &[u32]) -> Vec<u32> {
    let mut brightness = [0u32; 256];
    let mut chroma = [0u32; 256];
    for &i in pixels {
        let p = &rgb[i as usize * 3..i as usize * 3 + 3];
        let max = p[0].max(p[1]).max(p[2]);
        let min = p[0].min(p[1]).min(p[2]);
        brightness[max as usize] += 1;
        chroma[(max - min) as usize] += 1;
    }
    let percentile = |hist: &[u32; 256], q: f64| {
        let target = (pixels.len() as f64 * q).ceil() as u32;
        let mut seen = 0;
        for (value, count) in hist.iter().enumerate() {
            seen += count;
            if seen >= target {
                return value as f64;
            }
        }
        255.0
    };
    let (b95, c95) = (percentile(&brightness, 0.95), percentile(&chroma, 0.95));
    let (b_min, c_min) = (0.8 * b95, 0.6 * c95);
    pixels
        .iter()
        .copied()
        .filter(|&i| {
            let p = &rgb[i as usize * 3..i as usize * 3 + 3];
            let max = p[0].max(p[1]).max(p[2]);
            let min = p[0].min(p[1]).min(p[2]);
            f64::from(max) >= b_min && f64::from(max - min) >= c_min
        })
        .collect()
}

impl Detector for ColourDetector {
    fn name(&self) -> &str {
        "robotd"
    }

    fn labels(&self) -> Vec<String> {
        self.table.labels()
    }

    fn detect(
        &mut self,
        frame: &FrameView<'_>,
        sheet: &SheetView<'_>,
    ) -> Result<Vec<DetectedObject>, DetectError> {
        let (w, h) = (frame.width, frame.height);
        if frame.rgb.len() < w * h * 3 || w == 0 || h == 0 || w > u16::MAX as usize {
            return Err(DetectError {
                detector: self.name().to_owned(),
                reason: format!(
                    "frame of {w}x{h} pixels has {} bytes, expected {}",
                    frame.rgb.len(),
                    w * h * 3
                ),
            });
        }
        // The sheet itself, measured in this frame: its paper's colour and its printed border.
        let background = SheetBackground::measure(frame, sheet);
        let gains = background.map_or([1.0; 3], |b| b.gains);
        let inset = background.map_or(self.settings.plain_inset_m, |b| {
            b.border_m.max(self.settings.plain_inset_m)
        });
        sheet_spans(sheet, self.settings.sheet_margin_m, w, h, &mut self.spans);
        sheet_spans(sheet, -inset, w, h, &mut self.inner_spans);
        self.classify_pixels(frame, gains);
        self.components
            .label(&self.classes, w, h, self.settings.min_blob_px);

        let timestamp = frame.timestamp_unix_ns as f64 / 1e9;
        let ws = sheet.workspace;
        let mut objects = Vec::new();
        let unknown = self.unknown_class();
        // Fragments 2 mm apart are one object; small dark pieces 8 mm from a larger one join it;
        // a piece of another colour under 5 mm × 5 mm is a sliver of its neighbour.
        let px_per_m = pixels_per_metre(sheet);
        let gaps = Gaps {
            join_px: (0.002 * px_per_m).round().clamp(2.0, 50.0) as u32,
            absorb_px: (0.008 * px_per_m).round().clamp(2.0, 150.0) as u32,
            sliver_px: (0.005 * px_per_m).powi(2).round().clamp(1.0, 1e6) as u32,
        };
        // Hues this close (blue and cyan, red and pink) may be one printed object; red and
        // blue never are.
        let signatures: Vec<[f32; 3]> = self.table.colours.iter().map(|c| c.signature).collect();
        let neighbour_hues = |a: u8, b: u8| {
            let (Some(x), Some(y)) = (
                signatures.get(usize::from(a).wrapping_sub(1)),
                signatures.get(usize::from(b).wrapping_sub(1)),
            ) else {
                return false;
            };
            let d2: f32 = x.iter().zip(y).map(|(p, q)| (p - q) * (p - q)).sum();
            d2 < NEIGHBOUR_HUE_DISTANCE * NEIGHBOUR_HUE_DISTANCE
        };
        for blob in group_fragments(&self.components, unknown, w, gaps, neighbour_hues) {
            // A dark or unknown-coloured object has no reliable brightest face: all of it.
            let top = if blob.class == unknown {
                blob.pixels.clone()
            } else {
                top_face(frame.rgb, &blob.pixels)
            };
            if top.len() < self.settings.min_top_px {
                continue;
            }
            // Lines and specks are not objects: too thin, or too small, on the table.
            let thickness_m = thickness_px(&self.classes, w, h, &blob.pixels) / px_per_m;
            let extent_m =
                f64::from((blob.u_max - blob.u_min + 1).max(blob.v_max - blob.v_min + 1))
                    / px_per_m;
            if thickness_m < self.settings.min_thickness_m || extent_m < self.settings.min_size_m {
                continue;
            }
            let colour = usize::from(blob.class - 1);
            let colour_ref = self.table.colours.get(colour);

            // Measure on the table first, then at the height of the rule that names it.
            let mut height_m = 0.0;
            let mut found: Option<(Footprint, ShapeClass, Option<usize>)> = None;
            for _ in 0..4 {
                let Some(fp) = measure(&top, w, sheet.camera, &sheet.plane, height_m) else {
                    break;
                };
                let aspect = fp.rect.long / fp.rect.short.max(1e-6);
                let shape = ShapeClass::measure(aspect, fp.fill);
                let rule = self.table.rule_index_for(colour, shape, fp.rect.long);
                let next = match rule.map(|r| &self.table.rules[r]) {
                    Some(r) => match r.height {
                        HeightRule::Fixed(h) => h,
                        HeightRule::Side => fp.rect.short,
                    },
                    None => self.settings.unknown_height_m,
                };
                let settled = (next - height_m).abs() < 0.0003;
                found = Some((fp, shape, rule));
                if settled {
                    break;
                }
                height_m = next;
            }
            let Some((fp, shape, rule)) = found else {
                continue;
            };
            let centre = fp.rect.centre;
            let outside = self.settings.outside_tolerance_m;
            if !ws.contains(
                robotd_protocol::geometry::Point2::new(centre[0], centre[1]),
                outside,
            ) {
                continue;
            }

            // Mean hue distance of the top face to its colour: how sure the colour is.
            let mut mean = [0f32; 3];
            for &i in &top {
                let p = &frame.rgb[i as usize * 3..i as usize * 3 + 3];
                for c in 0..3 {
                    mean[c] += f32::from(p[c]);
                }
            }
            let mean = mean.map(|s| s / top.len() as f32);
            let hue_distance = hue_signature(mean)
                .zip(colour_ref)
                .map(|(s, colour_ref)| {
                    s.iter()
                        .zip(&colour_ref.signature)
                        .map(|(a, b)| (a - b) * (a - b))
                        .sum::<f32>()
                        .sqrt()
                })
                .unwrap_or(1.0);
            let shape_fit = if rule.is_some() { 1.0 } else { 0.6 };
            let confidence = if colour_ref.is_none() {
                UNKNOWN_CONFIDENCE
            } else {
                (f64::from(1.0 - hue_distance / MAX_HUE_DISTANCE) * shape_fit).clamp(0.05, 0.99)
            };

            let (label, class_id) = match (rule, colour_ref) {
                (Some(r), _) => (self.table.rules[r].label.clone(), r as i64),
                (None, Some(c)) => (format!("{} {}", c.name, shape.noun()), -1),
                (None, None) => (UNKNOWN_LABEL.to_owned(), -1),
            };
            // A square looks the same turned by 90°: report the smallest such rotation.
            let aspect = fp.rect.long / fp.rect.short.max(1e-6);
            let gripper_rotation = match shape {
                ShapeClass::Round => 0.0,
                _ if aspect < SQUARE_SYMMETRY_ASPECT => normalise_quarter_turn(fp.rect.angle),
                _ => normalise_half_turn(fp.rect.angle),
            };
            let (wf, hf) = (w as f64, h as f64);
            objects.push(fp.to_object(Sighting {
                label,
                class_id,
                confidence,
                workspace_id: ws.id.clone(),
                timestamp_unix_s: timestamp,
                bbox: RelBox {
                    u_min: f64::from(blob.u_min) / wf,
                    v_min: f64::from(blob.v_min) / hf,
                    u_max: f64::from(blob.u_max + 1) / wf,
                    v_max: f64::from(blob.v_max + 1) / hf,
                },
                center_of_mass_rel: RelPoint {
                    u: (blob.u_mean + 0.5) / wf,
                    v: (blob.v_mean + 0.5) / hf,
                },
                gripper_rotation_rad: gripper_rotation,
            }));
        }
        Ok(objects)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::Pipeline;
    use robotd_protocol::geometry::{Point2, Pose, RobotModel};
    use robotd_render::Intrinsics;

    #[test]
    fn objects_of_unknown_colour_and_dark_objects_are_reported_not_dropped() {
        // A 200×200 image that is the workspace square: a red, a lime (between the table's
        // yellow and green) and a black square on a white sheet lit unevenly.
        let n = 200;
        let mut rgb = vec![0u8; n * n * 3];
        for v in 0..n {
            for u in 0..n {
                let light = (235 - 60 * u / n) as u8;
                let colour = match (u / 50, v / 50) {
                    (0, 1) => [200, 30, 30],
                    (2, 1) => [120, 230, 10],
                    (1, 3) => [30, 30, 30],
                    _ => [light, light, light],
                };
                let inside = (u % 50) > 10 && (v % 50) > 10;
                let p = if inside {
                    colour
                } else {
                    [light, light, light]
                };
                rgb[(v * n + u) * 3..][..3].copy_from_slice(&p);
            }
        }
        let workspace = WorkspaceInfo {
            id: "ws".into(),
            robot: RobotModel::Ned2,
            upper_left: Point2::new(0.337, 0.087),
            lower_right: Point2::new(0.163, -0.087),
            observation_pose: Pose::new(0.173, -0.002, 0.277, -3.042, 1.327, -3.027),
        };
        let intrinsics = Intrinsics {
            width: n as u32,
            height: n as u32,
            fx: 300.0,
            fy: 300.0,
            cx: 99.5,
            cy: 99.5,
            distortion: [0.0; 5],
        };
        let detector =
            ColourDetector::new(LabelTable::builtin(), ColourDetectorSettings::default());
        let mut pipeline = Pipeline::new(
            &intrinsics.into(),
            vec![workspace.clone()],
            Box::new(detector),
        )
        .unwrap();
        let plane = pipeline.warped_plane(&workspace).unwrap();
        let frame = FrameView {
            rgb: &rgb,
            width: n,
            height: n,
            frame_id: 1,
            timestamp_unix_ns: 0,
        };
        let objects = pipeline.detect_on(&frame, &workspace, plane).unwrap();
        let mut labels: Vec<&str> = objects.iter().map(|o| o.label.as_str()).collect();
        labels.sort();
        assert_eq!(
            labels,
            ["red cube", UNKNOWN_LABEL, UNKNOWN_LABEL],
            "{objects:#?}"
        );
        for o in &objects {
            // 39 px of 200 across a 174 mm square: 34 mm on the table, less at the height the
            // object is measured at (3 cm for a red cube, 2 cm for unknown objects).
            assert!((0.028..0.036).contains(&o.dimensions.width_m), "{o:#?}");
            assert!(workspace.contains(
                Point2::new(o.position.center.x_m, o.position.center.y_m),
                0.0
            ));
        }
    }
}
