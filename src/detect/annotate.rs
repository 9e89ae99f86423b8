//! The annotated image of `robotd detect --out`: what the report says, drawn on the photo.
//!
//! The workspace rectangle is drawn through the table plane and the lens (so it follows the
//! sheet even in a distorted image), the markers as circles numbered the way the Niryo tools
//! number them (1 = reference in magenta, then 2–4 clockwise in cyan; markers not used in grey),
//! and each object as its pixel box with its number from the report (unknown-coloured objects
//! in orange).

use super::report::Report;
use robotd_perception::plane::TablePlane;
use robotd_perception::Pipeline;
use robotd_protocol::workspace::WorkspaceInfo;
use robotd_render::canvas::Canvas;

/// Colours of the drawing.
const REFERENCE: [u8; 3] = [255, 0, 255];
const CORNER: [u8; 3] = [0, 200, 255];
const UNUSED: [u8; 3] = [128, 128, 128];
const SHEET: [u8; 3] = [0, 220, 0];
const UNKNOWN: [u8; 3] = [255, 140, 0];
const KNOWN: [u8; 3] = [20, 20, 20];

pub fn annotate(
    rgb: &mut [u8],
    report: &Report,
    workspace: &WorkspaceInfo,
    sheet: Option<&(Pipeline, TablePlane)>,
) {
    let mut canvas = Canvas::new(rgb, report.width, report.height);
    // The workspace rectangle, through the plane and the lens.
    if let Some((pipeline, plane)) = sheet {
        let (ul, lr) = (workspace.upper_left, workspace.lower_right);
        let corners = [
            [ul.x_m, ul.y_m],
            [ul.x_m, lr.y_m],
            [lr.x_m, lr.y_m],
            [lr.x_m, ul.y_m],
        ];
        let mut outline = Vec::new();
        for k in 0..4 {
            let (a, b) = (corners[k], corners[(k + 1) % 4]);
            for s in 0..32 {
                let t = f64::from(s) / 32.0;
                let p = [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t];
                outline.push(pipeline.camera().raw_of(plane.table_to_pixel(p[0], p[1])));
            }
        }
        canvas.polygon(&outline, SHEET);
    }
    // Markers, numbered as the Niryo tools do: 1 = reference, then clockwise.
    for m in &report.markers {
        let (colour, number) = match m.corner.as_deref() {
            Some("upper_left") => (REFERENCE, Some(1)),
            Some("upper_right") => (CORNER, Some(2)),
            Some("lower_right") => (CORNER, Some(3)),
            Some("lower_left") => (CORNER, Some(4)),
            _ => (UNUSED, None),
        };
        canvas.circle(m.centre_px, m.radius_px, colour);
        canvas.cross(m.centre_px, colour);
        if let Some(n) = number {
            canvas.number(
                [m.centre_px[0] + m.radius_px, m.centre_px[1] - m.radius_px],
                n,
                colour,
            );
        }
    }
    for (k, o) in report.objects.iter().enumerate() {
        let colour = if o.colour == "unknown" {
            UNKNOWN
        } else {
            KNOWN
        };
        canvas.rect(o.box_px, colour);
        canvas.cross(o.centre_px, colour);
        canvas.number([o.box_px[0], o.box_px[1] - 14.0], k + 1, colour);
    }
}
