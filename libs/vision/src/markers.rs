//! Finding the workspace markers in a frame.
//!
//! Each corner of a workspace sheet carries a marker of concentric rings: black, white, black
//! and a black centre — except the sheet's origin (upper-left = far-left corner), whose centre
//! is white. In the image a marker is two or three dark blobs sharing one centre (a ring and a
//! disc, or two rings), which nothing else on a tabletop looks like. The centre of a marker is
//! the mean of its dark pixels (the rings are symmetric about it).
//!
//! [`find_markers`] returns every marker it sees; [`assign_corners`] picks the origin marker
//! and its three partners and orders them upper-left, upper-right, lower-left, lower-right.

use crate::components::{Blob, Components};

/// Class of dark pixels in the class map.
const DARK: u8 = 1;

/// One marker in the image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkerObservation {
    /// Centre, raw (distorted) pixel coordinates.
    pub centre_px: [f64; 2],
    /// Outer radius, pixels (half the mean bounding-box side of the outer ring).
    pub radius_px: f64,
    /// Whether its centre is white (the sheet's origin marker).
    pub white_centre: bool,
}

/// Reusable buffers of the marker search.
#[derive(Debug, Default)]
pub struct MarkerFinder {
    classes: Vec<u8>,
    components: Components,
}

impl MarkerFinder {
    /// A finder with no buffers yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Every marker in an RGB8 image of `width` × `height` pixels.
    pub fn find_markers(
        &mut self,
        rgb: &[u8],
        width: usize,
        height: usize,
    ) -> Vec<MarkerObservation> {
        let n = width * height;
        if rgb.len() < n * 3 || n == 0 {
            return Vec::new();
        }
        self.classes.clear();
        self.classes.extend(rgb[..n * 3].chunks_exact(3).map(|p| {
            let max = p[0].max(p[1]).max(p[2]);
            let min = p[0].min(p[1]).min(p[2]);
            // Dark and without hue: printed black (anti-aliased edges count from mid-grey).
            u8::from(max < 110 && max - min < 45) * DARK
        }));
        self.components.label(&self.classes, width, height, 4);
        let blobs: Vec<Blob> = self
            .components
            .blobs()
            .iter()
            .filter(|b| {
                let (w, h) = (b.box_width(), b.box_height());
                (2..=200).contains(&w) && (2..=200).contains(&h) && w <= 3 * h && h <= 3 * w
            })
            .copied()
            .collect();

        // Group blobs sharing a centre; the largest of a group is its outer ring.
        let mut used = vec![false; blobs.len()];
        let mut order: Vec<usize> = (0..blobs.len()).collect();
        order.sort_by_key(|&i| std::cmp::Reverse(blobs[i].box_width() * blobs[i].box_height()));
        let mut markers = Vec::new();
        for &outer in &order {
            if used[outer] {
                continue;
            }
            let o = &blobs[outer];
            let size = 0.5 * f64::from(o.box_width() + o.box_height());
            let tolerance = (0.12 * size).max(1.5);
            let inner: Vec<usize> = order
                .iter()
                .copied()
                .filter(|&i| {
                    i != outer
                        && !used[i]
                        && (blobs[i].u_mean - o.u_mean).abs() <= tolerance
                        && (blobs[i].v_mean - o.v_mean).abs() <= tolerance
                        && blobs[i].box_width() < o.box_width()
                        && blobs[i].box_height() < o.box_height()
                })
                .collect();
            if inner.is_empty() || size < 6.0 {
                continue;
            }
            used[outer] = true;
            let mut area = f64::from(o.area);
            let mut su = o.u_mean * area;
            let mut sv = o.v_mean * area;
            for &i in &inner {
                used[i] = true;
                let a = f64::from(blobs[i].area);
                su += blobs[i].u_mean * a;
                sv += blobs[i].v_mean * a;
                area += a;
            }
            let centre = [su / area, sv / area];
            markers.push(MarkerObservation {
                centre_px: centre,
                radius_px: size / 2.0,
                white_centre: self.is_bright(rgb, width, height, centre),
            });
        }
        markers
    }

    /// Whether the 3×3 pixels around `at` are bright on average.
    fn is_bright(&self, rgb: &[u8], width: usize, height: usize, at: [f64; 2]) -> bool {
        let (cu, cv) = (at[0].round() as i64, at[1].round() as i64);
        let mut sum = 0u32;
        let mut count = 0u32;
        for dv in -1..=1 {
            for du in -1..=1 {
                let (u, v) = (cu + du, cv + dv);
                if u < 0 || v < 0 || u >= width as i64 || v >= height as i64 {
                    continue;
                }
                let i = (v as usize * width + u as usize) * 3;
                sum += u32::from(rgb[i].max(rgb[i + 1]).max(rgb[i + 2]));
                count += 1;
            }
        }
        count > 0 && sum / count > 150
    }
}

/// Orders four markers of one sheet as upper-left (the white-centre one), upper-right,
/// lower-left, lower-right. The diagonal partner of the origin is the farthest in the image;
/// which of the other two is upper-right is decided by the caller (mirror order gives no
/// valid camera pose), so both orders are returned, the more likely first.
///
/// `None` unless there is exactly one white-centre marker with at least three others.
pub fn assign_corners(markers: &[MarkerObservation]) -> Option<[[MarkerObservation; 4]; 2]> {
    let mut whites = markers.iter().filter(|m| m.white_centre);
    let origin = *whites.next()?;
    if whites.next().is_some() {
        return None;
    }
    let dist = |m: &MarkerObservation| {
        (m.centre_px[0] - origin.centre_px[0]).hypot(m.centre_px[1] - origin.centre_px[1])
    };
    let mut others: Vec<MarkerObservation> = markers
        .iter()
        .filter(|m| !m.white_centre)
        .copied()
        .collect();
    if others.len() < 3 {
        return None;
    }
    // The sheet's other three corners are the three black markers nearest the origin.
    others.sort_by(|a, b| dist(a).total_cmp(&dist(b)));
    others.truncate(3);
    let diagonal = others[2];
    let (a, b) = (others[0], others[1]);
    Some([[origin, a, b, diagonal], [origin, b, a, diagonal]])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn draw_marker(img: &mut [u8], width: usize, c: [f64; 2], r: f64, white_centre: bool) {
        let height = img.len() / 3 / width;
        for v in 0..height {
            for u in 0..width {
                let d = (u as f64 - c[0]).hypot(v as f64 - c[1]) / r;
                let dark = if d > 1.0 {
                    continue;
                } else if d > 0.7 {
                    true
                } else if d > 0.45 {
                    false
                } else if d > 0.2 {
                    true
                } else {
                    !white_centre
                };
                let value = if dark { 20 } else { 245 };
                img[(v * width + u) * 3..][..3].fill(value);
            }
        }
    }

    #[test]
    fn finds_four_markers_and_orders_them() {
        let (w, h) = (200, 150);
        let mut img = vec![245u8; w * h * 3];
        draw_marker(&mut img, w, [30.0, 30.0], 12.0, true);
        draw_marker(&mut img, w, [170.0, 32.0], 12.0, false);
        draw_marker(&mut img, w, [28.0, 120.0], 12.0, false);
        draw_marker(&mut img, w, [168.0, 118.0], 12.0, false);
        // A dark bar (a pen) is not a marker.
        for v in 70..76 {
            for u in 60..140 {
                img[(v * w + u) * 3..][..3].fill(25);
            }
        }
        let mut finder = MarkerFinder::new();
        let markers = finder.find_markers(&img, w, h);
        assert_eq!(markers.len(), 4, "{markers:?}");
        let [first, _] = assign_corners(&markers).unwrap();
        assert!(first[0].white_centre);
        assert!((first[0].centre_px[0] - 30.0).abs() < 0.2);
        assert!((first[3].centre_px[0] - 168.0).abs() < 0.2, "diagonal last");
        assert!((first[3].centre_px[1] - 118.0).abs() < 0.2);

        // Without its origin marker a sheet is not usable.
        let no_origin: Vec<_> = markers
            .iter()
            .filter(|m| !m.white_centre)
            .copied()
            .collect();
        assert!(assign_corners(&no_origin).is_none());
        assert!(finder.find_markers(&[245; 30], 5, 2).is_empty());
    }
}
