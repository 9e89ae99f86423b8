//! Boxes and labels drawn onto a frame: the Redis edge's `annotated_camera` stream and the
//! dashboard's camera view.
//!
//! Each object gets its bounding box (2 px, one colour per label) and a filled tag above it
//! with `label 0.87` (`obj-3 label 0.87` when it carries a tracked id) in an 8×8 bitmap font
//! (ASCII; other characters show as `?`). Drawing is clipped to the frame, so any box, even
//! one partly outside, is safe.

use robotd_protocol::objects::DetectedObject;

const PALETTE: [[u8; 3]; 6] = [
    [0, 200, 0],
    [230, 30, 30],
    [30, 90, 230],
    [230, 160, 0],
    [170, 0, 200],
    [0, 180, 200],
];

/// Draws `objects` (their relative bounding boxes) onto `rgb`, `width × height` RGB8.
pub fn draw_objects(rgb: &mut [u8], width: usize, height: usize, objects: &[DetectedObject]) {
    if rgb.len() < width * height * 3 {
        return;
    }
    for object in objects {
        let b = &object.image_coordinates.bounding_box_rel;
        let to_px = |rel: f64, size: usize| (rel * size as f64).round().clamp(0.0, size as f64);
        let (x0, x1) = (to_px(b.u_min, width), to_px(b.u_max, width));
        let (y0, y1) = (to_px(b.v_min, height), to_px(b.v_max, height));
        if !(x0 < x1 && y0 < y1) {
            continue;
        }
        let colour = PALETTE[label_hash(&object.label) % PALETTE.len()];
        let (x0, y0, x1, y1) = (x0 as i64, y0 as i64, x1 as i64 - 1, y1 as i64 - 1);
        let mut canvas = Canvas {
            rgb: &mut *rgb,
            width,
            height,
        };
        for t in 0..2 {
            canvas.hline(x0, x1, y0 + t, colour);
            canvas.hline(x0, x1, y1 - t, colour);
            canvas.vline(x0 + t, y0, y1, colour);
            canvas.vline(x1 - t, y0, y1, colour);
        }
        let text = if object.id.is_empty() {
            format!("{} {:.2}", object.label, object.confidence)
        } else {
            format!("{} {} {:.2}", object.id, object.label, object.confidence)
        };
        let tag_w = text.chars().count() as i64 * 8 + 4;
        let tag_y = if y0 >= 12 { y0 - 12 } else { y1 + 2 };
        canvas.fill(x0, tag_y, x0 + tag_w, tag_y + 11, colour);
        canvas.text(x0 + 2, tag_y + 2, &text, [255, 255, 255]);
    }
}

fn label_hash(label: &str) -> usize {
    label
        .bytes()
        .fold(7usize, |h, b| h.wrapping_mul(31).wrapping_add(b as usize))
}

struct Canvas<'a> {
    rgb: &'a mut [u8],
    width: usize,
    height: usize,
}

impl Canvas<'_> {
    fn put(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
            return;
        }
        let i = (y as usize * self.width + x as usize) * 3;
        self.rgb[i..i + 3].copy_from_slice(&c);
    }

    fn hline(&mut self, x0: i64, x1: i64, y: i64, c: [u8; 3]) {
        for x in x0..=x1 {
            self.put(x, y, c);
        }
    }

    fn vline(&mut self, x: i64, y0: i64, y1: i64, c: [u8; 3]) {
        for y in y0..=y1 {
            self.put(x, y, c);
        }
    }

    fn fill(&mut self, x0: i64, y0: i64, x1: i64, y1: i64, c: [u8; 3]) {
        for y in y0..y1 {
            self.hline(x0, x1 - 1, y, c);
        }
    }

    fn text(&mut self, x: i64, y: i64, text: &str, c: [u8; 3]) {
        for (k, ch) in text.chars().enumerate() {
            let code = if ch.is_ascii() {
                ch as usize
            } else {
                '?' as usize
            };
            let glyph = font8x8::legacy::BASIC_LEGACY[code];
            for (row, bits) in glyph.iter().enumerate() {
                for col in 0..8 {
                    if bits & (1 << col) != 0 {
                        self.put(x + k as i64 * 8 + col, y + row as i64, c);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_protocol::objects::RelBox;

    #[test]
    fn boxes_are_drawn_and_clipped() {
        let (w, h) = (64, 48);
        let mut rgb = vec![255u8; w * h * 3];
        let mut object = DetectedObject {
            label: "cube".into(),
            confidence: 0.5,
            ..Default::default()
        };
        object.image_coordinates.bounding_box_rel = RelBox {
            u_min: 0.5,
            v_min: 0.5,
            u_max: 1.5,
            v_max: 2.0,
        };
        draw_objects(&mut rgb, w, h, &[object]);
        // The box's top-left corner is coloured, the frame's top-left is not.
        let at = |x: usize, y: usize| &rgb[(y * w + x) * 3..(y * w + x) * 3 + 3];
        assert_ne!(at(32, 24), [255, 255, 255]);
        assert_eq!(at(0, 0), [255, 255, 255]);
        assert_eq!(at(40, 40), [255, 255, 255]);
    }
}
