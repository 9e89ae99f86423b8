//! The world: objects on the table, the gripper moving among them, grasping, releasing and
//! pushing.

use crate::geom::{
    footprint_inside_rect, footprint_overlap, penetration, push_out, Footprint, Hull,
};
use crate::gripper::{GripperBox, GripperGeometry};
use crate::scene::{
    footprint_of, markers_of, sheet_rects, Marker, ObjectShape, ObjectSpec, Scene, SceneError,
    WorkspaceSpec, CONTAINER_WALL_M, MARKER_RADIUS_M, OVERLAP_TOLERANCE_M, SHEET_MARGIN_M,
    SHEET_Z_M,
};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector2, Vector3};
use robotd_protocol::geometry::RobotModel;
use std::collections::VecDeque;
use std::f64::consts::{FRAC_PI_2, PI};

/// Longest sub-step of a tool motion, metres (also for points 0.1 m from the TCP when the
/// tool turns).
pub const SUB_STEP_M: f64 = 0.001;
/// Lever arm used to turn a rotation into a sub-step length, metres.
const LEVER_M: f64 = 0.1;
/// Upper bound on the sub-steps of one motion (100 m of travel).
const MAX_SUB_STEPS: f64 = 100_000.0;
/// The gripper may touch things: only a penetration deeper than this is a contact.
pub const CONTACT_TOLERANCE_M: f64 = 0.0001;
/// A contact that already exists counts again only when a step makes it deeper by more than
/// this, metres: an arm leaving a contact along a joint-space path wobbles by a few microns,
/// and must not be stopped by it (a straight push into an object deepens by far more).
pub const DEEPER_M: f64 = 0.00005;
/// A carried object may sink this far into another (or the table) before it is a collision,
/// so that placing it on top of something, or down on the table, works.
pub const HELD_TOLERANCE_M: f64 = 0.002;
/// An object's centre must be this close to the TCP (perpendicular to the tool axis) to be
/// grasped.
pub const GRASP_CENTRE_TOLERANCE_M: f64 = 0.005;
/// The closing axis must be within this angle of the object's side to grasp, degrees.
pub const GRASP_ANGLE_TOLERANCE_DEG: f64 = 15.0;
/// The fingers must reach this far into an object along the tool axis (or 30 % of its extent,
/// if less) to grasp it.
pub const GRASP_MIN_ENGAGEMENT_M: f64 = 0.003;
/// A released object may start this far below the top of what it lands on.
const DROP_TOLERANCE_M: f64 = 0.003;
/// Two footprints must overlap this much for one to support the other.
const SUPPORT_OVERLAP_M: f64 = 0.0005;
/// A pushed object may be shoved at most this much further than the pushing step.
const PUSH_SLACK_M: f64 = 0.003;
/// A sub-step pushes (rather than collides) when |dz| ≤ this × its horizontal length.
const PUSH_MAX_SLOPE: f64 = 0.5;

/// The gripper: where its tool centre point is and how far apart its fingers are.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolState {
    /// Tool centre point pose in the world (= robot base) frame. The tool points along its +x,
    /// the fingers close along its y.
    pub tcp: Isometry3<f64>,
    /// Distance between the fingers' inner faces, metres.
    pub opening_m: f64,
}

impl ToolState {
    /// A tool state from position (m), roll/pitch/yaw (rad, R = Rz(yaw)·Ry(pitch)·Rx(roll))
    /// and opening (m).
    pub fn from_xyz_rpy(xyz: [f64; 3], rpy: [f64; 3], opening_m: f64) -> Self {
        Self {
            tcp: Isometry3::from_parts(
                Translation3::new(xyz[0], xyz[1], xyz[2]),
                UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
            ),
            opening_m,
        }
    }

    /// The tool pointing straight down (pitch +π/2, roll 0) at (x, y, z), turned by `yaw`:
    /// at yaw 0 the fingers close along the world y axis, at yaw θ along (−sin θ, cos θ, 0).
    pub fn pointing_down(x: f64, y: f64, z: f64, yaw: f64, opening_m: f64) -> Self {
        Self::from_xyz_rpy([x, y, z], [0.0, FRAC_PI_2, yaw], opening_m)
    }
}

/// An object of the world (ground truth).
#[derive(Debug, Clone, PartialEq)]
pub struct SimObject {
    /// Stable id within this world.
    pub id: u32,
    /// What it is (label, shape, colour; `x_m`/`y_m`/`yaw_rad` are where it started).
    pub spec: ObjectSpec,
    /// Pose of the object's centre (the middle of its bounding box). Upright objects have a
    /// pure yaw rotation; a carried object follows the tool and may be tilted.
    pub pose: Isometry3<f64>,
    /// Whether the gripper holds it.
    pub held: bool,
}

impl SimObject {
    /// Height of the object's top above the table, metres (upright objects).
    pub fn top_z(&self) -> f64 {
        self.pose.translation.z + self.spec.shape.height_m() / 2.0
    }

    /// Height of the object's base above the table, metres (upright objects).
    pub fn bottom_z(&self) -> f64 {
        self.pose.translation.z - self.spec.shape.height_m() / 2.0
    }

    /// Rotation of the object about the vertical, radians in (−π, π].
    pub fn yaw_rad(&self) -> f64 {
        upright_yaw(&self.pose.rotation)
    }
}

/// Something the gripper ran into.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Contact {
    /// The gripper (or what it carries) would have entered something solid.
    Collision {
        /// `"table"` or the label of the object.
        what: String,
    },
}

/// What happened during one [`World::move_tool`].
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct StepOutcome {
    /// Set when the motion stopped at a collision: `"table"` or the object's label.
    pub collision: Option<String>,
    /// Ids of the objects pushed during the motion (each once).
    pub pushed: Vec<u32>,
}

impl StepOutcome {
    /// The collision as a [`Contact`], if there was one.
    pub fn contact(&self) -> Option<Contact> {
        self.collision
            .as_ref()
            .map(|what| Contact::Collision { what: what.clone() })
    }
}

/// What [`World::close_gripper`] got.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum GraspOutcome {
    /// The object is now held; the fingers rest on it.
    Grasped {
        /// The object's id.
        id: u32,
        /// The object's label.
        label: String,
    },
    /// Nothing was grasped; the fingers closed fully.
    Empty {
        /// Why, e.g. "no object between the fingers".
        reason: String,
    },
}

#[derive(Debug, Clone, Copy)]
struct Held {
    id: u32,
    /// Object pose in the TCP frame.
    rel: Isometry3<f64>,
    /// The object's width between the fingers.
    width_m: f64,
}

/// Penetration depths of the gripper (and of what it carries) at one tool pose.
#[derive(Debug, Clone)]
struct Probe {
    table: f64,
    held_table: f64,
    /// Per object index: gripper vs object.
    grip: Vec<f64>,
    /// Per object index: carried object vs object.
    held: Vec<f64>,
}

enum Hit {
    Table,
    Grip(usize),
    Held(usize),
}

enum Step {
    Free(Probe),
    Pushed(Vec<Isometry3<f64>>, Vec<usize>, Probe),
    Blocked(String),
}

/// The simulated tabletop: workspace sheets, objects, and the gripper moving among them.
///
/// See the [crate documentation](crate) for the physics it models.
#[derive(Debug, Clone)]
pub struct World {
    name: String,
    robot: RobotModel,
    workspaces: Vec<WorkspaceSpec>,
    objects: Vec<SimObject>,
    next_id: u32,
    tool: ToolState,
    gripper: GripperGeometry,
    held: Option<Held>,
}

impl World {
    /// The world of `scene`: its objects standing on the table (ids 1, 2, … in file order),
    /// the tool 0.25 m above the middle of the first workspace pointing down, gripper open.
    ///
    /// The scene is taken as it is; check it first with [`Scene::validate`].
    pub fn new(scene: &Scene) -> World {
        let gripper = GripperGeometry::for_model(scene.robot);
        let [cx, cy] = scene
            .workspaces
            .first()
            .map(|w| w.centre())
            .unwrap_or([0.25, 0.0]);
        let mut world = World {
            name: scene.name.clone(),
            robot: scene.robot,
            workspaces: scene.workspaces.clone(),
            objects: Vec::new(),
            next_id: 1,
            tool: ToolState::pointing_down(cx, cy, 0.25, 0.0, gripper.max_opening_m),
            gripper,
            held: None,
        };
        for spec in &scene.objects {
            world.insert(spec.clone());
        }
        world
    }

    /// The scene's name.
    pub fn scene_name(&self) -> &str {
        &self.name
    }

    /// The robot model the world is set up for.
    pub fn robot(&self) -> RobotModel {
        self.robot
    }

    /// The workspaces of the scene.
    pub fn workspaces(&self) -> &[WorkspaceSpec] {
        &self.workspaces
    }

    /// Every object with its true pose — for tests and rendering; perception must never read
    /// it (it sees the rendered camera image).
    pub fn objects(&self) -> &[SimObject] {
        &self.objects
    }

    /// The object with id `id`.
    pub fn object(&self, id: u32) -> Option<&SimObject> {
        self.objects.iter().find(|o| o.id == id)
    }

    /// Puts a new object on the table at the spec's x, y and yaw. Refused (nothing changes)
    /// when its values are bad or it would overlap another object or the gripper.
    pub fn add_object(&mut self, spec: ObjectSpec) -> Result<u32, SceneError> {
        let refuse = |reason: String| SceneError::Refused {
            label: spec.label.clone(),
            reason,
        };
        let problems = spec.problems();
        if !problems.is_empty() {
            return Err(refuse(problems.join("; ")));
        }
        let pose = standing_pose(&spec);
        let hulls = object_hulls(&spec, &pose);
        for o in &self.objects {
            let depth = max_penetration(&hulls, &object_hulls(&o.spec, &o.pose));
            if depth > OVERLAP_TOLERANCE_M {
                return Err(refuse(format!(
                    "it would overlap '{}' (id {}) by {:.1} mm",
                    o.spec.label,
                    o.id,
                    depth * 1000.0
                )));
            }
        }
        if max_penetration(&hulls, &self.gripper_hulls(&self.tool.tcp)) > OVERLAP_TOLERANCE_M {
            return Err(refuse("it would overlap the gripper".to_owned()));
        }
        Ok(self.insert(spec))
    }

    fn insert(&mut self, spec: ObjectSpec) -> u32 {
        let id = self.next_id;
        self.next_id = self.next_id.saturating_add(1);
        let pose = standing_pose(&spec);
        self.objects.push(SimObject {
            id,
            spec,
            pose,
            held: false,
        });
        id
    }

    /// Removes an object (also a held one: the gripper then holds nothing). False if there was
    /// no such object.
    pub fn remove_object(&mut self, id: u32) -> bool {
        let before = self.objects.len();
        self.objects.retain(|o| o.id != id);
        if self.held.is_some_and(|h| h.id == id) {
            self.held = None;
        }
        self.objects.len() != before
    }

    /// The four markers of every workspace sheet (workspaces with the same corners share one
    /// sheet), at the sheet corners = the workspace corners. Exactly one marker per sheet — the
    /// upper-left (far-left) one — has a white centre.
    pub fn markers(&self) -> Vec<Marker> {
        markers_of(&self.workspaces)
    }

    /// The white sheet of every workspace as a quad `[upper-left, upper-right, lower-right,
    /// lower-left]` (far-left, far-right, near-right, near-left) at z = [`SHEET_Z_M`], reaching
    /// [`SHEET_MARGIN_M`] beyond the markers' outer rings.
    pub fn sheet_quads(&self) -> Vec<[Point3<f64>; 4]> {
        let m = MARKER_RADIUS_M + SHEET_MARGIN_M;
        sheet_rects(&self.workspaces)
            .into_iter()
            .map(|[x0, x1, y0, y1]| {
                let (x0, x1, y0, y1) = (x0 - m, x1 + m, y0 - m, y1 + m);
                [
                    Point3::new(x1, y1, SHEET_Z_M),
                    Point3::new(x1, y0, SHEET_Z_M),
                    Point3::new(x0, y0, SHEET_Z_M),
                    Point3::new(x0, y1, SHEET_Z_M),
                ]
            })
            .collect()
    }

    /// The id of the held object.
    pub fn held(&self) -> Option<u32> {
        self.held.map(|h| h.id)
    }

    /// The tool's current state.
    pub fn tool(&self) -> &ToolState {
        &self.tool
    }

    /// The gripper's sizes.
    pub fn gripper(&self) -> &GripperGeometry {
        &self.gripper
    }

    /// The gripper's solid boxes where the tool is now (for drawing and tests).
    pub fn gripper_boxes(&self) -> [GripperBox; 3] {
        self.gripper.boxes(&self.tool.tcp, self.tool.opening_m)
    }

    /// Current distance between the fingers, metres.
    pub fn gripper_width_m(&self) -> f64 {
        self.tool.opening_m
    }

    /// Puts the tool at `t` without physics (initialisation; motions go through
    /// [`move_tool`](Self::move_tool)). A held object follows. The opening is clamped to the
    /// gripper's range, and never below a held object's width; a non-finite pose or opening is
    /// ignored.
    pub fn set_tool(&mut self, t: ToolState) {
        if isometry_finite(&t.tcp) {
            self.tool.tcp = t.tcp;
        }
        if t.opening_m.is_finite() {
            let min = self.held.map_or(0.0, |h| h.width_m);
            self.tool.opening_m = t.opening_m.clamp(
                min.min(self.gripper.max_opening_m),
                self.gripper.max_opening_m,
            );
        }
        self.update_held_pose();
    }

    /// Moves the tool in a straight line (and a shortest rotation) from where it is to
    /// `to.tcp`, in sub-steps of at most 1 mm (also at 0.1 m from the TCP when it turns).
    ///
    /// At each sub-step:
    /// - a finger or the palm that would sink into the table, or a carried object that would
    ///   sink more than [`HELD_TOLERANCE_M`] into the table or another object, stops the
    ///   motion: the tool stays at the last free position (refined to within ~0.01 mm of the
    ///   contact) and the outcome names what was hit;
    /// - a finger or the palm that would enter an object either **pushes** it — when the
    ///   gripper is empty, the sub-step is mostly horizontal (|dz| ≤ 0.5 × horizontal travel)
    ///   and the object is wider along the closing axis than the opening (it cannot slip
    ///   between the fingers; always so for a closed gripper) — or else is a collision, as
    ///   above;
    /// - a pushed object is shoved along the step's horizontal direction just far enough to
    ///   clear the gripper (so it travels the remaining distance of the push, without
    ///   turning); whatever stands on it or inside it moves along; an object it then runs
    ///   into is shoved the same way, and so on; objects that lost their support drop;
    /// - a held object follows the tool rigidly.
    ///
    /// Contacts only count when they get deeper, so a tool that starts inside something (after
    /// [`set_tool`](Self::set_tool)) can move out of it. `to.opening_m` is ignored: the fingers
    /// move only through [`close_gripper`](Self::close_gripper) and
    /// [`open_gripper`](Self::open_gripper). A non-finite target does nothing.
    ///
    /// Returns the state reached and what happened.
    pub fn move_tool(&mut self, to: &ToolState) -> (ToolState, StepOutcome) {
        let mut outcome = StepOutcome::default();
        if !isometry_finite(&to.tcp) {
            return (self.tool, outcome);
        }
        let start = self.tool.tcp;
        let dist = (to.tcp.translation.vector - start.translation.vector).norm();
        let angle = start.rotation.angle_to(&to.tcp.rotation);
        let n = (dist.max(angle * LEVER_M) / SUB_STEP_M)
            .ceil()
            .clamp(1.0, MAX_SUB_STEPS) as usize;
        let mut poses = self.poses();
        let mut before = self.probe(&start, &poses);
        let mut prev = start;
        for i in 1..=n {
            let next = interpolate(&start, &to.tcp, i as f64 / n as f64);
            match self.step(&prev, &next, &before, &poses) {
                Step::Free(after) => {
                    before = after;
                    prev = next;
                }
                Step::Pushed(new_poses, moved, after) => {
                    poses = new_poses;
                    for (o, p) in self.objects.iter_mut().zip(&poses) {
                        o.pose = *p;
                    }
                    for i in moved {
                        let id = self.objects[i].id;
                        if !outcome.pushed.contains(&id) {
                            outcome.pushed.push(id);
                        }
                    }
                    before = after;
                    prev = next;
                }
                Step::Blocked(what) => {
                    let (mut lo, mut hi) = (0.0, 1.0);
                    for _ in 0..10 {
                        let mid = (lo + hi) / 2.0;
                        let probe = self.probe(&interpolate(&prev, &next, mid), &poses);
                        if self.hits(&before, &probe).is_empty() {
                            lo = mid;
                        } else {
                            hi = mid;
                        }
                    }
                    prev = interpolate(&prev, &next, lo);
                    outcome.collision = Some(what);
                    break;
                }
            }
        }
        self.tool.tcp = prev;
        self.update_held_pose();
        (self.tool, outcome)
    }

    /// Closes the fingers. An object is grasped only if it is really between them:
    /// - the fingers reach into it along the tool axis by at least [`GRASP_MIN_ENGAGEMENT_M`]
    ///   (or 30 % of its extent, if less) — i.e. the TCP is inside its vertical extent, not
    ///   above it;
    /// - its centre is within [`GRASP_CENTRE_TOLERANCE_M`] of the TCP, measured perpendicular
    ///   to the tool axis;
    /// - the closing axis is within [`GRASP_ANGLE_TOLERANCE_DEG`] of one of its sides that fits
    ///   in the current opening (for a box: across its short side, or across a longer side
    ///   that also fits; a cylinder at any angle), and that side is no wider than the opening.
    ///
    /// On success the object is held and the fingers stop on it (the opening becomes its
    /// width); the fingers square it up (turn it by up to 15° about the vertical so its side is
    /// across the jaw) and centre it between them. Otherwise the fingers close fully (opening
    /// 0) and the reason names the nearest object and what was wrong. Closing while already
    /// holding something keeps holding it.
    pub fn close_gripper(&mut self) -> GraspOutcome {
        if let Some(h) = self.held {
            let label = self
                .object(h.id)
                .map(|o| o.spec.label.clone())
                .unwrap_or_default();
            return GraspOutcome::Grasped { id: h.id, label };
        }
        let tcp = self.tool.tcp;
        let opening = self.tool.opening_m;
        let inv = tcp.inverse();
        let tool_axis = tcp.rotation * Vector3::x();
        let closing = tcp.rotation * Vector3::y();
        // (score, reason) of the best failure; (distance, index, width, gripped axis) of the best success.
        let mut failure: Option<(f64, String)> = None;
        let mut success: Option<(f64, usize, f64, Vector3<f64>)> = None;
        for (i, o) in self.objects.iter().enumerate() {
            let label = &o.spec.label;
            let c = inv * Point3::from(o.pose.translation.vector);
            let perp = c.y.hypot(c.z);
            if perp > 0.03 {
                continue;
            }
            let e = extent_along(&o.spec.shape, &o.pose.rotation, &tool_axis) / 2.0;
            let (lo, hi) = (c.x - e, c.x + e);
            let engaged = hi.min(0.0) - lo.max(-self.gripper.finger_length_m);
            let need = GRASP_MIN_ENGAGEMENT_M.min(0.3 * 2.0 * e);
            let mut fail = |score: f64, reason: String| {
                if failure.as_ref().is_none_or(|(s, _)| score < *s) {
                    failure = Some((score, reason));
                }
            };
            if engaged < need {
                let reason = if lo > 0.0 {
                    format!(
                        "the fingertips are {:.1} mm short of '{label}' (above its top)",
                        lo * 1000.0
                    )
                } else if hi < -self.gripper.finger_length_m {
                    format!("'{label}' is behind the fingers")
                } else {
                    format!(
                        "the fingers reach only {:.1} mm into '{label}' (at least {:.1} mm needed)",
                        engaged.max(0.0) * 1000.0,
                        need * 1000.0
                    )
                };
                fail(perp + (need - engaged), reason);
                continue;
            }
            if perp > GRASP_CENTRE_TOLERANCE_M {
                fail(
                    perp,
                    format!(
                        "'{label}' is not centred between the fingers: its centre is {:.1} mm \
                         from the tool centre (at most {:.1} mm)",
                        perp * 1000.0,
                        GRASP_CENTRE_TOLERANCE_M * 1000.0
                    ),
                );
                continue;
            }
            match grip_axis(
                &o.spec.shape,
                &o.pose.rotation,
                &tool_axis,
                &closing,
                opening,
            ) {
                Ok((width, axis)) => {
                    if success.as_ref().is_none_or(|(d, ..)| perp < *d) {
                        success = Some((perp, i, width, axis));
                    }
                }
                Err(GripError::TooWide(w)) => fail(
                    perp,
                    format!("'{label}' is {w:.3} m wide, wider than the {opening:.3} m opening"),
                ),
                Err(GripError::Angle(deg)) => fail(
                    perp,
                    format!(
                        "jaw not across the short side of '{label}' (off by {deg:.0}°, at most \
                         {GRASP_ANGLE_TOLERANCE_DEG:.0}°)"
                    ),
                ),
                Err(GripError::NoSide) => {
                    fail(perp, format!("no side of '{label}' lies across the jaw"))
                }
            }
        }
        let Some((_, i, width, axis)) = success else {
            self.tool.opening_m = 0.0;
            let reason = failure
                .map(|(_, r)| r)
                .unwrap_or_else(|| "no object between the fingers".to_owned());
            return GraspOutcome::Empty { reason };
        };
        // Square the object up and centre it between the fingers.
        let mut pose = self.objects[i].pose;
        if tool_axis.z < -(10f64.to_radians().cos()) && axis.z.abs() < 0.2 {
            let a = Vector2::new(axis.x, axis.y);
            let c = Vector2::new(closing.x, closing.y);
            if a.norm() > 1e-9 && c.norm() > 1e-9 {
                let mut turn = (a.x * c.y - a.y * c.x).atan2(a.dot(&c));
                if turn > FRAC_PI_2 {
                    turn -= PI;
                } else if turn < -FRAC_PI_2 {
                    turn += PI;
                }
                pose.rotation = UnitQuaternion::from_euler_angles(0.0, 0.0, turn) * pose.rotation;
            }
        }
        let off = (pose.translation.vector - tcp.translation.vector).dot(&closing);
        pose.translation.vector -= closing * off;
        let id = self.objects[i].id;
        self.objects[i].pose = pose;
        self.objects[i].held = true;
        self.held = Some(Held {
            id,
            rel: inv * pose,
            width_m: width,
        });
        self.tool.opening_m = width;
        GraspOutcome::Grasped {
            id,
            label: self.objects[i].spec.label.clone(),
        }
    }

    /// Opens the fingers to `opening_m` (clamped to the gripper's range; non-finite = fully
    /// open). Fingers that meet an object on the way stall against it, as a real gripper's do:
    /// the opening stops at the contact. A held object is released if the fingers open beyond
    /// its width: it drops
    /// straight down from where it is, upright, keeping its yaw, onto whatever is below its
    /// footprint — the table, the top of another object (stacking), or the floor of an open
    /// container it fits into (inside; else it rests on the rim). Returns the released
    /// object's id. Asking for less than the held object's width keeps holding it.
    pub fn open_gripper(&mut self, opening_m: f64) -> Option<u32> {
        let max = self.gripper.max_opening_m;
        let wanted = if opening_m.is_finite() {
            opening_m.clamp(0.0, max)
        } else {
            max
        };
        let opening = self.free_opening(wanted);
        let Some(held) = self.held else {
            self.tool.opening_m = opening;
            return None;
        };
        if opening < held.width_m - 1e-9 {
            return None;
        }
        self.tool.opening_m = opening;
        self.held = None;
        let i = self.index_of(held.id)?;
        let carried = self.tool.tcp * held.rel;
        let spec = &self.objects[i].spec;
        let bottom = object_hulls(spec, &carried)
            .iter()
            .map(Hull::min_z)
            .fold(f64::INFINITY, f64::min);
        let yaw = upright_yaw(&carried.rotation);
        let mut pose = Isometry3::from_parts(
            Translation3::new(carried.translation.x, carried.translation.y, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
        );
        let poses = self.poses();
        let rest = self.rest_height(i, &pose, bottom, &poses);
        pose.translation.z = rest + spec.shape.height_m() / 2.0;
        self.objects[i].pose = pose;
        self.objects[i].held = false;
        Some(held.id)
    }

    // ---- internals ----

    /// The widest opening up to `wanted` the fingers reach from the current one before a
    /// finger presses into an object (found to ~0.01 mm). Closing further is never blocked
    /// here: closing goes through [`close_gripper`](Self::close_gripper).
    fn free_opening(&mut self, wanted: f64) -> f64 {
        let current = self.tool.opening_m;
        if wanted <= current {
            return wanted;
        }
        let tcp = self.tool.tcp;
        let poses = self.poses();
        let before = self.probe(&tcp, &poses);
        // Touching is the limit (not the contact tolerance), so the arm can leave afterwards.
        let free = |world: &mut World, opening: f64| {
            world.tool.opening_m = opening;
            let after = world.probe(&tcp, &poses);
            after
                .grip
                .iter()
                .zip(&before.grip)
                .all(|(a, b)| *a <= b + 1e-6)
        };
        let reached = if free(self, wanted) {
            wanted
        } else {
            let (mut lo, mut hi) = (current, wanted);
            for _ in 0..12 {
                let mid = (lo + hi) / 2.0;
                if free(self, mid) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            lo
        };
        self.tool.opening_m = current;
        reached
    }

    fn index_of(&self, id: u32) -> Option<usize> {
        self.objects.iter().position(|o| o.id == id)
    }

    fn held_index(&self) -> Option<usize> {
        self.held.and_then(|h| self.index_of(h.id))
    }

    fn poses(&self) -> Vec<Isometry3<f64>> {
        self.objects.iter().map(|o| o.pose).collect()
    }

    fn update_held_pose(&mut self) {
        if let Some(h) = self.held {
            let pose = self.tool.tcp * h.rel;
            if let Some(i) = self.index_of(h.id) {
                self.objects[i].pose = pose;
            }
        }
    }

    fn gripper_hulls(&self, tcp: &Isometry3<f64>) -> Vec<Hull> {
        self.gripper
            .boxes(tcp, self.tool.opening_m)
            .iter()
            .map(|b| Hull::cuboid(&b.pose, &b.half_extents_m))
            .collect()
    }

    /// Penetrations of the gripper and the carried object at `tcp`, objects at `poses`.
    fn probe(&self, tcp: &Isometry3<f64>, poses: &[Isometry3<f64>]) -> Probe {
        let grip = self.gripper_hulls(tcp);
        let table = grip.iter().map(Hull::min_z).fold(f64::INFINITY, f64::min);
        let held_index = self.held_index();
        let carried = match (self.held, held_index) {
            (Some(h), Some(i)) => object_hulls(&self.objects[i].spec, &(tcp * h.rel)),
            _ => Vec::new(),
        };
        let held_table = carried
            .iter()
            .map(Hull::min_z)
            .fold(f64::INFINITY, f64::min);
        let mut probe = Probe {
            table: (-table).max(0.0),
            held_table: (-held_table).max(0.0),
            grip: vec![0.0; self.objects.len()],
            held: vec![0.0; self.objects.len()],
        };
        for (i, (o, pose)) in self.objects.iter().zip(poses).enumerate() {
            if Some(i) == held_index {
                continue;
            }
            let hulls = object_hulls(&o.spec, pose);
            probe.grip[i] = max_penetration(&grip, &hulls).max(0.0);
            if !carried.is_empty() {
                probe.held[i] = max_penetration(&carried, &hulls).max(0.0);
            }
        }
        probe
    }

    /// Contacts that are new or deeper in `after` than in `before` (by more than
    /// [`DEEPER_M`]: an arm leaving a contact along a joint-space path wobbles by microns).
    fn hits(&self, before: &Probe, after: &Probe) -> Vec<Hit> {
        let deeper = |a: f64, b: f64, tol: f64| a > tol && a > b + DEEPER_M;
        let mut out = Vec::new();
        if deeper(after.table, before.table, CONTACT_TOLERANCE_M)
            || deeper(after.held_table, before.held_table, HELD_TOLERANCE_M)
        {
            out.push(Hit::Table);
        }
        for i in 0..after.grip.len().min(before.grip.len()) {
            if deeper(after.held[i], before.held[i], HELD_TOLERANCE_M) {
                out.push(Hit::Held(i));
            }
            if deeper(after.grip[i], before.grip[i], CONTACT_TOLERANCE_M) {
                out.push(Hit::Grip(i));
            }
        }
        out
    }

    fn step(
        &self,
        prev: &Isometry3<f64>,
        next: &Isometry3<f64>,
        before: &Probe,
        poses: &[Isometry3<f64>],
    ) -> Step {
        let after = self.probe(next, poses);
        let hits = self.hits(before, &after);
        if hits.is_empty() {
            return Step::Free(after);
        }
        let d = next.translation.vector - prev.translation.vector;
        let horizontal = Vector3::new(d.x, d.y, 0.0);
        let run = horizontal.norm();
        let can_push = self.held.is_none() && run > 1e-9 && d.z.abs() <= PUSH_MAX_SLOPE * run;
        let closing = next.rotation * Vector3::y();
        let mut pushed = Vec::new();
        for hit in &hits {
            match *hit {
                Hit::Table => return Step::Blocked("table".to_owned()),
                Hit::Held(i) => return Step::Blocked(self.objects[i].spec.label.clone()),
                Hit::Grip(i) => {
                    let o = &self.objects[i];
                    let across = extent_along(&o.spec.shape, &poses[i].rotation, &closing);
                    if !can_push || self.tool.opening_m >= across {
                        return Step::Blocked(o.spec.label.clone());
                    }
                    pushed.push(i);
                }
            }
        }
        let dir = horizontal / run;
        match self.push(next, &pushed, &dir, run, poses) {
            Ok((new_poses, moved)) => {
                let after = self.probe(next, &new_poses);
                match self.hits(before, &after).first() {
                    None => Step::Pushed(new_poses, moved, after),
                    Some(Hit::Table) => Step::Blocked("table".to_owned()),
                    Some(Hit::Grip(i) | Hit::Held(i)) => {
                        Step::Blocked(self.objects[*i].spec.label.clone())
                    }
                }
            }
            Err(label) => Step::Blocked(label),
        }
    }

    /// Shoves the objects `first` out of the gripper at `tcp` along `dir`, and whatever they
    /// run into, then lets everything settle. Returns the new poses and the moved indices, or
    /// the label of an object that could not be moved out of the way.
    fn push(
        &self,
        tcp: &Isometry3<f64>,
        first: &[usize],
        dir: &Vector3<f64>,
        run: f64,
        poses: &[Isometry3<f64>],
    ) -> Result<(Vec<Isometry3<f64>>, Vec<usize>), String> {
        let n = self.objects.len();
        let held_index = self.held_index();
        let grip = self.gripper_hulls(tcp);
        let mut poses = poses.to_vec();
        let riders = self.riders(&poses);
        let cap = run + PUSH_SLACK_M;
        let mut moved = vec![false; n];
        let mut queue = VecDeque::new();
        let label = |i: usize| self.objects[i].spec.label.clone();
        for &i in first {
            let hulls = object_hulls(&self.objects[i].spec, &poses[i]);
            let t = shove_distance(&grip, &hulls, dir);
            if t.is_nan() || t > cap {
                return Err(label(i));
            }
            if t > 0.0 {
                for j in shift(&mut poses, &riders, i, None, dir * (t + 1e-6)) {
                    moved[j] = true;
                    queue.push_back(j);
                }
            }
        }
        let mut budget = 64 * n.max(1);
        while let Some(m) = queue.pop_front() {
            budget -= 1;
            if budget == 0 {
                return Err(label(m));
            }
            let hm = object_hulls(&self.objects[m].spec, &poses[m]);
            for k in 0..n {
                if k == m || Some(k) == held_index {
                    continue;
                }
                let hk = object_hulls(&self.objects[k].spec, &poses[k]);
                if max_penetration(&hm, &hk) <= CONTACT_TOLERANCE_M {
                    continue;
                }
                let t = shove_distance(&hm, &hk, dir);
                if t.is_nan() || t > cap {
                    return Err(label(k));
                }
                for j in shift(&mut poses, &riders, k, Some(m), dir * (t + 1e-6)) {
                    moved[j] = true;
                    queue.push_back(j);
                }
            }
        }
        self.settle(&mut poses);
        let moved = (0..n).filter(|&i| moved[i]).collect();
        Ok((poses, moved))
    }

    /// For each object, the objects standing directly on it or inside it.
    fn riders(&self, poses: &[Isometry3<f64>]) -> Vec<Vec<usize>> {
        let held_index = self.held_index();
        let n = self.objects.len();
        let mut out = vec![Vec::new(); n];
        for (j, a) in self.objects.iter().enumerate() {
            if Some(j) == held_index {
                continue;
            }
            let fp = footprint_at(&a.spec, &poses[j]);
            let bottom = poses[j].translation.z - a.spec.shape.height_m() / 2.0;
            if bottom < 0.0005 {
                continue;
            }
            for (i, b) in self.objects.iter().enumerate() {
                if i == j || Some(i) == held_index {
                    continue;
                }
                if let Some(s) = support_height(&b.spec, &poses[i], &fp) {
                    if (s - bottom).abs() <= 0.001 {
                        out[i].push(j);
                    }
                }
            }
        }
        out
    }

    /// Height of what object `i` (footprint from `pose`, base at `bottom`) comes to rest on
    /// when it drops straight down: the table or the highest support below it.
    fn rest_height(
        &self,
        i: usize,
        pose: &Isometry3<f64>,
        bottom: f64,
        poses: &[Isometry3<f64>],
    ) -> f64 {
        let fp = footprint_at(&self.objects[i].spec, pose);
        let held_index = self.held_index();
        let mut rest: f64 = 0.0;
        for (k, o) in self.objects.iter().enumerate() {
            if k == i || Some(k) == held_index {
                continue;
            }
            if let Some(s) = support_height(&o.spec, &poses[k], &fp) {
                if s <= bottom + DROP_TOLERANCE_M {
                    rest = rest.max(s);
                }
            }
        }
        rest
    }

    /// Lets unsupported objects drop, lowest first.
    fn settle(&self, poses: &mut [Isometry3<f64>]) {
        let held_index = self.held_index();
        let half = |i: usize| self.objects[i].spec.shape.height_m() / 2.0;
        let mut order: Vec<usize> = (0..self.objects.len())
            .filter(|&i| Some(i) != held_index)
            .collect();
        order.sort_by(|&a, &b| {
            let za = poses[a].translation.z - half(a);
            let zb = poses[b].translation.z - half(b);
            za.total_cmp(&zb)
        });
        for i in order {
            let bottom = poses[i].translation.z - half(i);
            let pose = poses[i];
            let rest = self.rest_height(i, &pose, bottom, poses);
            if rest < bottom - 1e-5 {
                poses[i].translation.z = rest + half(i);
            }
        }
    }
}

/// Moves object `i` and (recursively) what rides on it, except `except`, by `v`; returns the
/// moved indices.
fn shift(
    poses: &mut [Isometry3<f64>],
    riders: &[Vec<usize>],
    i: usize,
    except: Option<usize>,
    v: Vector3<f64>,
) -> Vec<usize> {
    let mut done = vec![false; poses.len()];
    let mut stack = vec![i];
    let mut out = Vec::new();
    while let Some(j) = stack.pop() {
        if done[j] || Some(j) == except {
            continue;
        }
        done[j] = true;
        poses[j].translation.vector += v;
        out.push(j);
        stack.extend(riders[j].iter().copied());
    }
    out
}

/// How far `moving` (several hulls, rigidly joined) must go along `dir` to clear `fixed`.
fn shove_distance(fixed: &[Hull], moving: &[Hull], dir: &Vector3<f64>) -> f64 {
    let mut t: f64 = 0.0;
    for f in fixed {
        for m in moving {
            if penetration(f, m) > 0.0 {
                t = t.max(push_out(f, m, dir));
            }
        }
    }
    t
}

/// The deepest penetration between any hull of `a` and any of `b` (≤ 0: apart).
fn max_penetration(a: &[Hull], b: &[Hull]) -> f64 {
    let mut depth = f64::NEG_INFINITY;
    for x in a {
        for y in b {
            depth = depth.max(penetration(x, y));
        }
    }
    depth
}

/// Pose of an object standing on the table as its spec says.
fn standing_pose(spec: &ObjectSpec) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(spec.x_m, spec.y_m, spec.shape.height_m() / 2.0),
        UnitQuaternion::from_euler_angles(0.0, 0.0, spec.yaw_rad),
    )
}

/// The solid parts of an object at `pose`: one hull, or floor and four walls of a container.
fn object_hulls(spec: &ObjectSpec, pose: &Isometry3<f64>) -> Vec<Hull> {
    match spec.shape {
        ObjectShape::Box {
            length_x_m: l,
            width_y_m: w,
            height_z_m: h,
        } => {
            if !spec.container {
                return vec![Hull::cuboid(pose, &Vector3::new(l / 2.0, w / 2.0, h / 2.0))];
            }
            let t = CONTAINER_WALL_M;
            let part = |x: f64, y: f64, z: f64, half: Vector3<f64>| {
                Hull::cuboid(
                    &(pose * Isometry3::from_parts(Translation3::new(x, y, z), Default::default())),
                    &half,
                )
            };
            let wall_h = (h - t) / 2.0;
            vec![
                part(
                    0.0,
                    0.0,
                    -h / 2.0 + t / 2.0,
                    Vector3::new(l / 2.0, w / 2.0, t / 2.0),
                ),
                part(
                    l / 2.0 - t / 2.0,
                    0.0,
                    t / 2.0,
                    Vector3::new(t / 2.0, w / 2.0, wall_h),
                ),
                part(
                    -l / 2.0 + t / 2.0,
                    0.0,
                    t / 2.0,
                    Vector3::new(t / 2.0, w / 2.0, wall_h),
                ),
                part(
                    0.0,
                    w / 2.0 - t / 2.0,
                    t / 2.0,
                    Vector3::new(l / 2.0 - t, t / 2.0, wall_h),
                ),
                part(
                    0.0,
                    -w / 2.0 + t / 2.0,
                    t / 2.0,
                    Vector3::new(l / 2.0 - t, t / 2.0, wall_h),
                ),
            ]
        }
        ObjectShape::Cylinder {
            diameter_m,
            height_m,
        } => vec![Hull::prism(pose, diameter_m / 2.0, height_m / 2.0)],
    }
}

/// Footprint of an (upright) object at `pose`.
fn footprint_at(spec: &ObjectSpec, pose: &Isometry3<f64>) -> Footprint {
    footprint_of(
        &spec.shape,
        Vector2::new(pose.translation.x, pose.translation.y),
        upright_yaw(&pose.rotation),
    )
}

/// The height at which something with footprint `fp` rests on object `spec` at `pose`: its
/// top, or its floor if it is a container and `fp` fits inside; `None` when the footprints do
/// not overlap.
fn support_height(spec: &ObjectSpec, pose: &Isometry3<f64>, fp: &Footprint) -> Option<f64> {
    let own = footprint_at(spec, pose);
    if footprint_overlap(&own, fp) <= SUPPORT_OVERLAP_M {
        return None;
    }
    let h = spec.shape.height_m();
    let bottom = pose.translation.z - h / 2.0;
    if let (
        true,
        ObjectShape::Box {
            length_x_m,
            width_y_m,
            ..
        },
    ) = (spec.container, spec.shape)
    {
        let inner = Vector2::new(
            length_x_m / 2.0 - CONTAINER_WALL_M,
            width_y_m / 2.0 - CONTAINER_WALL_M,
        );
        let c = Vector2::new(pose.translation.x, pose.translation.y);
        if footprint_inside_rect(fp, &c, &inner, upright_yaw(&pose.rotation), 0.0005) {
            return Some(bottom + CONTAINER_WALL_M);
        }
    }
    Some(bottom + h)
}

/// Extent of an object of `shape` rotated by `rot` along the unit direction `u`.
fn extent_along(shape: &ObjectShape, rot: &UnitQuaternion<f64>, u: &Vector3<f64>) -> f64 {
    let local = rot.inverse() * u;
    match *shape {
        ObjectShape::Box {
            length_x_m,
            width_y_m,
            height_z_m,
        } => local.x.abs() * length_x_m + local.y.abs() * width_y_m + local.z.abs() * height_z_m,
        ObjectShape::Cylinder {
            diameter_m,
            height_m,
        } => diameter_m * (1.0 - local.z * local.z).max(0.0).sqrt() + height_m * local.z.abs(),
    }
}

enum GripError {
    TooWide(f64),
    Angle(f64),
    NoSide,
}

/// The side of the object the jaw closes across: its width and world direction.
fn grip_axis(
    shape: &ObjectShape,
    rot: &UnitQuaternion<f64>,
    tool_axis: &Vector3<f64>,
    closing: &Vector3<f64>,
    opening: f64,
) -> Result<(f64, Vector3<f64>), GripError> {
    let fit = opening + 0.0005;
    // (width, world direction, angle to the closing axis in degrees)
    let mut sides: Vec<(f64, Vector3<f64>, f64)> = Vec::new();
    let angle = |a: &Vector3<f64>| a.dot(closing).abs().min(1.0).acos().to_degrees();
    let z = rot * Vector3::z();
    match *shape {
        ObjectShape::Box {
            length_x_m,
            width_y_m,
            height_z_m,
        } => {
            for (w, a) in [
                (length_x_m, rot * Vector3::x()),
                (width_y_m, rot * Vector3::y()),
                (height_z_m, z),
            ] {
                sides.push((w, a, angle(&a)));
            }
        }
        ObjectShape::Cylinder {
            diameter_m,
            height_m,
        } => {
            // Radial: the closing axis projected onto the cylinder's cross-section.
            let radial = closing - z * closing.dot(&z);
            if radial.norm() > 1e-9 {
                let r = radial.normalize();
                sides.push((diameter_m, r, angle(&r)));
            }
            sides.push((height_m, z, angle(&z)));
        }
    }
    // A side along the tool axis cannot be gripped across.
    sides.retain(|(_, a, _)| a.dot(tool_axis).abs() < 0.7);
    let nearest = sides
        .iter()
        .min_by(|a, b| a.2.total_cmp(&b.2))
        .copied()
        .ok_or(GripError::NoSide)?;
    let fitting = sides
        .iter()
        .filter(|s| s.0 <= fit)
        .min_by(|a, b| a.2.total_cmp(&b.2))
        .copied();
    match fitting {
        None => Err(GripError::TooWide(nearest.0)),
        Some((w, a, deg)) if deg <= GRASP_ANGLE_TOLERANCE_DEG => Ok((w, a)),
        Some((_, _, deg)) => Err(GripError::Angle(deg)),
    }
}

/// Yaw of an upright-ish rotation: the heading of its x axis (of its y axis − 90° when x is
/// nearly vertical), in (−π, π].
fn upright_yaw(rot: &UnitQuaternion<f64>) -> f64 {
    let x = rot * Vector3::x();
    if x.z.abs() < 0.9 {
        x.y.atan2(x.x)
    } else {
        let y = rot * Vector3::y();
        let yaw = y.y.atan2(y.x) - FRAC_PI_2;
        if yaw <= -PI {
            yaw + 2.0 * PI
        } else {
            yaw
        }
    }
}

fn isometry_finite(p: &Isometry3<f64>) -> bool {
    p.translation.vector.iter().all(|v| v.is_finite())
        && p.rotation.coords.iter().all(|v| v.is_finite())
}

/// Straight-line position and shortest-path rotation between `a` and `b` at `t` ∈ [0, 1].
fn interpolate(a: &Isometry3<f64>, b: &Isometry3<f64>, t: f64) -> Isometry3<f64> {
    let position = a.translation.vector.lerp(&b.translation.vector, t);
    let delta = a.rotation.inverse() * b.rotation;
    let rotation = match delta.axis_angle() {
        Some((axis, angle)) => a.rotation * UnitQuaternion::from_axis_angle(&axis, angle * t),
        None => a.rotation,
    };
    Isometry3::from_parts(Translation3::from(position), rotation)
}
