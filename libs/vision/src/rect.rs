//! Minimum-area rectangles of point sets: the size and orientation of an object's footprint.
//!
//! The convex hull (Andrew's monotone chain) is tried against each of its edge directions —
//! the smallest enclosing rectangle always has a side along a hull edge.
//!
//! ```
//! use robotd_vision::rect::min_area_rect;
//!
//! let square_rotated = [[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]];
//! let r = min_area_rect(&square_rotated).unwrap();
//! assert!((r.long - 2f64.sqrt()).abs() < 1e-12 && (r.short - 2f64.sqrt()).abs() < 1e-12);
//! assert!((r.area() - 2.0).abs() < 1e-12);
//! ```

/// A rotated rectangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotatedRect {
    /// Centre.
    pub centre: [f64; 2],
    /// Length of the longer side.
    pub long: f64,
    /// Length of the shorter side.
    pub short: f64,
    /// Direction of the longer side, radians from the +x axis, in (−π/2, π/2].
    pub angle: f64,
}

impl RotatedRect {
    /// Area.
    pub fn area(&self) -> f64 {
        self.long * self.short
    }

    /// Extent along y and along x as width and height: the side closer to the y axis is the
    /// width (the object-JSON convention: width along y, height along x).
    pub fn width_height(&self) -> (f64, f64) {
        if self.angle.sin().abs() >= self.angle.cos().abs() {
            (self.long, self.short)
        } else {
            (self.short, self.long)
        }
    }
}

/// Convex hull, counter-clockwise, without collinear points.
pub fn convex_hull(points: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let mut pts: Vec<[f64; 2]> = points
        .iter()
        .copied()
        .filter(|p| p[0].is_finite() && p[1].is_finite())
        .collect();
    pts.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    pts.dedup();
    if pts.len() < 3 {
        return pts;
    }
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(2 * pts.len());
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &[f64; 2]>> = if pass == 0 {
            Box::new(pts.iter())
        } else {
            Box::new(pts.iter().rev())
        };
        for &p in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

/// The smallest rectangle enclosing `points`; `None` for fewer than two distinct points.
pub fn min_area_rect(points: &[[f64; 2]]) -> Option<RotatedRect> {
    let hull = convex_hull(points);
    if hull.len() < 2 {
        return None;
    }
    let mut best: Option<(f64, RotatedRect)> = None;
    for i in 0..hull.len() {
        let a = hull[i];
        let b = hull[(i + 1) % hull.len()];
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len = dx.hypot(dy);
        if len <= 0.0 {
            continue;
        }
        let (ux, uy) = (dx / len, dy / len);
        let (mut s_min, mut s_max, mut t_min, mut t_max) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for p in &hull {
            let s = p[0] * ux + p[1] * uy;
            let t = -p[0] * uy + p[1] * ux;
            s_min = s_min.min(s);
            s_max = s_max.max(s);
            t_min = t_min.min(t);
            t_max = t_max.max(t);
        }
        let (ls, lt) = (s_max - s_min, t_max - t_min);
        let area = ls * lt;
        if best.as_ref().is_some_and(|(a, _)| *a <= area) {
            continue;
        }
        let (sc, tc) = ((s_min + s_max) / 2.0, (t_min + t_max) / 2.0);
        let centre = [sc * ux - tc * uy, sc * uy + tc * ux];
        let (long, short, angle) = if ls >= lt {
            (ls, lt, uy.atan2(ux))
        } else {
            (lt, ls, ux.atan2(-uy))
        };
        best = Some((
            area,
            RotatedRect {
                centre,
                long,
                short,
                angle: normalise_half_turn(angle),
            },
        ));
    }
    best.map(|(_, r)| r)
}

/// An angle of an undirected line, in (−π/2, π/2].
pub fn normalise_half_turn(angle: f64) -> f64 {
    use std::f64::consts::PI;
    let mut a = angle.rem_euclid(PI);
    if a > PI / 2.0 {
        a -= PI;
    }
    a
}

/// An angle of a shape with 90° symmetry (a square), in (−π/4, π/4].
pub fn normalise_quarter_turn(angle: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, FRAC_PI_4};
    let mut a = angle.rem_euclid(FRAC_PI_2);
    if a > FRAC_PI_4 {
        a -= FRAC_PI_2;
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotated_bar_measures_its_sides_and_direction() {
        let angle: f64 = 0.4;
        let (c, s) = (angle.cos(), angle.sin());
        let mut pts = Vec::new();
        for i in 0..=60 {
            for j in 0..=10 {
                let (a, b) = (
                    f64::from(i) / 60.0 * 0.12 - 0.06,
                    f64::from(j) / 10.0 * 0.012 - 0.006,
                );
                pts.push([0.2 + a * c - b * s, -0.05 + a * s + b * c]);
            }
        }
        let r = min_area_rect(&pts).unwrap();
        assert!(
            (r.long - 0.12).abs() < 1e-9 && (r.short - 0.012).abs() < 1e-9,
            "{r:?}"
        );
        assert!((r.angle - 0.4).abs() < 1e-9);
        assert!((r.centre[0] - 0.2).abs() < 1e-9 && (r.centre[1] + 0.05).abs() < 1e-9);
        assert_eq!(r.width_height(), (r.short, r.long));
    }

    #[test]
    fn angles_normalise_by_symmetry() {
        use std::f64::consts::PI;
        assert!((normalise_half_turn(PI - 0.1) + 0.1).abs() < 1e-12);
        assert!((normalise_half_turn(PI / 2.0) - PI / 2.0).abs() < 1e-12);
        assert!((normalise_quarter_turn(PI / 2.0 + 0.1) - 0.1).abs() < 1e-12);
        assert!((normalise_quarter_turn(-PI / 4.0 - 0.1) - (PI / 4.0 - 0.1)).abs() < 1e-12);
        assert!(min_area_rect(&[[1.0, 1.0]]).is_none());
        assert_eq!(convex_hull(&[[0.0, 0.0], [1.0, 0.0], [0.5, 0.0]]).len(), 2);
    }
}
