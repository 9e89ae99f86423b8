//! The largest free rectangle of a workspace: where there is room to put something.
//!
//! As the Python server does it, made exact: the workspace rectangle is rasterised into a
//! 100 × 100 grid; a cell is occupied when its centre lies in an object's axis-aligned
//! footprint (centre ± width/2 along y, ± height/2 along x) grown by a safety margin; the
//! largest all-free axis-aligned rectangle of cells (the classic histogram-and-stack
//! algorithm, O(cells)) gives the area (cells / 10 000 × the workspace's area) and centre.
//! Of equally large rectangles the first found wins (scanning rows from the near edge).
//! Held objects are not passed in: they are not on the table.
//!
//! ```
//! use robotd_protocol::geometry::{Point2, Pose, RobotModel};
//! use robotd_protocol::workspace::WorkspaceInfo;
//! use robotd_workspace_model::free_space::largest_free_space;
//!
//! let ws = WorkspaceInfo {
//!     id: "niryo_ws".into(),
//!     robot: RobotModel::Ned2,
//!     upper_left: Point2::new(0.337, 0.087),
//!     lower_right: Point2::new(0.163, -0.087),
//!     observation_pose: Pose::new(0.173, -0.002, 0.277, -3.042, 1.327, -3.027),
//! };
//! let (area_m2, center) = largest_free_space(&ws, &[], 0.01);
//! assert!((area_m2 - 0.174 * 0.174).abs() < 1e-12); // an empty sheet is all free
//! assert!((center.x_m - 0.25).abs() < 1e-12);
//! ```

use robotd_protocol::geometry::Point2;
use robotd_protocol::objects::DetectedObject;
use robotd_protocol::workspace::WorkspaceInfo;

/// Cells along each side of the grid.
pub const GRID: usize = 100;

/// The largest free rectangle: area in m² and centre.
pub fn largest_free_space(
    workspace: &WorkspaceInfo,
    objects: &[DetectedObject],
    margin_m: f64,
) -> (f64, Point2) {
    let (x0, y0) = (workspace.lower_right.x_m, workspace.lower_right.y_m);
    let (dx, dy) = (
        workspace.height_m() / GRID as f64,
        workspace.width_m() / GRID as f64,
    );
    // occupied[i][j]: row i along x (near → far), column j along y (right → left).
    let mut occupied = vec![[false; GRID]; GRID];
    for o in objects {
        let c = o.xy();
        let (hx, hy) = (
            o.dimensions.height_m / 2.0 + margin_m,
            o.dimensions.width_m / 2.0 + margin_m,
        );
        for (i, row) in occupied.iter_mut().enumerate() {
            let x = x0 + (i as f64 + 0.5) * dx;
            if (x - c.x_m).abs() > hx {
                continue;
            }
            for (j, cell) in row.iter_mut().enumerate() {
                let y = y0 + (j as f64 + 0.5) * dy;
                if (y - c.y_m).abs() <= hy {
                    *cell = true;
                }
            }
        }
    }
    // Histogram of free cells above each column, rows taken one at a time.
    let mut heights = [0usize; GRID];
    let mut best = (0usize, 0usize, 0usize, 0usize, 0usize); // cells, i_top, height, j_start, width
    for (i, row) in occupied.iter().enumerate() {
        for j in 0..GRID {
            heights[j] = if row[j] { 0 } else { heights[j] + 1 };
        }
        let mut stack: Vec<usize> = Vec::with_capacity(GRID + 1);
        for j in 0..=GRID {
            let h = if j < GRID { heights[j] } else { 0 };
            while let Some(&top) = stack.last() {
                if heights[top] <= h {
                    break;
                }
                stack.pop();
                let height = heights[top];
                let start = stack.last().map_or(0, |&s| s + 1);
                let width = j - start;
                if height * width > best.0 {
                    best = (height * width, i, height, start, width);
                }
            }
            stack.push(j);
        }
    }
    let (cells, i_top, height, j_start, width) = best;
    let area = cells as f64 / (GRID * GRID) as f64 * workspace.area_m2();
    if cells == 0 {
        return (0.0, workspace.center());
    }
    // Rows i_top − height + 1 … i_top, columns j_start … j_start + width − 1.
    let x_lo = x0 + (i_top + 1 - height) as f64 * dx;
    let x_hi = x0 + (i_top + 1) as f64 * dx;
    let y_lo = y0 + j_start as f64 * dy;
    let y_hi = y0 + (j_start + width) as f64 * dy;
    (area, Point2::new((x_lo + x_hi) / 2.0, (y_lo + y_hi) / 2.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_protocol::geometry::{Point3, Pose, RobotModel};

    pub(crate) fn niryo() -> WorkspaceInfo {
        WorkspaceInfo {
            id: "niryo_ws".into(),
            robot: RobotModel::Ned2,
            upper_left: Point2::new(0.337, 0.087),
            lower_right: Point2::new(0.163, -0.087),
            observation_pose: Pose::new(0.173, -0.002, 0.277, -3.042, 1.327, -3.027),
        }
    }

    fn object(x: f64, y: f64, w: f64, h: f64) -> DetectedObject {
        let mut o = DetectedObject::default();
        o.position.center_of_mass = Point3::new(x, y, 0.0);
        o.dimensions.width_m = w;
        o.dimensions.height_m = h;
        o.dimensions.size_m2 = w * h;
        o
    }

    #[test]
    fn empty_workspace_is_all_free() {
        let ws = niryo();
        let (area, c) = largest_free_space(&ws, &[], 0.01);
        assert!((area - 0.174 * 0.174).abs() < 1e-12);
        assert!((c.x_m - 0.25).abs() < 1e-9 && c.y_m.abs() < 1e-9);
    }

    #[test]
    fn a_strip_across_leaves_the_larger_side() {
        // A bar across the whole width at x = 0.20 (height 0.02 along x, margin 0.01):
        // occupied x ∈ [0.18, 0.22]. Cells are 1.74 mm; cell centres 0.163 + (i + 0.5)·0.00174.
        // Free near side: x < 0.18 → rows 0..=9 (centre of row 9 = 0.17953); far side:
        // x > 0.22 → rows 33..=99 (row 32 centre 0.21956 is occupied, row 33 0.2213 free):
        // 67 rows × 100 columns = 6700 cells → 0.67 × 0.030276 m² = 0.020285 m², centred at
        // x = 0.163 + (33 + 100) / 2 · 0.00174 = 0.27871, y = 0.
        let ws = niryo();
        let (area, c) = largest_free_space(&ws, &[object(0.20, 0.0, 0.3, 0.02)], 0.01);
        assert!((area - 0.67 * 0.174 * 0.174).abs() < 1e-9, "{area}");
        assert!(
            (c.x_m - 0.27871).abs() < 1e-6 && c.y_m.abs() < 1e-9,
            "{c:?}"
        );
    }

    #[test]
    fn one_cube_in_the_middle_leaves_the_near_strip() {
        // A 3 cm cube at the centre (0.25, 0) with a 1 cm margin occupies |x − 0.25| ≤ 0.025
        // and |y| ≤ 0.025. Row i's centre is x = 0.163 + (i + 0.5) · 0.00174: row 35 is at
        // 0.22477 (25.2 mm away, free), row 36 at 0.22651 (23.5 mm, occupied) … row 63 at
        // 0.27349 (occupied), row 64 at 0.27523 (25.2 mm, free) — rows 36..=63 are blocked,
        // and by symmetry columns 36..=63.
        // Four free strips of 36 × 100 = 3600 cells each (near, far, right, left); the first
        // found, scanning rows near → far, is the near strip, rows 0..=35:
        // x ∈ [0.163, 0.163 + 36 · 0.00174 = 0.22564], centre x = 0.19432, y = 0;
        // area = 0.36 · 0.174² = 0.01089936 m².
        let ws = niryo();
        let (area, c) = largest_free_space(&ws, &[object(0.25, 0.0, 0.03, 0.03)], 0.01);
        assert!((area - 0.01089936).abs() < 1e-9, "{area}");
        assert!(
            (c.x_m - 0.19432).abs() < 1e-9 && c.y_m.abs() < 1e-9,
            "{c:?}"
        );
    }

    #[test]
    fn a_corner_object_leaves_an_l_whose_larger_arm_wins() {
        // A 5 cm × 5 cm object (no margin) centred on the far-left corner (0.337, 0.087)
        // covers x ≥ 0.312 and y ≥ 0.062. Row 85's centre, 0.163 + 85.5 · 0.00174 = 0.31177,
        // is 25.2 mm from 0.337 (free); row 86's, 0.31351, 23.5 mm (occupied): rows 86..=99
        // are blocked where the object is, and likewise columns 86..=99.
        // Free: rows 0..=85 × all 100 columns = 8600 cells, or all rows × columns 0..=85 =
        // 8600 cells; the row strip is found first (at row 85), the column strip ties and does
        // not replace it. Area 0.86 · 0.030276 = 0.02603736 m²; centre
        // x = 0.163 + 86 · 0.00174 / 2 = 0.23782, y = 0.
        let ws = niryo();
        let (area, c) = largest_free_space(&ws, &[object(0.337, 0.087, 0.05, 0.05)], 0.0);
        assert!((area - 0.02603736).abs() < 1e-9, "{area}");
        assert!(
            (c.x_m - 0.23782).abs() < 1e-9 && c.y_m.abs() < 1e-9,
            "{c:?}"
        );
    }

    #[test]
    fn a_full_workspace_has_no_free_space() {
        let ws = niryo();
        let (area, c) = largest_free_space(&ws, &[object(0.25, 0.0, 0.5, 0.5)], 0.0);
        assert_eq!(area, 0.0);
        assert_eq!(c, ws.center());
    }
}
