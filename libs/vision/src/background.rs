//! The known sheet as the background: its paper's colour and where its plain centre begins.
//!
//! Once the markers fix the table plane, robotd knows where every part of the sheet lies in
//! the image, and so what the sheet itself looks like in this frame:
//!
//! - **The paper's colour.** White paper under a warm lamp is orange to the camera, under a
//!   cold one blue; the classic sheet's grey stripes then have as much "hue" as a pale object.
//!   [`SheetBackground::measure`] takes the brightest half of the little-saturated points of
//!   a grid over the sheet as the paper (objects are saturated, print and shadows darker) and
//!   gives per-channel gains that make it neutral grey (white balance by the sheet): colours
//!   are judged after them.
//! - **Where the plain centre begins.** The sheet designs print a border inside the marker
//!   rectangle (the classic sheet's stripes, the Ned2 sheet's black frame and ruler ticks);
//!   dark things are objects only inside it. Walking in from each side of the marker
//!   rectangle at several places, the border ends where paper starts and goes on for a few
//!   millimetres; the median over the places of each side, the widest side, and a margin give
//!   the inset of the plain area (an object lying on the border interrupts one walk, not the
//!   median).

use crate::detector::{FrameView, SheetView};

/// Gains are kept within this range (a sheet lit by a coloured light, not a coloured sheet).
const GAIN_RANGE: (f32, f32) = (0.7, 1.45);
/// Paper is at most this saturated ((max − min) / max of r, g, b) under a tinted light.
const PAPER_MAX_SATURATION: f32 = 0.3;
/// Paper continues for this long where the plain centre begins, metres.
const PAPER_RUN_M: f64 = 0.005;
/// Walks go in at most this far from the marker rectangle's sides, metres.
const MAX_BORDER_M: f64 = 0.04;
/// Margin added to the measured border, metres.
const BORDER_MARGIN_M: f64 = 0.003;

/// What the sheet looks like in one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SheetBackground {
    /// Per-channel gains (r, g, b) that make the paper neutral.
    pub gains: [f32; 3],
    /// The paper's grey level after the gains, 0..=255.
    pub paper_grey: f32,
    /// How far inside the marker rectangle the plain centre begins, metres.
    pub border_m: f64,
}

impl SheetBackground {
    /// Measures the paper and the border of the sheet in `frame`. `None` when too little of
    /// the sheet's centre is in view to tell.
    pub fn measure(frame: &FrameView<'_>, sheet: &SheetView<'_>) -> Option<SheetBackground> {
        let ws = sheet.workspace;
        let (x0, x1) = (ws.lower_right.x_m, ws.upper_left.x_m);
        let (y0, y1) = (ws.lower_right.y_m, ws.upper_left.y_m);
        let pixel = |x: f64, y: f64| -> Option<[f32; 3]> {
            let raw = sheet.camera.raw_of(sheet.plane.table_to_pixel(x, y));
            let (u, v) = (raw[0].round(), raw[1].round());
            if !(u >= 0.0 && v >= 0.0 && u < frame.width as f64 && v < frame.height as f64) {
                return None;
            }
            let i = (v as usize * frame.width + u as usize) * 3;
            let p = frame.rgb.get(i..i + 3)?;
            Some([f32::from(p[0]), f32::from(p[1]), f32::from(p[2])])
        };

        // The paper: of a grid over the sheet inside its markers, the samples with little
        // colour (paper under any lamp is far less saturated than a coloured object), and of
        // those the brightest half (not the grey print, not shadows).
        let mut samples: Vec<[f32; 3]> = Vec::with_capacity(400);
        let mut in_view = 0;
        for i in 0..20 {
            for j in 0..20 {
                let t = |k: usize| 0.1 + 0.8 * k as f64 / 19.0;
                if let Some(p) = pixel(x0 + (x1 - x0) * t(i), y0 + (y1 - y0) * t(j)) {
                    in_view += 1;
                    let max = p[0].max(p[1]).max(p[2]);
                    let min = p[0].min(p[1]).min(p[2]);
                    if max - min <= PAPER_MAX_SATURATION * max {
                        samples.push(p);
                    }
                }
            }
        }
        if in_view < 100 || samples.len() < 40 {
            return None;
        }
        samples.sort_by(|a, b| (b[0] + b[1] + b[2]).total_cmp(&(a[0] + a[1] + a[2])));
        let bright = &samples[..samples.len() / 2];
        let mut paper = [0f32; 3];
        for p in bright {
            for c in 0..3 {
                paper[c] += p[c] / bright.len() as f32;
            }
        }
        let grey = (paper[0] + paper[1] + paper[2]) / 3.0;
        if grey < 20.0 {
            return None;
        }
        let gains = paper.map(|c| (grey / c.max(1.0)).clamp(GAIN_RANGE.0, GAIN_RANGE.1));
        let balanced = |p: [f32; 3]| [p[0] * gains[0], p[1] * gains[1], p[2] * gains[2]];
        let is_paper = |p: [f32; 3]| {
            let q = balanced(p);
            let max = q[0].max(q[1]).max(q[2]);
            let min = q[0].min(q[1]).min(q[2]);
            let g = (q[0] + q[1] + q[2]) / 3.0;
            g >= 0.75 * grey && max - min <= 0.2 * max.max(1.0)
        };

        // The border: walk in from each side at seven places.
        let step = 0.001;
        let run_steps = (PAPER_RUN_M / step).round() as usize;
        let mut widest: f64 = 0.0;
        // Each side of the marker rectangle (its two ends) and the way in from it.
        type Side = (([f64; 2], [f64; 2]), [f64; 2]);
        let sides: [Side; 4] = [
            (([x1, y0], [x1, y1]), [-1.0, 0.0]),
            (([x0, y0], [x0, y1]), [1.0, 0.0]),
            (([x0, y1], [x1, y1]), [0.0, -1.0]),
            (([x0, y0], [x1, y0]), [0.0, 1.0]),
        ];
        for ((a, b), inward) in sides {
            let mut found: Vec<f64> = Vec::new();
            let mut in_view = 0;
            for k in 0..7 {
                let t = 0.2 + 0.6 * f64::from(k) / 6.0;
                let start = [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t];
                let mut run = 0usize;
                let mut d = 0.0;
                let mut edge = None;
                let mut seen = false;
                while d <= MAX_BORDER_M {
                    let at = [start[0] + inward[0] * d, start[1] + inward[1] * d];
                    match pixel(at[0], at[1]) {
                        Some(p) if is_paper(p) => {
                            seen = true;
                            run += 1;
                            if run > run_steps {
                                edge = Some(d - run_steps as f64 * step);
                                break;
                            }
                        }
                        Some(_) => {
                            seen = true;
                            run = 0;
                        }
                        // Out of the frame (an image cropped at the marker centres): go on in.
                        None => run = 0,
                    }
                    d += step;
                }
                in_view += usize::from(seen);
                if let Some(e) = edge {
                    found.push(e.max(0.0));
                }
            }
            if found.len() >= 3 {
                found.sort_by(f64::total_cmp);
                widest = widest.max(found[found.len() / 2]);
            } else if in_view >= 3 {
                // Along this side the paper never starts: the border is as wide as looked.
                widest = widest.max(MAX_BORDER_M);
            }
        }
        Some(SheetBackground {
            gains,
            paper_grey: grey,
            border_m: widest + BORDER_MARGIN_M,
        })
    }
}
