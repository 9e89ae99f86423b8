//! Scene descriptions: which robot, which workspace sheets, which objects where.
//!
//! A scene is a TOML file (see `config/scenes/*.toml`, every key commented there). Parsing is
//! strict: unknown keys are refused, every number must be finite and in range, and the
//! messages name the file, the line, the object and the key, so a person can fix the file.
//! Physical checks that need the arm's kinematics (reach) are done by [`Scene::validate`].

use crate::geom::{footprint_overlap, Footprint};
use nalgebra::Vector2;
use robotd_protocol::geometry::RobotModel;
pub use robotd_protocol::workspace::WorkspaceSpec;
use serde::de::{self, Deserializer, SeqAccess, Visitor};
use serde::Deserialize;
use std::fmt;
use std::path::Path;
use toml::Spanned;

/// A colour, 8-bit sRGB `[r, g, b]`.
pub type Rgb = [u8; 3];

/// Colour names a scene file may use instead of `[r, g, b]`, with their values.
///
/// The values are saturated enough for a colour-based detector to tell them apart on a white
/// sheet and a brown table.
pub const COLOURS: &[(&str, Rgb)] = &[
    ("red", [200, 30, 30]),
    ("green", [40, 160, 60]),
    ("blue", [40, 80, 200]),
    ("yellow", [235, 200, 40]),
    ("orange", [240, 130, 30]),
    ("purple", [130, 60, 170]),
    ("pink", [240, 130, 180]),
    ("brown", [130, 85, 50]),
    ("cyan", [40, 190, 200]),
    ("magenta", [200, 40, 170]),
    ("black", [30, 30, 30]),
    ("white", [245, 245, 245]),
    ("grey", [128, 128, 128]),
    ("gray", [128, 128, 128]),
];

/// The value of a colour name of [`COLOURS`] (case-insensitive, surrounding spaces ignored).
pub fn colour_by_name(name: &str) -> Option<Rgb> {
    let name = name.trim();
    COLOURS
        .iter()
        .find(|(n, _)| n.eq_ignore_ascii_case(name))
        .map(|(_, rgb)| *rgb)
}

/// Wall and floor thickness of an open-top container, metres.
pub const CONTAINER_WALL_M: f64 = 0.003;

/// Smallest accepted object dimension, metres.
pub const MIN_SIZE_M: f64 = 0.001;
/// Largest accepted object dimension, metres.
pub const MAX_SIZE_M: f64 = 1.0;
/// Largest accepted |x| or |y| of an object or workspace corner, metres.
pub const MAX_COORD_M: f64 = 2.0;

/// The solid shape of an object. Objects always stand upright on their base.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ObjectShape {
    /// A cuboid; `length_x_m` along the object's own x axis (the world x axis at yaw 0),
    /// `width_y_m` along its y axis, `height_z_m` vertical.
    Box {
        /// Extent along the object's x axis, metres.
        length_x_m: f64,
        /// Extent along the object's y axis, metres.
        width_y_m: f64,
        /// Vertical extent, metres.
        height_z_m: f64,
    },
    /// An upright cylinder.
    Cylinder {
        /// Diameter, metres.
        diameter_m: f64,
        /// Vertical extent, metres.
        height_m: f64,
    },
}

impl ObjectShape {
    /// Vertical extent, metres.
    pub fn height_m(&self) -> f64 {
        match *self {
            Self::Box { height_z_m, .. } => height_z_m,
            Self::Cylinder { height_m, .. } => height_m,
        }
    }

    /// Extents along the object's own x, y and z axes, metres (a cylinder: diameter, diameter,
    /// height).
    pub fn extents_m(&self) -> [f64; 3] {
        match *self {
            Self::Box {
                length_x_m,
                width_y_m,
                height_z_m,
            } => [length_x_m, width_y_m, height_z_m],
            Self::Cylinder {
                diameter_m,
                height_m,
            } => [diameter_m, diameter_m, height_m],
        }
    }

    /// `"box"` or `"cylinder"`.
    pub fn kind(&self) -> &'static str {
        match self {
            Self::Box { .. } => "box",
            Self::Cylinder { .. } => "cylinder",
        }
    }
}

/// One object of a scene: what it is and where it stands on the table.
///
/// In a scene file (`[[objects]]`):
///
/// ```toml
/// [[objects]]
/// label = "red cube"          # what a detector should call it (non-empty)
/// shape = "box"               # "box" or "cylinder"
/// length_x_m = 0.030          # box: extent along its own x axis (= world x at yaw 0)
/// width_y_m = 0.030           # box: extent along its own y axis
/// height_z_m = 0.030          # box: height
/// # diameter_m = 0.030        # cylinder: diameter
/// # height_m = 0.040          # cylinder: height
/// color = "red"               # a colour name (see COLOURS) or [r, g, b]
/// x_m = 0.28                  # centre, metres, robot base frame
/// y_m = 0.04
/// yaw_deg = 0.0               # optional: rotation about z (or yaw_rad); default 0
/// container = false           # optional: an open-top box things can be dropped into
/// ```
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(try_from = "RawObject")]
pub struct ObjectSpec {
    /// What the object is called ("red cube").
    pub label: String,
    /// Its solid shape and size.
    pub shape: ObjectShape,
    /// Its colour.
    pub color: Rgb,
    /// Centre x (forward), metres.
    pub x_m: f64,
    /// Centre y (left), metres.
    pub y_m: f64,
    /// Rotation about the vertical axis, radians (0 = own x axis along world x).
    pub yaw_rad: f64,
    /// An open-top container (box only, walls and floor [`CONTAINER_WALL_M`] thick): objects
    /// released above its opening fall inside, onto its floor.
    pub container: bool,
}

impl ObjectSpec {
    /// A non-container object with yaw 0.
    pub fn new(label: &str, shape: ObjectShape, color: Rgb, x_m: f64, y_m: f64) -> Self {
        Self {
            label: label.to_owned(),
            shape,
            color,
            x_m,
            y_m,
            yaw_rad: 0.0,
            container: false,
        }
    }

    /// This spec with `yaw_rad` set.
    pub fn with_yaw(mut self, yaw_rad: f64) -> Self {
        self.yaw_rad = yaw_rad;
        self
    }

    /// This spec marked as an open-top container.
    pub fn as_container(mut self) -> Self {
        self.container = true;
        self
    }

    /// Every problem with the values (empty label, non-finite or out-of-range numbers, a
    /// container that is not a box or too small to hold anything); empty when all is well.
    pub fn problems(&self) -> Vec<String> {
        let mut out = Vec::new();
        if self.label.trim().is_empty() {
            out.push("label must not be empty".to_owned());
        }
        let sizes: Vec<(&str, f64)> = match self.shape {
            ObjectShape::Box {
                length_x_m,
                width_y_m,
                height_z_m,
            } => vec![
                ("length_x_m", length_x_m),
                ("width_y_m", width_y_m),
                ("height_z_m", height_z_m),
            ],
            ObjectShape::Cylinder {
                diameter_m,
                height_m,
            } => vec![("diameter_m", diameter_m), ("height_m", height_m)],
        };
        for (key, v) in sizes {
            if !v.is_finite() || !(MIN_SIZE_M..=MAX_SIZE_M).contains(&v) {
                out.push(format!(
                    "{key} must be a size between {MIN_SIZE_M} and {MAX_SIZE_M} m, got {v}"
                ));
            }
        }
        for (key, v) in [("x_m", self.x_m), ("y_m", self.y_m)] {
            if !v.is_finite() || v.abs() > MAX_COORD_M {
                out.push(format!(
                    "{key} must be a finite coordinate within ±{MAX_COORD_M} m, got {v}"
                ));
            }
        }
        if !self.yaw_rad.is_finite() {
            out.push(format!("yaw must be finite, got {}", self.yaw_rad));
        }
        if self.container {
            match self.shape {
                ObjectShape::Box {
                    length_x_m,
                    width_y_m,
                    height_z_m,
                } => {
                    let min = 2.0 * CONTAINER_WALL_M + 0.005;
                    if length_x_m < min || width_y_m < min || height_z_m < CONTAINER_WALL_M + 0.005
                    {
                        out.push(format!(
                            "a container must be at least {min:.3} m long and wide and {:.3} m high \
                             (walls and floor are {CONTAINER_WALL_M} m thick)",
                            CONTAINER_WALL_M + 0.005
                        ));
                    }
                }
                ObjectShape::Cylinder { .. } => {
                    out.push("only a box can be a container (shape = \"box\")".to_owned())
                }
            }
        }
        out
    }

    /// The object's footprint on the table.
    pub(crate) fn footprint(&self) -> Footprint {
        footprint_of(&self.shape, Vector2::new(self.x_m, self.y_m), self.yaw_rad)
    }
}

/// The footprint of `shape` centred at `c`, rotated by `yaw`.
pub(crate) fn footprint_of(shape: &ObjectShape, c: Vector2<f64>, yaw: f64) -> Footprint {
    match *shape {
        ObjectShape::Box {
            length_x_m,
            width_y_m,
            ..
        } => Footprint::Rect {
            c,
            half: Vector2::new(length_x_m / 2.0, width_y_m / 2.0),
            yaw,
        },
        ObjectShape::Cylinder { diameter_m, .. } => Footprint::Circle {
            c,
            r: diameter_m / 2.0,
        },
    }
}

/// The object table as written in a scene file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawObject {
    label: String,
    shape: RawShapeKind,
    #[serde(default)]
    length_x_m: Option<f64>,
    #[serde(default)]
    width_y_m: Option<f64>,
    #[serde(default)]
    height_z_m: Option<f64>,
    #[serde(default)]
    diameter_m: Option<f64>,
    #[serde(default)]
    height_m: Option<f64>,
    color: Colour,
    x_m: f64,
    y_m: f64,
    #[serde(default)]
    yaw_rad: Option<f64>,
    #[serde(default)]
    yaw_deg: Option<f64>,
    #[serde(default)]
    container: bool,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(rename_all = "lowercase")]
enum RawShapeKind {
    Box,
    Cylinder,
}

impl RawObject {
    /// The spec, or every structural problem (missing / misplaced size keys, both yaws).
    fn convert(self) -> Result<ObjectSpec, Vec<String>> {
        let mut problems = Vec::new();
        let mut need = |key: &str, v: Option<f64>, kind: &str| -> f64 {
            v.unwrap_or_else(|| {
                problems.push(format!("a {kind} needs `{key}`"));
                f64::NAN
            })
        };
        let shape = match self.shape {
            RawShapeKind::Box => ObjectShape::Box {
                length_x_m: need("length_x_m", self.length_x_m, "box"),
                width_y_m: need("width_y_m", self.width_y_m, "box"),
                height_z_m: need("height_z_m", self.height_z_m, "box"),
            },
            RawShapeKind::Cylinder => ObjectShape::Cylinder {
                diameter_m: need("diameter_m", self.diameter_m, "cylinder"),
                height_m: need("height_m", self.height_m, "cylinder"),
            },
        };
        let foreign: &[(&str, Option<f64>)] = match self.shape {
            RawShapeKind::Box => &[("diameter_m", self.diameter_m), ("height_m", self.height_m)],
            RawShapeKind::Cylinder => &[
                ("length_x_m", self.length_x_m),
                ("width_y_m", self.width_y_m),
                ("height_z_m", self.height_z_m),
            ],
        };
        for (key, v) in foreign {
            if v.is_some() {
                problems.push(format!(
                    "`{key}` does not apply to shape \"{}\"",
                    shape.kind()
                ));
            }
        }
        let yaw_rad = match (self.yaw_rad, self.yaw_deg) {
            (Some(_), Some(_)) => {
                problems.push("give `yaw_rad` or `yaw_deg`, not both".to_owned());
                0.0
            }
            (Some(r), None) => r,
            (None, Some(d)) => d.to_radians(),
            (None, None) => 0.0,
        };
        if !problems.is_empty() {
            return Err(problems);
        }
        Ok(ObjectSpec {
            label: self.label,
            shape,
            color: self.color.0,
            x_m: self.x_m,
            y_m: self.y_m,
            yaw_rad,
            container: self.container,
        })
    }
}

impl TryFrom<RawObject> for ObjectSpec {
    type Error = String;

    fn try_from(raw: RawObject) -> Result<Self, Self::Error> {
        let label = raw.label.clone();
        let spec = raw
            .convert()
            .map_err(|p| format!("object '{label}': {}", p.join("; ")))?;
        let problems = spec.problems();
        if problems.is_empty() {
            Ok(spec)
        } else {
            Err(format!("object '{label}': {}", problems.join("; ")))
        }
    }
}

/// A colour as written in a file: a name or `[r, g, b]`.
#[derive(Debug, Clone, Copy)]
struct Colour(Rgb);

impl<'de> Deserialize<'de> for Colour {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Colour;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a colour name or [r, g, b] with 0 … 255 each")
            }
            fn visit_str<E: de::Error>(self, s: &str) -> Result<Colour, E> {
                colour_by_name(s).map(Colour).ok_or_else(|| {
                    let names: Vec<&str> = COLOURS.iter().map(|(n, _)| *n).collect();
                    E::custom(format!(
                        "unknown colour '{s}'; known: {} (or [r, g, b])",
                        names.join(", ")
                    ))
                })
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Colour, A::Error> {
                let mut rgb = [0u8; 3];
                for (i, c) in rgb.iter_mut().enumerate() {
                    let v: i64 = seq
                        .next_element()?
                        .ok_or_else(|| de::Error::invalid_length(i, &self))?;
                    *c = u8::try_from(v).map_err(|_| {
                        de::Error::custom(format!("colour component {v} is outside 0 … 255"))
                    })?;
                }
                if seq.next_element::<de::IgnoredAny>()?.is_some() {
                    return Err(de::Error::invalid_length(4, &self));
                }
                Ok(Colour(rgb))
            }
        }
        d.deserialize_any(V)
    }
}

/// Why a scene could not be loaded, or why a world refused an object.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read.
    #[error("cannot read scene file {path}: {source}")]
    Io {
        /// The path as given.
        path: String,
        /// What the operating system said.
        #[source]
        source: std::io::Error,
    },
    /// The file is not valid TOML, has an unknown key, a wrong type or a bad value.
    #[error("scene file {origin}: {message}")]
    Parse {
        /// File name.
        origin: String,
        /// Where (line) and what.
        message: String,
    },
    /// The scene parsed but describes something impossible; one entry per problem.
    #[error("scene file {origin}: {}", problems.join("; "))]
    Invalid {
        /// File name.
        origin: String,
        /// Each problem, naming the object(s) and the reason.
        problems: Vec<String>,
    },
    /// [`World::add_object`](crate::World::add_object) refused an object.
    #[error("cannot add object '{label}': {reason}")]
    Refused {
        /// The object's label.
        label: String,
        /// Why (overlap, bad values).
        reason: String,
    },
}

/// A scene: the robot, its workspace sheets and the objects on the table.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// Scene name (`name = "…"` in the file).
    pub name: String,
    /// Where the scene came from (file name), used in messages.
    pub origin: String,
    /// The arm this scene is made for.
    pub robot: RobotModel,
    /// Workspace sheets: the file's own `[[workspaces]]`, else the robot model's built-in ones
    /// (robotd's service replaces them with `[robot] workspaces`, see `drivers/sim`).
    pub workspaces: Vec<WorkspaceSpec>,
    /// Whether the file listed its own `[[workspaces]]`.
    pub own_workspaces: bool,
    /// Objects standing on the table at the start.
    pub objects: Vec<ObjectSpec>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    name: String,
    robot: Spanned<String>,
    #[serde(default)]
    workspaces: Vec<Spanned<WorkspaceSpec>>,
    #[serde(default)]
    objects: Vec<Spanned<RawObject>>,
}

/// 1-based line of byte offset `at` in `text`.
fn line_of(text: &str, at: usize) -> usize {
    text.get(..at)
        .map(|s| s.bytes().filter(|b| *b == b'\n').count() + 1)
        .unwrap_or(1)
}

/// The built-in default Ned2 scene file.
const DEFAULT_NED2: &str = include_str!("../../../config/scenes/default.toml");
/// The built-in default WidowX scene file.
const DEFAULT_WIDOWX: &str = include_str!("../../../config/scenes/widowx.toml");

impl Scene {
    /// The scene's workspaces as [`robotd_protocol::workspace::WorkspaceInfo`]s.
    pub fn workspace_infos(&self) -> Vec<robotd_protocol::workspace::WorkspaceInfo> {
        self.workspaces
            .iter()
            .map(|w| w.to_info(self.robot))
            .collect()
    }

    /// Parses a scene file's text. `origin` (the file name) is used in messages.
    ///
    /// Refuses unknown keys, wrong types, non-finite or out-of-range numbers, unknown colour
    /// names, empty labels and duplicate workspace ids. A file without `[[workspaces]]` gets the
    /// robot model's built-in ones. Overlaps and
    /// reach are checked by [`validate`](Self::validate).
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Scene, SceneError> {
        let raw: RawScene = toml::from_str(text).map_err(|e| {
            let at = e
                .span()
                .map(|s| format!("line {}: ", line_of(text, s.start)))
                .unwrap_or_default();
            SceneError::Parse {
                origin: origin.to_owned(),
                message: format!("{at}{}", e.message().trim()),
            }
        })?;
        let mut problems = Vec::new();
        let robot = match raw.robot.get_ref().parse::<RobotModel>() {
            Ok(r) => Some(r),
            Err(e) => {
                problems.push(format!(
                    "line {}: robot: {e}",
                    line_of(text, raw.robot.span().start)
                ));
                None
            }
        };
        if raw.name.trim().is_empty() {
            problems.push("name must not be empty".to_owned());
        }
        let mut workspaces = Vec::new();
        for (i, ws) in raw.workspaces.into_iter().enumerate() {
            let line = line_of(text, ws.span().start);
            let ws = ws.into_inner();
            for p in ws.problems() {
                problems.push(format!("line {line}: workspaces[{i}] '{}': {p}", ws.id));
            }
            if workspaces.iter().any(|w: &WorkspaceSpec| w.id == ws.id) {
                problems.push(format!(
                    "line {line}: workspaces[{i}]: id '{}' is used twice",
                    ws.id
                ));
            }
            workspaces.push(ws);
        }
        let mut objects = Vec::new();
        for (i, obj) in raw.objects.into_iter().enumerate() {
            let line = line_of(text, obj.span().start);
            let obj = obj.into_inner();
            let label = obj.label.clone();
            match obj.convert() {
                Ok(spec) => {
                    for p in spec.problems() {
                        problems.push(format!("line {line}: objects[{i}] '{label}': {p}"));
                    }
                    objects.push(spec);
                }
                Err(ps) => {
                    for p in ps {
                        problems.push(format!("line {line}: objects[{i}] '{label}': {p}"));
                    }
                }
            }
        }
        match robot {
            Some(robot) if problems.is_empty() => Ok(Scene {
                name: raw.name,
                origin: origin.to_owned(),
                robot,
                own_workspaces: !workspaces.is_empty(),
                workspaces: if workspaces.is_empty() {
                    robotd_protocol::workspace::builtin_workspaces(robot)
                } else {
                    workspaces
                },
                objects,
            }),
            _ => Err(SceneError::Invalid {
                origin: origin.to_owned(),
                problems,
            }),
        }
    }

    /// Reads and parses a scene file (see [`from_toml_str`](Self::from_toml_str)).
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Scene::from_toml_str(&text, &path.display().to_string())
    }

    /// Checks what parsing cannot: objects must not overlap (their footprints on the table,
    /// touching is fine), must not cover a workspace marker (the camera needs all four), and
    /// the top centre of each must be reachable — `reachable(x, y, z)` is the caller's
    /// kinematics check. Every problem is listed, naming the file, the object(s) and why.
    pub fn validate(&self, reachable: &dyn Fn(f64, f64, f64) -> bool) -> Result<(), SceneError> {
        let mut problems = Vec::new();
        for (i, a) in self.objects.iter().enumerate() {
            for b in &self.objects[i + 1..] {
                let depth = footprint_overlap(&a.footprint(), &b.footprint());
                if depth > OVERLAP_TOLERANCE_M {
                    problems.push(format!(
                        "objects '{}' at ({:.3}, {:.3}) and '{}' at ({:.3}, {:.3}) overlap by \
                         {:.1} mm",
                        a.label,
                        a.x_m,
                        a.y_m,
                        b.label,
                        b.x_m,
                        b.y_m,
                        depth * 1000.0
                    ));
                }
            }
            for m in markers_of(&self.workspaces) {
                let disc = Footprint::Circle {
                    c: Vector2::new(m.center.x, m.center.y),
                    r: m.outer_radius_m,
                };
                if footprint_overlap(&a.footprint(), &disc) > OVERLAP_TOLERANCE_M {
                    problems.push(format!(
                        "object '{}' at ({:.3}, {:.3}) covers the workspace marker at ({:.3}, \
                         {:.3}); the camera needs all four markers",
                        a.label, a.x_m, a.y_m, m.center.x, m.center.y
                    ));
                }
            }
            let top = a.shape.height_m();
            if !reachable(a.x_m, a.y_m, top) {
                problems.push(format!(
                    "object '{}': its top centre ({:.3}, {:.3}, {:.3}) is out of reach of the {}",
                    a.label,
                    a.x_m,
                    a.y_m,
                    top,
                    self.robot.display_name()
                ));
            }
        }
        if problems.is_empty() {
            Ok(())
        } else {
            Err(SceneError::Invalid {
                origin: self.origin.clone(),
                problems,
            })
        }
    }

    /// The built-in default Ned2 scene (`config/scenes/default.toml`, compiled in).
    pub fn default_ned2() -> Scene {
        Self::builtin(DEFAULT_NED2, "config/scenes/default.toml", RobotModel::Ned2)
    }

    /// The built-in default WidowX 250 scene (`config/scenes/widowx.toml`, compiled in).
    pub fn default_widowx() -> Scene {
        Self::builtin(
            DEFAULT_WIDOWX,
            "config/scenes/widowx.toml",
            RobotModel::WidowX250,
        )
    }

    fn builtin(text: &str, origin: &str, robot: RobotModel) -> Scene {
        // The built-in files are checked by this crate's tests; should one ever fail to parse,
        // an empty scene (no objects, no workspaces) is better than a panic.
        Scene::from_toml_str(text, origin).unwrap_or_else(|_| Scene {
            name: "empty".to_owned(),
            origin: origin.to_owned(),
            robot,
            workspaces: robotd_protocol::workspace::builtin_workspaces(robot),
            own_workspaces: false,
            objects: Vec::new(),
        })
    }
}

/// Footprints may overlap by this much before it counts as an overlap (touching is fine).
pub(crate) const OVERLAP_TOLERANCE_M: f64 = 0.0001;

/// A workspace marker: concentric black and white rings printed at a sheet corner.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Marker {
    /// Centre of the rings, on the sheet (z = [`MARKER_Z_M`]).
    pub center: nalgebra::Point3<f64>,
    /// Radius of the outermost (black) ring, metres.
    pub outer_radius_m: f64,
    /// True for the one origin marker of a sheet (its upper-left = far-left corner): its centre
    /// is white where the others' is black.
    pub white_centre: bool,
}

/// Radius of a marker's outer ring, metres.
pub const MARKER_RADIUS_M: f64 = 0.010;
/// White paper around the markers: the sheet reaches this far beyond a marker's outer ring.
pub const SHEET_MARGIN_M: f64 = 0.008;
/// Height of the sheets' surface (paper on the table), metres.
pub const SHEET_Z_M: f64 = 0.0002;
/// Height of the printed markers (drawn over the sheet), metres.
pub const MARKER_Z_M: f64 = 0.0004;

/// The distinct sheet rectangles `(x_min, x_max, y_min, y_max)` of `workspaces`: workspaces
/// with the same corners (within 1 mm, e.g. `niryo_ws` and `gazebo_1`) share one sheet.
pub(crate) fn sheet_rects(workspaces: &[WorkspaceSpec]) -> Vec<[f64; 4]> {
    let mut out: Vec<[f64; 4]> = Vec::new();
    for ws in workspaces {
        let r = [
            ws.lower_right[0],
            ws.upper_left[0],
            ws.lower_right[1],
            ws.upper_left[1],
        ];
        if r.iter().any(|v| !v.is_finite()) {
            continue;
        }
        if !out
            .iter()
            .any(|o| o.iter().zip(&r).all(|(a, b)| (a - b).abs() < 0.001))
        {
            out.push(r);
        }
    }
    out
}

/// The four markers of every distinct sheet, origin (upper-left) marker first.
pub(crate) fn markers_of(workspaces: &[WorkspaceSpec]) -> Vec<Marker> {
    let mut out = Vec::new();
    for [x_min, x_max, y_min, y_max] in sheet_rects(workspaces) {
        for (x, y, white) in [
            (x_max, y_max, true),
            (x_max, y_min, false),
            (x_min, y_min, false),
            (x_min, y_max, false),
        ] {
            out.push(Marker {
                center: nalgebra::Point3::new(x, y, MARKER_Z_M),
                outer_radius_m: MARKER_RADIUS_M,
                white_centre: white,
            });
        }
    }
    out
}
