//! Local brightness: the mean grey level of the square around a pixel, in constant time.
//!
//! Real light is uneven — the arm's shadow, a lamp's glare, a lens that darkens the corners —
//! so "dark" and "bright" must be judged against the neighbourhood, not a fixed level. A
//! summed-area table (integral image) holds at each position the sum of all grey levels above
//! and to the left; any square's sum is then four look-ups, whatever its size.
//!
//! ```
//! use robotd_vision::shade::LocalMean;
//!
//! // A 5×5 white patch with one dark pixel in the middle.
//! let mut rgb = vec![200u8; 5 * 5 * 3];
//! rgb[(2 * 5 + 2) * 3..][..3].fill(20);
//! let mut shade = LocalMean::default();
//! shade.compute(&rgb, 5, 5);
//! assert_eq!(shade.grey(2, 2), 20);
//! assert!((shade.mean(2, 2, 2) - (24.0 * 200.0 + 20.0) / 25.0).abs() < 1e-9);
//! assert!(shade.darker_than(2, 2, 2, 62) && !shade.darker_than(0, 0, 2, 62));
//! // Between pixel centres the grey level is interpolated.
//! assert_eq!(shade.grey_at(1.5, 2.0), Some(110.0));
//! ```

/// Grey levels of a frame and their summed-area table.
#[derive(Debug, Default, Clone)]
pub struct LocalMean {
    grey: Vec<u8>,
    integral: Vec<u32>,
    width: usize,
    height: usize,
}

impl LocalMean {
    /// Computes the grey levels (Rec. 601 luma) and their summed-area table of an RGB8 frame.
    pub fn compute(&mut self, rgb: &[u8], width: usize, height: usize) {
        let n = width * height;
        self.width = width;
        self.height = height;
        self.grey.clear();
        self.grey.extend(rgb[..n * 3].chunks_exact(3).map(|p| {
            ((u32::from(p[0]) * 77 + u32::from(p[1]) * 150 + u32::from(p[2]) * 29) >> 8) as u8
        }));
        // One zero row and column in front: (width + 1) × (height + 1). The sums wrap around
        // 2³²; a square's sum, taken with wrapping arithmetic too, is still exact as long as
        // it is below 2³² (squares of fewer than 16.8 million pixels).
        let stride = width + 1;
        self.integral.clear();
        self.integral.resize(stride * (height + 1), 0);
        for v in 0..height {
            let (above, row) = self.integral[v * stride..(v + 2) * stride].split_at_mut(stride);
            let grey = &self.grey[v * width..(v + 1) * width];
            let mut row_sum = 0u32;
            for u in 0..width {
                row_sum = row_sum.wrapping_add(u32::from(grey[u]));
                row[u + 1] = above[u + 1].wrapping_add(row_sum);
            }
        }
    }

    /// The grey level of pixel `(u, v)`.
    pub fn grey(&self, u: usize, v: usize) -> u8 {
        self.grey[v * self.width + u]
    }

    /// The grey level at `(u, v)` between pixel centres (bilinear; pixel `(i, j)`'s centre is
    /// at `(i, j)`), `None` outside the frame.
    pub fn grey_at(&self, u: f64, v: f64) -> Option<f64> {
        if !(u >= 0.0 && v >= 0.0) {
            return None;
        }
        // Both are not negative here: truncation is the floor.
        let (i, j) = (u as usize, v as usize);
        if i + 1 >= self.width || j + 1 >= self.height {
            return None;
        }
        let (fu, fv) = (u - i as f64, v - j as f64);
        let at = |i: usize, j: usize| f64::from(self.grey[j * self.width + i]);
        let top = at(i, j) + fu * (at(i + 1, j) - at(i, j));
        let bottom = at(i, j + 1) + fu * (at(i + 1, j + 1) - at(i, j + 1));
        Some(top + fv * (bottom - top))
    }

    /// The frame's size, pixels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The sum of grey levels and the pixel count of the square of half-side `half` around
    /// `(u, v)`, clipped to the frame.
    pub fn sum(&self, u: usize, v: usize, half: usize) -> (u64, u64) {
        let (u0, u1) = (u.saturating_sub(half), (u + half + 1).min(self.width));
        let (v0, v1) = (v.saturating_sub(half), (v + half + 1).min(self.height));
        let stride = self.width + 1;
        let sum = self.integral[v1 * stride + u1]
            .wrapping_add(self.integral[v0 * stride + u0])
            .wrapping_sub(self.integral[v0 * stride + u1])
            .wrapping_sub(self.integral[v1 * stride + u0]);
        (u64::from(sum), ((v1 - v0) * (u1 - u0)) as u64)
    }

    /// The mean grey level of the square of half-side `half` around `(u, v)`, which must lie
    /// wholly inside the frame (not clipped: for scans that keep off the edges).
    #[inline]
    pub fn interior_mean(&self, u: usize, v: usize, half: usize) -> f64 {
        if half == 0 {
            return f64::from(self.grey[v * self.width + u]);
        }
        let stride = self.width + 1;
        let (u0, u1, v0, v1) = (u - half, u + half + 1, v - half, v + half + 1);
        let sum = self.integral[v1 * stride + u1]
            .wrapping_add(self.integral[v0 * stride + u0])
            .wrapping_sub(self.integral[v0 * stride + u1])
            .wrapping_sub(self.integral[v1 * stride + u0]);
        let side = 2 * half + 1;
        f64::from(sum) / (side * side) as f64
    }

    /// The mean grey level of the square of half-side `half` around `(u, v)`.
    pub fn mean(&self, u: usize, v: usize, half: usize) -> f64 {
        let (sum, count) = self.sum(u, v, half);
        sum as f64 / count.max(1) as f64
    }

    /// Whether pixel `(u, v)` is darker than `percent` % of its neighbourhood's mean.
    pub fn darker_than(&self, u: usize, v: usize, half: usize, percent: u32) -> bool {
        // No mean is above 255: a pixel at or above `percent` % of 255 is never darker.
        if u32::from(self.grey(u, v)) * 100 >= 255 * percent {
            return false;
        }
        let (sum, count) = self.sum(u, v, half);
        u64::from(self.grey(u, v)) * 100 * count < sum * u64::from(percent)
    }
}
