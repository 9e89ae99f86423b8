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
//! What the tool answers is [`placeable_free_space`]: the largest free **square**, so that its
//! answer — an area and a centre, nothing else — says what fits: anything whose footprint fits
//! in a square of the answered area (its longest side no longer than the square root of it)
//! can be put down at the answered centre. (A rectangle's area says nothing of a pencil's
//! length: a 200 × 30 mm strip has the area of an 80 mm square and takes neither a cube nor
//! a pencil.) The same search as above, but with the skills' footprints (turned as the objects
//! lie) and the corner markers' keep-out squares taken as occupied; each free rectangle gives
//! the square centred in it, and a centre is answered only when the skills' own placement check
//! ([`robotd_placement::geometry::table_place_problem`]) accepts there an object as large as the
//! square and, for every gripper yaw, the smallest object (released lowest, its opening fingers
//! reaching furthest beyond it). Of the free squares, the largest whose centre passes is
//! answered.
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

use robotd_placement::geometry::{marker_zones, table_place_problem, Rect};
use robotd_placement::SkillsSettings;
use robotd_protocol::geometry::{Point2, Point3};
use robotd_protocol::objects::DetectedObject;
use robotd_protocol::workspace::WorkspaceInfo;
use std::f64::consts::PI;

/// Cells along each side of the grid.
pub const GRID: usize = 100;

/// Gripper yaws the smallest-object probe of [`placeable_free_space`] is checked at (every
/// 15° of a half turn; the fingers are symmetric).
const PROBE_YAWS: usize = 12;

/// Free rectangles [`placeable_free_space`] checks for any object, largest first, before it
/// gives up (for the objects memory holds it checks every one).
const MAX_CHECKED: usize = 4000;

/// A free rectangle of the grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FreeRect {
    /// Its area, m².
    pub area_m2: f64,
    /// Its centre.
    pub center: Point2,
    /// Its extent along x, metres.
    pub size_x_m: f64,
    /// Its extent along y, metres.
    pub size_y_m: f64,
}

impl FreeRect {
    /// The largest square inside it with the same centre.
    pub fn centred_square(self) -> FreeRect {
        let side = self.size_x_m.min(self.size_y_m);
        FreeRect {
            area_m2: side * side,
            center: self.center,
            size_x_m: side,
            size_y_m: side,
        }
    }
}

/// The grid of a workspace: its near-right corner and cell sizes.
struct Grid {
    x0: f64,
    y0: f64,
    dx: f64,
    dy: f64,
    area_m2: f64,
}

impl Grid {
    fn of(workspace: &WorkspaceInfo) -> Self {
        Self {
            x0: workspace.lower_right.x_m,
            y0: workspace.lower_right.y_m,
            dx: workspace.height_m() / GRID as f64,
            dy: workspace.width_m() / GRID as f64,
            area_m2: workspace.area_m2(),
        }
    }

    /// The centre of cell (i, j).
    fn cell(&self, i: usize, j: usize) -> Point2 {
        Point2::new(
            self.x0 + (i as f64 + 0.5) * self.dx,
            self.y0 + (j as f64 + 0.5) * self.dy,
        )
    }

    /// `occupied[i][j]`: row i along x (near → far), column j along y (right → left); a cell is
    /// occupied when `inside` holds at its centre.
    fn occupied(&self, inside: impl Fn(Point2) -> bool) -> Vec<[bool; GRID]> {
        let mut occupied = vec![[false; GRID]; GRID];
        for (i, row) in occupied.iter_mut().enumerate() {
            for (j, cell) in row.iter_mut().enumerate() {
                *cell = inside(self.cell(i, j));
            }
        }
        occupied
    }

    /// The rectangle of `height` rows ending at row `i_top` and `width` columns from
    /// `j_start`.
    fn rect(&self, (cells, i_top, height, j_start, width): Candidate) -> FreeRect {
        let x_lo = self.x0 + (i_top + 1 - height) as f64 * self.dx;
        let x_hi = self.x0 + (i_top + 1) as f64 * self.dx;
        let y_lo = self.y0 + j_start as f64 * self.dy;
        let y_hi = self.y0 + (j_start + width) as f64 * self.dy;
        FreeRect {
            area_m2: cells as f64 / (GRID * GRID) as f64 * self.area_m2,
            center: Point2::new((x_lo + x_hi) / 2.0, (y_lo + y_hi) / 2.0),
            size_x_m: x_hi - x_lo,
            size_y_m: y_hi - y_lo,
        }
    }
}

/// A free rectangle of cells: (cells, i_top, height, j_start, width).
type Candidate = (usize, usize, usize, usize, usize);

/// The maximal free rectangles of `occupied` (the histogram-and-stack algorithm: each row
/// taken as the bottom, the free cells above each column as a histogram), in the order found.
fn free_rectangles(occupied: &[[bool; GRID]]) -> Vec<Candidate> {
    let mut found = Vec::new();
    let mut heights = [0usize; GRID];
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
                found.push((height * width, i, height, start, width));
            }
            stack.push(j);
        }
    }
    found
}

/// The largest free rectangle: area in m² and centre.
pub fn largest_free_space(
    workspace: &WorkspaceInfo,
    objects: &[DetectedObject],
    margin_m: f64,
) -> (f64, Point2) {
    let grid = Grid::of(workspace);
    let occupied = grid.occupied(|p| {
        objects.iter().any(|o| {
            let c = o.xy();
            (p.x_m - c.x_m).abs() <= o.dimensions.height_m / 2.0 + margin_m
                && (p.y_m - c.y_m).abs() <= o.dimensions.width_m / 2.0 + margin_m
        })
    });
    // Of equally large rectangles the first found wins.
    let mut best: Option<Candidate> = None;
    for candidate in free_rectangles(&occupied) {
        if candidate.0 > best.map_or(0, |b| b.0) {
            best = Some(candidate);
        }
    }
    match best {
        Some(best) => {
            let rect = grid.rect(best);
            (rect.area_m2, rect.center)
        }
        None => (0.0, workspace.center()),
    }
}

/// The largest free square of `workspace` whose centre takes a place (module docs): the
/// objects' footprints grown by `margin_m` and the corner markers' keep-out squares are
/// occupied, and the centre passes the skills' placement check (`skills`' sizes) for any
/// object that fits the square. Of those, the largest that also takes each of `known` (the
/// objects memory holds: on the table or in the gripper) that the gripper can hold and whose
/// footprint is no larger than the largest such square, as it lies, wins — so a pencil longer
/// than any free square is still sent where it fits when some free rectangle's centre takes
/// it; when none with the margin does, one without it (the skills need none). `None` when no
/// free square takes a place.
pub fn placeable_free_space(
    workspace: &WorkspaceInfo,
    objects: &[DetectedObject],
    known: &[DetectedObject],
    margin_m: f64,
    skills: &SkillsSettings,
) -> Option<FreeRect> {
    let rects = free_rects(workspace, objects, margin_m, skills);
    let first = rects
        .iter()
        .take(MAX_CHECKED)
        .find(|rect| takes_any_place(rect, objects, skills))
        .copied()?;
    // The objects memory holds that the gripper can hold (the others are never placed) and
    // whose footprint is no larger than the largest placeable square's area: those that fit
    // it, and longer ones (a pencil) that a free rectangle's centre may still take.
    let known: Vec<DetectedObject> = known
        .iter()
        .filter(|o| {
            let (w, h) = (o.dimensions.width_m, o.dimensions.height_m);
            w * h <= first.area_m2 && w.min(h) <= skills.gripper_max_width_m - 0.002
        })
        .cloned()
        .collect();
    let all = known.len();
    let mut best = (taken(&first, objects, &known, skills), first);
    if best.0 == all {
        return Some(first);
    }
    // Every free rectangle, the cheap count first; then, since the skills need no margin,
    // those nearer the objects than it. The one taking the most (the largest of those) wins.
    let nearer = if margin_m > 0.0 {
        free_rects(workspace, objects, 0.0, skills)
    } else {
        Vec::new()
    };
    for rect in rects.iter().chain(&nearer) {
        let count = taken(rect, objects, &known, skills);
        if count > best.0 && takes_any_place(rect, objects, skills) {
            best = (count, *rect);
            if count == all {
                break;
            }
        }
    }
    Some(best.1)
}

/// The squares centred in the free rectangles of `workspace` (objects' footprints grown by
/// `margin_m` and the markers' keep-out squares occupied), largest first.
fn free_rects(
    workspace: &WorkspaceInfo,
    objects: &[DetectedObject],
    margin_m: f64,
    skills: &SkillsSettings,
) -> Vec<FreeRect> {
    let grid = Grid::of(workspace);
    let footprints: Vec<Rect> = objects
        .iter()
        .map(|o| Rect::of_object(o).grown(margin_m))
        .collect();
    // A cell whose centre is clear of a marker's square may still reach half a cell into it.
    let half_cell = grid.dx.hypot(grid.dy) / 2.0;
    let markers = marker_zones(workspace, skills.marker_keep_out_m).map(|z| z.grown(half_cell));
    let occupied = grid.occupied(|p| {
        let point = Rect::footprint(p, (0.0, 0.0));
        footprints
            .iter()
            .chain(&markers)
            .any(|area| area.contains(&point))
    });
    let mut candidates = free_rectangles(&occupied);
    candidates.sort_by_key(|c| std::cmp::Reverse(c.0));
    candidates.dedup();
    let mut squares: Vec<FreeRect> = candidates
        .into_iter()
        .map(|c| grid.rect(c).centred_square())
        .collect();
    // Largest first; of equally large ones the one of the larger rectangle, then the first
    // found (a stable sort).
    squares.sort_by(|a, b| b.area_m2.total_cmp(&a.area_m2));
    squares
}

/// How many of `known` the skills would put down at `rect`'s centre, each as it lies (at one
/// of the skills' grasp yaws), among `objects` without itself.
fn taken(
    rect: &FreeRect,
    objects: &[DetectedObject],
    known: &[DetectedObject],
    skills: &SkillsSettings,
) -> usize {
    known
        .iter()
        .filter(|o| {
            let others: Vec<DetectedObject> =
                objects.iter().filter(|p| p.id != o.id).cloned().collect();
            // The grasp yaws the skills take: across the narrow side, and across the long
            // side too when that fits the gripper.
            let yaw = o.gripper_rotation_rad;
            let long = o.dimensions.width_m.max(o.dimensions.height_m);
            let turned = long <= skills.gripper_max_width_m - 0.002;
            [Some(yaw), turned.then_some(yaw + PI / 2.0)]
                .into_iter()
                .flatten()
                .any(|y| table_place_problem(skills, &others, o, y, rect.center).is_none())
        })
        .count()
}

/// A flat probe object at `at`: `size_x` along x, `size_y` along y, 2 mm high.
fn probe(at: Point2, size_x: f64, size_y: f64) -> DetectedObject {
    let mut o = DetectedObject {
        id: "free-space-probe".into(),
        label: "an object".into(),
        ..Default::default()
    };
    o.position.center_of_mass = Point3::new(at.x_m, at.y_m, 0.001);
    o.position.center = o.position.center_of_mass;
    o.dimensions.width_m = size_y;
    o.dimensions.height_m = size_x;
    o.dimensions.size_m2 = size_x * size_y;
    // The footprint's long side lies along the grasp yaw's x axis.
    o.gripper_rotation_rad = if size_y > size_x { PI / 2.0 } else { 0.0 };
    o
}

/// Whether the skills would put down at `rect`'s centre an object as large as `rect` (less a
/// millimetre each side), and the smallest object at every gripper yaw.
fn takes_any_place(rect: &FreeRect, objects: &[DetectedObject], skills: &SkillsSettings) -> bool {
    let at = rect.center;
    let whole = probe(
        at,
        (rect.size_x_m - 0.002).max(0.001),
        (rect.size_y_m - 0.002).max(0.001),
    );
    let yaw = whole.gripper_rotation_rad;
    if table_place_problem(skills, objects, &whole, yaw, at).is_some() {
        return false;
    }
    let small = probe(at, 0.001, 0.001);
    (0..PROBE_YAWS).all(|k| {
        let yaw = k as f64 * PI / PROBE_YAWS as f64;
        table_place_problem(skills, objects, &small, yaw, at).is_none()
    })
}

#[cfg(test)]
mod tests;
