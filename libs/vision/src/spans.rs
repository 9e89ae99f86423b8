//! Which pixels of a frame see the workspace: per image row, the span of columns inside the
//! sheet's outline.
//!
//! The workspace rectangle (grown or shrunk by a margin) is sampled densely along its edges,
//! each point mapped through the table plane and the lens into the raw image, and each row's
//! span taken between the outline's leftmost and rightmost crossing. The lens bends the
//! rectangle's edges; sixteen samples an edge follow that curve to well under a pixel.

use crate::detector::SheetView;

/// For each image row, the columns `[start, end)` whose pixels see the workspace rectangle grown
/// by `margin_m` (shrunk when negative), written to `spans`.
pub fn sheet_spans(
    sheet: &SheetView<'_>,
    margin_m: f64,
    width: usize,
    height: usize,
    spans: &mut Vec<(u16, u16)>,
) {
    let ws = sheet.workspace;
    let m = margin_m;
    let (x0, x1) = (ws.lower_right.x_m - m, ws.upper_left.x_m + m);
    let (y0, y1) = (ws.lower_right.y_m - m, ws.upper_left.y_m + m);
    // The sheet's outline, sampled densely enough to follow the lens's curvature.
    let corners = [[x1, y1], [x1, y0], [x0, y0], [x0, y1]];
    let mut outline = Vec::with_capacity(64);
    for k in 0..4 {
        let (a, b) = (corners[k], corners[(k + 1) % 4]);
        for s in 0..16 {
            let t = f64::from(s) / 16.0;
            let p = [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t];
            outline.push(sheet.camera.raw_of(sheet.plane.table_to_pixel(p[0], p[1])));
        }
    }
    spans.clear();
    spans.resize(height, (0, 0));
    let mut lo = vec![f64::INFINITY; height];
    let mut hi = vec![f64::NEG_INFINITY; height];
    let n = outline.len();
    for k in 0..n {
        let (a, b) = (outline[k], outline[(k + 1) % n]);
        if !(a.iter().chain(&b).all(|c| c.is_finite())) {
            continue;
        }
        let (v_min, v_max) = (a[1].min(b[1]), a[1].max(b[1]));
        let first = v_min.ceil().max(0.0) as usize;
        let last = (v_max.floor().min(height as f64 - 1.0)).max(-1.0);
        if last < 0.0 {
            continue;
        }
        for v in first..=last as usize {
            let vf = v as f64;
            let u = if (b[1] - a[1]).abs() < 1e-9 {
                a[0]
            } else {
                a[0] + (b[0] - a[0]) * (vf - a[1]) / (b[1] - a[1])
            };
            lo[v] = lo[v].min(u);
            hi[v] = hi[v].max(u);
        }
    }
    for v in 0..height {
        if lo[v] <= hi[v] {
            let start = lo[v].ceil().clamp(0.0, width as f64) as u16;
            let end = (hi[v].floor() + 1.0).clamp(0.0, width as f64) as u16;
            spans[v] = (start, end.max(start));
        }
    }
}
