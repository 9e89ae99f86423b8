//! Drawing on an RGB8 image: lines, boxes, rings and digits (what `robotd detect --out` draws).
//!
//! Everything is clipped to the image, so a marker or box partly outside it draws what is
//! inside. Digits use a 3×5 pixel font scaled up with the image, enough to number markers and
//! objects without a font file.

/// An RGB8 image being drawn on.
pub struct Canvas<'a> {
    rgb: &'a mut [u8],
    width: usize,
    height: usize,
}

/// 3×5 glyphs of the digits 0–9, one row per 3 bits (top row first, high bit left).
const DIGITS: [[u8; 5]; 10] = [
    [7, 5, 5, 5, 7],
    [2, 6, 2, 2, 7],
    [7, 1, 7, 4, 7],
    [7, 1, 7, 1, 7],
    [5, 5, 7, 1, 1],
    [7, 4, 7, 1, 7],
    [7, 4, 7, 5, 7],
    [7, 1, 1, 1, 1],
    [7, 5, 7, 5, 7],
    [7, 5, 7, 1, 7],
];

impl<'a> Canvas<'a> {
    /// A canvas over `rgb` (`width × height × 3` bytes).
    pub fn new(rgb: &'a mut [u8], width: usize, height: usize) -> Self {
        Self { rgb, width, height }
    }

    /// Line width and digit scale that stay visible at this image size.
    pub fn stroke(&self) -> i64 {
        (self.width.max(self.height) as i64 / 400).max(1)
    }

    fn dot(&mut self, u: i64, v: i64, colour: [u8; 3]) {
        if u >= 0 && v >= 0 && (u as usize) < self.width && (v as usize) < self.height {
            let i = (v as usize * self.width + u as usize) * 3;
            self.rgb[i..i + 3].copy_from_slice(&colour);
        }
    }

    fn blot(&mut self, u: f64, v: f64, colour: [u8; 3]) {
        let s = self.stroke();
        let (u, v) = (u.round() as i64, v.round() as i64);
        for dv in 0..s {
            for du in 0..s {
                self.dot(u + du - s / 2, v + dv - s / 2, colour);
            }
        }
    }

    /// A straight line from `a` to `b` (pixel coordinates).
    pub fn line(&mut self, a: [f64; 2], b: [f64; 2], colour: [u8; 3]) {
        if !(a.iter().chain(&b).all(|c| c.is_finite() && c.abs() < 1e6)) {
            return;
        }
        let steps = (b[0] - a[0]).abs().max((b[1] - a[1]).abs()).ceil().max(1.0) as usize;
        for k in 0..=steps {
            let t = k as f64 / steps as f64;
            self.blot(a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t, colour);
        }
    }

    /// The outline of a closed polygon.
    pub fn polygon(&mut self, points: &[[f64; 2]], colour: [u8; 3]) {
        for k in 0..points.len() {
            self.line(points[k], points[(k + 1) % points.len()], colour);
        }
    }

    /// An axis-aligned box `[u_min, v_min, u_max, v_max]`.
    pub fn rect(&mut self, b: [f64; 4], colour: [u8; 3]) {
        let corners = [[b[0], b[1]], [b[2], b[1]], [b[2], b[3]], [b[0], b[3]]];
        self.polygon(&corners, colour);
    }

    /// A circle of radius `r` around `c`.
    pub fn circle(&mut self, c: [f64; 2], r: f64, colour: [u8; 3]) {
        let steps = (r * 8.0).clamp(16.0, 2000.0) as usize;
        let points: Vec<[f64; 2]> = (0..steps)
            .map(|k| {
                let a = k as f64 / steps as f64 * std::f64::consts::TAU;
                [c[0] + r * a.cos(), c[1] + r * a.sin()]
            })
            .collect();
        self.polygon(&points, colour);
    }

    /// A small cross at `c`.
    pub fn cross(&mut self, c: [f64; 2], colour: [u8; 3]) {
        let r = 3.0 * self.stroke() as f64;
        self.line([c[0] - r, c[1]], [c[0] + r, c[1]], colour);
        self.line([c[0], c[1] - r], [c[0], c[1] + r], colour);
    }

    /// The number `n` with its top-left corner at `at`, on a white background.
    pub fn number(&mut self, at: [f64; 2], n: usize, colour: [u8; 3]) {
        let scale = self.stroke() * 2;
        let text = n.to_string();
        let (u0, v0) = (at[0].round() as i64, at[1].round() as i64);
        let width = text.len() as i64 * 4 * scale + scale;
        for v in -scale..6 * scale {
            for u in -scale..width {
                self.dot(u0 + u, v0 + v, [255, 255, 255]);
            }
        }
        for (k, ch) in text.bytes().enumerate() {
            let glyph = DIGITS[usize::from(ch - b'0')];
            for (row, bits) in glyph.iter().enumerate() {
                for col in 0..3 {
                    if bits & (4 >> col) != 0 {
                        for dv in 0..scale {
                            for du in 0..scale {
                                let u = u0 + (k as i64 * 4 + col) * scale + du;
                                let v = v0 + row as i64 * scale + dv;
                                self.dot(u, v, colour);
                            }
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drawing_is_clipped_to_the_image() {
        let mut rgb = vec![0u8; 10 * 10 * 3];
        let mut canvas = Canvas::new(&mut rgb, 10, 10);
        canvas.rect([-5.0, -5.0, 4.0, 4.0], [255, 0, 0]);
        canvas.circle([50.0, 50.0], 100.0, [0, 255, 0]);
        canvas.number([8.0, 8.0], 1234, [0, 0, 255]);
        canvas.line([f64::NAN, 0.0], [3.0, 3.0], [9, 9, 9]);
        assert_eq!(&rgb[(4 * 10 + 2) * 3..][..3], &[255, 0, 0]);
    }
}
