//! The world: objects on the table, the gripper moving among them, grasping, releasing and
//! pushing.
//!
//! [`World`] is the whole simulated tabletop. Its state lives here — the scene's workspaces,
//! the objects with their true poses, the tool (TCP pose and opening), the gripper's sizes and
//! what it holds — together with the calls that set it up and read it. What the world *does*
//! is split by job into child modules, each adding an `impl World` block (they see `World`'s
//! private fields):
//!
//! - [`motion`]: [`World::move_tool`] — a motion cut into ≤ 1 mm sub-steps, each one free,
//!   pushing or blocked;
//! - [`contact`]: what the gripper (and what it carries) touches at one tool pose, and which
//!   contacts count as a collision;
//! - [`push`]: shoving objects out of the gripper's way (and whatever they run into), and
//!   letting what lost its support drop;
//! - [`grasp`]: [`World::close_gripper`] and [`World::open_gripper`] — when an object counts
//!   as grasped, and where a released one lands;
//! - [`shapes`]: an object's solid parts, footprint and support height at a pose, and small
//!   pose helpers.
//!
//! The public types and constants of these modules are re-exported here (and from here by the
//! crate root), so `crate::world::X` names each of them.

mod contact;
mod grasp;
mod motion;
mod push;
mod shapes;

pub use contact::{Contact, CONTACT_TOLERANCE_M, HELD_TOLERANCE_M};
pub use grasp::{
    GraspOutcome, GRASP_ANGLE_TOLERANCE_DEG, GRASP_CENTRE_TOLERANCE_M, GRASP_MIN_ENGAGEMENT_M,
};
pub use motion::{StepOutcome, SUB_STEP_M};

use crate::geom::Hull;
use crate::gripper::{GripperBox, GripperBoxes, GripperGeometry};
use crate::scene::{
    markers_of, sheet_rects, Marker, ObjectSpec, Scene, SceneError, WorkspaceSpec, MARKER_RADIUS_M,
    OVERLAP_TOLERANCE_M, SHEET_MARGIN_M, SHEET_Z_M,
};
use contact::max_penetration;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion};
use robotd_protocol::geometry::RobotModel;
use shapes::{isometry_finite, object_hulls, standing_pose, upright_yaw};
use std::f64::consts::FRAC_PI_2;

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

/// The object the gripper holds, and how it sits in the jaw.
#[derive(Debug, Clone, Copy)]
struct Held {
    id: u32,
    /// Object pose in the TCP frame.
    rel: Isometry3<f64>,
    /// The object's width between the fingers.
    width_m: f64,
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

    // ---- internals shared by the child modules ----

    pub(super) fn index_of(&self, id: u32) -> Option<usize> {
        self.objects.iter().position(|o| o.id == id)
    }

    pub(super) fn held_index(&self) -> Option<usize> {
        self.held.and_then(|h| self.index_of(h.id))
    }

    pub(super) fn poses(&self) -> Vec<Isometry3<f64>> {
        self.objects.iter().map(|o| o.pose).collect()
    }

    pub(super) fn update_held_pose(&mut self) {
        if let Some(h) = self.held {
            let pose = self.tool.tcp * h.rel;
            if let Some(i) = self.index_of(h.id) {
                self.objects[i].pose = pose;
            }
        }
    }

    pub(super) fn gripper_hulls(&self, tcp: &Isometry3<f64>) -> Vec<Hull> {
        self.gripper
            .boxes(tcp, self.tool.opening_m)
            .iter()
            .map(|b| Hull::cuboid(&b.pose, &b.half_extents_m))
            .collect()
    }
}
