//! Where a blurred marker may be: dark discs with a light rim, at every scale.
//!
//! The blob stage of [`crate::markers`] starts from pixels well below their neighbourhood's
//! mean. A marker blurred until its rings are grey has none: its rings are no longer dark
//! enough, only the marker as a whole is darker than the light disc around it. [`DiscScan`]
//! looks for exactly that, the way box-filter blob detectors do: at each scale (radii a
//! quarter apart), on a grid a quarter of the radius fine, the mean grey level of the square
//! inscribed in a would-be marker against eight small squares on a circle just outside it (a
//! printed marker sits on a light disc a third wider than itself; the simulator's on plain
//! paper), all from the frame's summed-area table; in each direction the lightest of four
//! places from just inside the edge to 1.4 radii out counts (a tilted marker is an ellipse).
//! Where seven of the eight are clearly lighter than the middle (a line or an edge through the
//! place darkens two), the best scale and position are a candidate for [`crate::ring_fit`],
//! which decides.

use crate::shade::LocalMean;

/// A place that may be a blurred marker.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiscCandidate {
    /// Its centre, pixels of the frame.
    pub centre: [f64; 2],
    /// Its radius (the marker's outer radius), pixels of the frame.
    pub radius_px: f64,
    /// How much darker its middle is than its rim: 1 − middle / rim.
    pub contrast: f64,
}

/// The middle of a candidate is at most this share of the lightest of its rim's grey levels.
const MAX_MIDDLE_SHARE: f64 = 0.85;
/// The rim squares lie this far out, as fractions of the radius (a printed marker's light
/// disc ends at 1.3; a tilted marker's rim is nearer on its short axis).
const RIM: [f64; 4] = [0.95, 1.1, 1.25, 1.4];
/// Of the eight directions, at least this many must show a light rim (an object or a line
/// may darken one).
const MIN_LIGHT_DIRECTIONS: usize = 7;
/// Scales grow by this factor.
const SCALE_STEP: f64 = 1.25;

/// Reusable buffers of the scan.
#[derive(Debug, Default)]
pub struct DiscScan {
    found: Vec<DiscCandidate>,
    raw: Vec<DiscCandidate>,
    response: Vec<f64>,
}

impl DiscScan {
    /// A scan with no buffers yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Candidates of radius `min_radius_px` to `max_radius_px` in the frame of `shade`, the
    /// most contrasted first, at most `limit`, none within another's radius at a scale less
    /// than two steps from its own.
    pub fn scan(
        &mut self,
        shade: &LocalMean,
        min_radius_px: f64,
        max_radius_px: f64,
        limit: usize,
    ) -> &[DiscCandidate] {
        self.found.clear();
        self.raw.clear();
        let (w, h) = shade.size();
        let (w, h) = (w as isize, h as isize);
        // Every square of the scan lies inside the frame (`reach` keeps it off the edges).
        let mean =
            |u: isize, v: isize, half: usize| shade.interior_mean(u as usize, v as usize, half);
        let mut radius = min_radius_px.max(2.0);
        while radius <= max_radius_px {
            let middle = (0.6 * radius).round().max(1.0) as usize;
            let rim_half = (0.08 * radius).floor() as usize;
            // Per direction, three places out from the edge: the lightest counts (the light
            // disc around a tilted marker is nearer on its short axis).
            let offsets: Vec<[[isize; 2]; 4]> = (0..8)
                .map(|k| {
                    let a = f64::from(k) * std::f64::consts::FRAC_PI_4;
                    RIM.map(|r| {
                        [
                            (a.cos() * r * radius).round() as isize,
                            (a.sin() * r * radius).round() as isize,
                        ]
                    })
                })
                .collect();
            let reach = (RIM[3] * radius).ceil() as isize + rim_half as isize + 1;
            let stride = (0.25 * radius).round().max(1.0) as usize;
            let cols = ((w - 2 * reach).max(0) as usize).div_ceil(stride);
            let rows = ((h - 2 * reach).max(0) as usize).div_ceil(stride);
            self.response.clear();
            self.response.resize(cols * rows, 0.0);
            for row in 0..rows {
                let v = reach + (row * stride) as isize;
                for col in 0..cols {
                    let u = reach + (col * stride) as isize;
                    let inner = mean(u, v, middle);
                    let needed = inner / MAX_MIDDLE_SHARE;
                    let mut dark_directions = 0;
                    let mut darkest_rim = f64::MAX;
                    for places in &offsets {
                        let m = places
                            .iter()
                            .map(|o| mean(u + o[0], v + o[1], rim_half))
                            .fold(0f64, f64::max);
                        if m < needed {
                            dark_directions += 1;
                            if dark_directions > 8 - MIN_LIGHT_DIRECTIONS {
                                break;
                            }
                        } else {
                            darkest_rim = darkest_rim.min(m);
                        }
                    }
                    if dark_directions <= 8 - MIN_LIGHT_DIRECTIONS {
                        self.response[row * cols + col] = 1.0 - inner / darkest_rim.max(1.0);
                    }
                }
            }
            let response = &self.response;
            for row in 0..rows {
                for col in 0..cols {
                    let c = response[row * cols + col];
                    if c <= 0.0 {
                        continue;
                    }
                    let peak = (row.saturating_sub(1)..(row + 2).min(rows)).all(|r| {
                        (col.saturating_sub(1)..(col + 2).min(cols))
                            .all(|k| response[r * cols + k] <= c)
                    });
                    if peak {
                        self.raw.push(DiscCandidate {
                            centre: [
                                (reach + (col * stride) as isize) as f64,
                                (reach + (row * stride) as isize) as f64,
                            ],
                            radius_px: radius,
                            contrast: c,
                        });
                    }
                }
            }
            radius *= SCALE_STEP;
        }
        self.raw.sort_by(|a, b| b.contrast.total_cmp(&a.contrast));
        for c in &self.raw {
            if self.found.len() >= limit {
                break;
            }
            // Scales far apart at one place are both kept: the middle of a marker can stand
            // out at a smaller scale than the marker's own.
            let near = self.found.iter().any(|k| {
                let (small, large) = (k.radius_px.min(c.radius_px), k.radius_px.max(c.radius_px));
                (k.centre[0] - c.centre[0]).hypot(k.centre[1] - c.centre[1]) < large
                    && large < SCALE_STEP * SCALE_STEP * small * 1.01
            });
            if !near {
                self.found.push(*c);
            }
        }
        &self.found
    }
}
