//! Where the fingers and the objects will go, checked before anything moves.
//!
//! - **Grasps** ([`grasp_yaw`]): the open fingers sweep a rectangle across the object
//!   ([`geometry::finger_sweep`]) down to the grasp height. Of the yaws that fit the object (across
//!   its narrow side, and across its long side when that fits the gripper too), the one whose
//!   sweep keeps the most room to its neighbours is taken; when every yaw would touch a
//!   neighbour taller than the finger tips, the pick is refused naming it.
//! - **Placements** ([`place_target`]): the held object's footprint must lie in a workspace,
//!   clear of the other objects (for table placements) and of the corner markers (the camera
//!   needs all four); the fingers, opening to release, must not reach a neighbour. Placements
//!   beside a reference step outwards from the contract's spot until all of that holds, so
//!   that a later grasp of either object finds room for the fingers.
//! - **Pushes** ([`push_problem`]): the area the pushed object sweeps must be free of other
//!   objects (they would be shoved along, unplanned), and where it ends must lie on the sheet and
//!   keep clear of the markers.
//!
//! Objects always come to rest wholly on a workspace sheet: one half off it is seen cut at the
//! sheet's edge, as a smaller object in the wrong place, and a later grasp of it would miss.
//!
//! Pick-and-place skills plan the place with the view taken for the pick, before the pick
//! starts: a place that cannot work means the pick does not start.

use crate::geometry::{self, extents, finger_sweep, marker_zones, top_z, Rect};
use crate::SkillsSettings;
use robotd_protocol::location::PLACE_GAP_M;
use robotd_protocol::objects::DetectedObject;
use robotd_protocol::skills::SkillError;
use robotd_protocol::workspace::WorkspaceInfo;
use robotd_protocol::{Location, Point2};
use std::f64::consts::FRAC_PI_2;

/// How far beyond the contract's spot a placement beside a reference may move outwards, in
/// steps of [`SIDE_STEP_M`], metres.
const SIDE_SEARCH_M: f64 = 0.03;
/// Step of that search, metres.
const SIDE_STEP_M: f64 = 0.0025;
/// How far an object's footprint may reach beyond the workspace rectangle (the marker
/// centres), metres: the detector looks 16 mm beyond it (the sheet's white border), less a
/// few millimetres for the object's own measurement.
const SHEET_BORDER_M: f64 = 0.012;
/// How far a stacked object may reach beyond the edge of the one below, metres.
const STACK_OVERHANG_M: f64 = 0.005;
/// Room kept between the pushing gripper's path and objects it must not touch, metres.
pub const PUSH_TOOL_CLEARANCE_M: f64 = 0.002;
/// Clearances tried when ranking grasp yaws (the largest that fits wins), metres.
pub const CLEARANCE_STEPS_M: [f64; 6] = [0.0, 0.002, 0.004, 0.007, 0.01, 0.015];

/// The object the gripper will hold, and how.
#[derive(Debug, Clone, Copy)]
pub struct HeldPlan<'a> {
    /// The object as seen before the pick.
    pub object: &'a DetectedObject,
    /// Gripper yaw of the grasp, radians.
    pub yaw_rad: f64,
    /// Height of the tool centre above the object's base while held, metres.
    pub tcp_above_base_m: f64,
}

/// The workspace `p` lies in, or the error naming the nearest one.
pub fn workspace_of(
    settings: &SkillsSettings,
    what: &str,
    p: Point2,
) -> Result<WorkspaceInfo, SkillError> {
    geometry::workspace_of(&settings.workspaces, p, settings.workspace_margin_m)
        .cloned()
        .ok_or_else(|| SkillError::OutsideWorkspace {
            what: what.to_owned(),
            at: p,
            workspace_id: settings
                .workspaces
                .iter()
                .min_by(|a, b| {
                    a.center()
                        .distance_to(&p)
                        .total_cmp(&b.center().distance_to(&p))
                })
                .map(|w| w.id.clone())
                .unwrap_or_default(),
        })
}

/// Half the span of the open fingers along the closing axis, metres.
fn open_reach(settings: &SkillsSettings) -> f64 {
    settings.gripper_max_width_m / 2.0 + settings.finger_thickness_m
}

/// How far below `above_z` an object's top may be and still count as in the way, metres: a
/// finger that comes down onto a top is a collision, even by a fraction of a millimetre.
const TOP_MARGIN_M: f64 = 0.0005;

/// The first of `others` whose footprint meets `area` and whose top reaches `above_z` (within
/// [`TOP_MARGIN_M`]).
fn first_in<'a>(
    area: &Rect,
    others: &'a [DetectedObject],
    above_z: f64,
) -> Option<&'a DetectedObject> {
    others
        .iter()
        .find(|o| top_z(o) > above_z - TOP_MARGIN_M && area.overlaps(&Rect::of_object(o)))
}

/// Gap kept between a grasped object's top and the palm, metres.
pub const PALM_CLEARANCE_M: f64 = 0.003;

/// The tool height for grasping `object` with the caller's `z_offset_m` above its centre of
/// mass: never below the lowest commanded height, and high enough that the palm, on top of
/// the fingers, clears the object's own top (a tall object is held by its upper part).
#[cfg(test)]
pub fn grasp_height(settings: &SkillsSettings, object: &DetectedObject, z_offset_m: f64) -> f64 {
    grasp_height_on(settings, object, 0.0, z_offset_m)
}

/// [`grasp_height`] for an object standing on a surface at `base_z` (the top of the object it
/// is stacked on; 0 on the table): its top is its base plus twice its centre of mass above it.
pub fn grasp_height_on(
    settings: &SkillsSettings,
    object: &DetectedObject,
    base_z: f64,
    z_offset_m: f64,
) -> f64 {
    let z = object.position.center_of_mass.z_m;
    let wanted = z + z_offset_m;
    let top = (2.0 * z - base_z).max(base_z);
    let palm_clear = top - settings.finger_length_m + PALM_CLEARANCE_M;
    wanted.max(palm_clear).max(settings.min_tcp_z_m)
}

/// The gripper yaw for grasping `object` at tool height `grasp_z` among `others` (the object
/// itself may be among them): the fitting yaw with the most room for the open fingers.
pub fn grasp_yaw(
    settings: &SkillsSettings,
    object: &DetectedObject,
    others: &[DetectedObject],
    grasp_z: f64,
) -> Result<f64, SkillError> {
    let neighbours: Vec<DetectedObject> = others
        .iter()
        .filter(|o| o.id != object.id)
        .cloned()
        .collect();
    let (w, h) = extents(object);
    let mut yaws = vec![object.gripper_rotation_rad];
    if w.max(h) <= settings.gripper_max_width_m - 0.002 {
        yaws.push(object.gripper_rotation_rad + FRAC_PI_2);
    }
    let reach = open_reach(settings);
    let mut best: Option<(f64, f64)> = None;
    let mut blocker = None;
    for yaw in yaws {
        let sweep = finger_sweep(object.xy(), yaw, reach, settings.finger_reach_m);
        // The palm, on top of the fingers, is wider than they are: taller neighbours must
        // clear it too.
        let palm = finger_sweep(
            object.xy(),
            yaw,
            settings.palm_half_length_m,
            settings.palm_reach_m,
        );
        let palm_z = grasp_z + settings.finger_length_m;
        let mut room = None;
        for gap in CLEARANCE_STEPS_M {
            let hit = first_in(&sweep.grown(gap), &neighbours, grasp_z)
                .or_else(|| first_in(&palm.grown(gap), &neighbours, palm_z));
            match hit {
                None => room = Some(gap),
                Some(o) => {
                    if gap == 0.0 && blocker.is_none() {
                        blocker = Some(o.label.clone());
                    }
                    break;
                }
            }
        }
        if let Some(room) = room {
            if best.is_none_or(|(_, r)| room > r) {
                best = Some((yaw, room));
            }
        }
    }
    match (best, blocker) {
        (Some((yaw, _)), _) => Ok(yaw),
        (None, blocker) => Err(SkillError::BadPlacement {
            reason: format!(
                "the open gripper's fingers would hit '{}' grasping '{}' at [{:.3}, {:.3}]; \
                 move one of them apart first (push_object)",
                blocker.unwrap_or_default(),
                object.label,
                object.xy().x_m,
                object.xy().y_m
            ),
        }),
    }
}

/// What is wrong with the held object coming to rest at `at` on a surface at `surface_z`,
/// released by the fingers at tool height `release_z`: `None` when nothing is.
fn placement_problem(
    settings: &SkillsSettings,
    others: &[DetectedObject],
    held: &HeldPlan<'_>,
    at: Point2,
    surface_z: f64,
    release_z: f64,
) -> Option<String> {
    let label = &held.object.label;
    let Ok(ws) = workspace_of(settings, "place", at) else {
        return Some(format!(
            "'{label}' at [{:.3}, {:.3}] would lie outside the workspaces",
            at.x_m, at.y_m
        ));
    };
    let footprint = Rect::of_object_at(held.object, at);
    if surface_z == 0.0 {
        if let Some(taken) = others
            .iter()
            .find(|o| footprint.overlaps(&Rect::of_object(o)))
        {
            return Some(format!(
                "'{label}' would not fit at [{:.3}, {:.3}]: '{}' is in the way",
                at.x_m, at.y_m, taken.label
            ));
        }
    }
    if let Some(problem) = marker_problem(settings, &ws, label, &footprint) {
        return Some(problem);
    }
    if let Some(problem) = off_sheet_problem(&ws, label, &footprint) {
        return Some(problem);
    }
    let sweep = finger_sweep(
        at,
        held.yaw_rad,
        open_reach(settings),
        settings.finger_reach_m,
    );
    if let Some(hit) = first_in(&sweep, others, release_z) {
        return Some(format!(
            "releasing '{label}' at [{:.3}, {:.3}], the opening fingers would hit '{}'",
            at.x_m, at.y_m, hit.label
        ));
    }
    None
}

/// Whether the axis-aligned `footprint` sticks out of the workspace rectangle of `ws`.
fn off_sheet_problem(ws: &WorkspaceInfo, label: &str, footprint: &Rect) -> Option<String> {
    let (ul, lr) = (ws.upper_left, ws.lower_right);
    let (x_lo, x_hi) = (ul.x_m.min(lr.x_m), ul.x_m.max(lr.x_m));
    let (y_lo, y_hi) = (ul.y_m.min(lr.y_m), ul.y_m.max(lr.y_m));
    let c = footprint.centre;
    let t = SHEET_BORDER_M;
    let (hx, hy) = (footprint.half_extent_x(), footprint.half_extent_y());
    let out = c.x_m - hx < x_lo - t
        || c.x_m + hx > x_hi + t
        || c.y_m - hy < y_lo - t
        || c.y_m + hy > y_hi + t;
    out.then(|| {
        format!(
            "'{label}' at [{:.3}, {:.3}] would stick out of the sheet of workspace '{}' (x {:.3} \
             … {:.3}, y {:.3} … {:.3}), where the camera would see it cut at the edge",
            c.x_m,
            c.y_m,
            ws.id,
            x_lo - t,
            x_hi + t,
            y_lo - t,
            y_hi + t
        )
    })
}

/// Whether `footprint` covers a corner marker of `ws` (or the margin the camera needs).
fn marker_problem(
    settings: &SkillsSettings,
    ws: &WorkspaceInfo,
    label: &str,
    footprint: &Rect,
) -> Option<String> {
    marker_zones(ws, settings.marker_keep_out_m)
        .iter()
        .find(|zone| footprint.overlaps(zone))
        .map(|zone| {
            format!(
                "'{label}' at [{:.3}, {:.3}] would cover the marker at [{:.3}, {:.3}] of \
                 workspace '{}', and the camera needs all four to see the workspace",
                footprint.centre.x_m, footprint.centre.y_m, zone.centre.x_m, zone.centre.y_m, ws.id
            )
        })
}

/// What is wrong with the closed gripper going down at `start` behind `object` and
/// travelling to `end` at tool height `low_z` (turned by `yaw_rad`): `None` when it touches
/// nothing but `object` on the way.
pub fn push_tool_problem(
    settings: &SkillsSettings,
    object: &DetectedObject,
    others: &[DetectedObject],
    start: Point2,
    end: Point2,
    yaw_rad: f64,
    low_z: f64,
) -> Option<String> {
    // The closed fingers: their two thicknesses along the closing axis, their width across.
    let fingers = finger_sweep(
        start,
        yaw_rad,
        settings.finger_thickness_m,
        settings.finger_reach_m,
    );
    let path = Rect::footprint(
        Point2::new((start.x_m + end.x_m) / 2.0, (start.y_m + end.y_m) / 2.0),
        (
            2.0 * fingers.half_extent_y() + (end.y_m - start.y_m).abs(),
            2.0 * fingers.half_extent_x() + (end.x_m - start.x_m).abs(),
        ),
    )
    .grown(PUSH_TOOL_CLEARANCE_M);
    let in_the_way: Vec<DetectedObject> = others
        .iter()
        .filter(|o| o.id != object.id)
        .cloned()
        .collect();
    first_in(&path, &in_the_way, low_z).map(|hit| {
        format!(
            "pushing '{}', the gripper would hit '{}' on its way from [{:.3}, {:.3}] to \
             [{:.3}, {:.3}]; move '{}' first",
            object.label, hit.label, start.x_m, start.y_m, end.x_m, end.y_m, hit.label
        )
    })
}

/// What is wrong with pushing `object` so that it ends at `end`, among `others`: `None` when
/// nothing is.
pub fn push_problem(
    settings: &SkillsSettings,
    object: &DetectedObject,
    others: &[DetectedObject],
    end: Point2,
) -> Option<String> {
    let ws = workspace_of(settings, "push", end).ok()?;
    let label = &object.label;
    let start = object.xy();
    let here = Rect::of_object(object);
    // Pushes go along x or y: the swept area is the box around both footprints.
    let swept = Rect::footprint(
        Point2::new((start.x_m + end.x_m) / 2.0, (start.y_m + end.y_m) / 2.0),
        (
            2.0 * here.half_extent_y() + (end.y_m - start.y_m).abs(),
            2.0 * here.half_extent_x() + (end.x_m - start.x_m).abs(),
        ),
    );
    if let Some(other) = others
        .iter()
        .find(|o| o.id != object.id && swept.overlaps(&Rect::of_object(o)))
    {
        return Some(format!(
            "pushing '{label}' to [{:.3}, {:.3}] would shove '{}' along; move it first or push \
             less far",
            end.x_m, end.y_m, other.label
        ));
    }
    let footprint = Rect::of_object_at(object, end);
    marker_problem(settings, &ws, label, &footprint)
        .or_else(|| off_sheet_problem(&ws, label, &footprint))
}

/// Tool height for releasing the held object onto a surface at `surface_z`: a stacked
/// object is released higher by [`SkillsSettings::stack_height_margin_m`], as the height of
/// what it goes onto is measured by the camera.
pub fn release_height(settings: &SkillsSettings, held: &HeldPlan<'_>, surface_z: f64) -> f64 {
    let margin = if surface_z > 0.0 {
        settings.stack_height_margin_m
    } else {
        0.0
    };
    (surface_z + held.tcp_above_base_m + settings.release_gap_m + margin).max(settings.min_tcp_z_m)
}

/// A spot on the table where the held object fits (no placement problem among `others`),
/// nearest the centre of its workspace: what a failure that leaves it held suggests.
pub fn free_spot(
    settings: &SkillsSettings,
    others: &[DetectedObject],
    held: &HeldPlan<'_>,
) -> Option<Point2> {
    const STEP_M: f64 = 0.005;
    let release_z = release_height(settings, held, 0.0);
    settings
        .workspaces
        .iter()
        .flat_map(|ws| {
            let (ul, lr) = (ws.upper_left, ws.lower_right);
            let (x_lo, x_hi) = (ul.x_m.min(lr.x_m), ul.x_m.max(lr.x_m));
            let (y_lo, y_hi) = (ul.y_m.min(lr.y_m), ul.y_m.max(lr.y_m));
            let nx = ((x_hi - x_lo) / STEP_M).floor() as usize;
            let ny = ((y_hi - y_lo) / STEP_M).floor() as usize;
            let centre = ws.center();
            (0..=nx).flat_map(move |i| {
                (0..=ny).map(move |j| {
                    let p = Point2::new(x_lo + i as f64 * STEP_M, y_lo + j as f64 * STEP_M);
                    (p.distance_to(&centre), p)
                })
            })
        })
        .filter(|(_, p)| placement_problem(settings, others, held, *p, 0.0, release_z).is_none())
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, p)| p)
}

/// Where the held object goes for a placement at `at` with `location`, among `others` (the
/// objects on the table without the held one): its centre and the height of the surface it
/// rests on.
pub fn place_target(
    settings: &SkillsSettings,
    others: &[DetectedObject],
    held: &HeldPlan<'_>,
    at: Point2,
    location: Location,
) -> Result<(Point2, f64), SkillError> {
    let release_z = |surface_z: f64| release_height(settings, held, surface_z);
    let bad = |reason: String| SkillError::BadPlacement { reason };
    if location == Location::None {
        workspace_of(settings, "place", at)?;
        return match placement_problem(settings, others, held, at, 0.0, release_z(0.0)) {
            None => Ok((at, 0.0)),
            Some(problem) => Err(bad(problem)),
        };
    }
    let reference = others
        .iter()
        .min_by(|a, b| a.xy().distance_to(&at).total_cmp(&b.xy().distance_to(&at)))
        .ok_or_else(|| {
            bad(format!(
                "no object near [{:.3}, {:.3}] to place {location}",
                at.x_m, at.y_m
            ))
        })?;
    let on_reference = |surface_z: f64| {
        let target = reference.xy();
        workspace_of(settings, "place", target)?;
        match placement_problem(
            settings,
            others,
            held,
            target,
            surface_z,
            release_z(surface_z),
        ) {
            None => Ok((target, surface_z)),
            Some(problem) => Err(bad(problem)),
        }
    };
    let sides: Vec<Location> = match location {
        Location::OnTopOf => {
            // A stack stands only when the upper object rests on the lower one's top.
            let support = Rect::of_object(reference).grown(STACK_OVERHANG_M);
            if !support.contains(&Rect::of_object_at(held.object, reference.xy())) {
                return Err(bad(format!(
                    "'{}' would overhang '{}' on top of it (more than {:.0} mm over its edge); \
                     stack smaller objects on larger ones",
                    held.object.label,
                    reference.label,
                    STACK_OVERHANG_M * 1000.0
                )));
            }
            return on_reference(geometry::top_among(reference, others));
        }
        Location::Inside => return on_reference(settings.container_floor_m),
        Location::CloseTo => {
            let mut sides = vec![
                Location::LeftNextTo,
                Location::RightNextTo,
                Location::Above,
                Location::Below,
            ];
            let distance = |side: &Location| {
                geometry::beside(reference, *side, extents(held.object))
                    .map_or(f64::INFINITY, |p| p.distance_to(&at))
            };
            sides.sort_by(|a, b| distance(a).total_cmp(&distance(b)));
            sides
        }
        side => vec![side],
    };
    let mut first_problem = None;
    for side in sides {
        let Some(spot) = geometry::beside(reference, side, extents(held.object)) else {
            continue;
        };
        let outwards = {
            let (dx, dy) = (spot.x_m - reference.xy().x_m, spot.y_m - reference.xy().y_m);
            let n = dx.hypot(dy).max(1e-9);
            (dx / n, dy / n)
        };
        let steps = (SIDE_SEARCH_M / SIDE_STEP_M).round() as usize;
        for k in 0..=steps {
            let d = k as f64 * SIDE_STEP_M;
            let p = Point2::new(spot.x_m + outwards.0 * d, spot.y_m + outwards.1 * d);
            match placement_problem(settings, others, held, p, 0.0, release_z(0.0)) {
                None => return Ok((p, 0.0)),
                Some(problem) => {
                    first_problem.get_or_insert(problem);
                }
            }
        }
    }
    let problem = first_problem.unwrap_or_else(|| "no side to place on".to_owned());
    Err(bad(format!(
        "no room {location} '{}' at [{:.3}, {:.3}] (tried up to {:.0} mm beyond the {:.0} mm \
         gap): {problem}",
        reference.label,
        reference.xy().x_m,
        reference.xy().y_m,
        SIDE_SEARCH_M * 1000.0,
        PLACE_GAP_M * 1000.0
    )))
}

#[cfg(test)]
#[path = "plan/against_sim.rs"]
mod against_sim;
#[cfg(test)]
#[path = "plan/tests.rs"]
pub(crate) mod tests;
