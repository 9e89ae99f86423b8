//! One randomized frame: the scene (sheet, objects, distractors), the camera and the photo's
//! conditions, drawn from a seeded generator, with the ground truth to score against.

use crate::labels::LabelTable;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::rngs::SmallRng;
use rand::Rng;
use robotd_driver_sim::solid_of;
use robotd_protocol::workspace::WorkspaceInfo;
use robotd_render::photo::PhotoEffects;
use robotd_render::sheet_art::{sheet_art, thick_line, SheetDesign, SheetPlacement};
use robotd_render::{look_at, Intrinsics, RenderScene, Shape, Solid};
use robotd_sim::{ObjectShape, ObjectSpec, SimObject};

/// The distractors a frame may have.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Distractor {
    PencilLines,
    TapedPaper,
    Cable,
    Hand,
    ObjectsBeside,
    SecondSheet,
    CoveredMarker,
    CornerBlobs,
    PaintedCentres,
}

pub(super) const DISTRACTORS: [(Distractor, &str, f64); 9] = [
    (Distractor::PencilLines, "pencil lines on the sheet", 0.25),
    (Distractor::TapedPaper, "taped paper", 0.15),
    (Distractor::Cable, "cable", 0.2),
    (Distractor::Hand, "hand at the border", 0.15),
    (Distractor::ObjectsBeside, "objects beside the sheet", 0.3),
    (Distractor::SecondSheet, "second sheet", 0.15),
    (Distractor::CoveredMarker, "marker half covered", 0.08),
    (
        Distractor::CornerBlobs,
        "dark/green blobs near a corner",
        0.25,
    ),
    (
        Distractor::PaintedCentres,
        "marker centres painted red",
        0.05,
    ),
];

/// One randomized frame's scene and conditions.
pub(super) struct Case {
    pub(super) scene: RenderScene,
    pub(super) camera: Isometry3<f64>,
    /// Where the arm holds the tool: a few centimetres from the camera, as on the wrist.
    pub(super) tool_pose: robotd_protocol::geometry::Pose,
    /// How far the kinematics' camera position is off the truth (mount, calibration), metres.
    pub(super) camera_error: [f64; 3],
    pub(super) photo: PhotoEffects,
    pub(super) jpeg_quality: u8,
    pub(super) truth: Vec<SimObject>,
    pub(super) design_index: usize,
    /// The markers' outer radius on the table, metres.
    pub(super) marker_radius_m: f64,
    /// The camera's tilt from straight down, degrees.
    pub(super) tilt_deg: f64,
    pub(super) sheet_expected: bool,
    pub(super) covered: bool,
    pub(super) distractors: Vec<Distractor>,
}

pub(super) fn corner_points(ws: &WorkspaceInfo) -> [[f64; 2]; 4] {
    let (x0, x1) = (ws.lower_right.x_m, ws.upper_left.x_m);
    let (y0, y1) = (ws.lower_right.y_m, ws.upper_left.y_m);
    [[x1, y1], [x1, y0], [x0, y1], [x0, y0]]
}

fn box_solid(x: f64, y: f64, size: [f64; 3], yaw: f64, color: [u8; 3]) -> Solid {
    Solid {
        shape: Shape::Box {
            size_m: Vector3::new(size[0], size[1], size[2]),
        },
        pose: Isometry3::from_parts(
            Translation3::new(x, y, size[2] / 2.0 + 0.0005),
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
        ),
        color,
    }
}

fn sim_object(id: u32, spec: ObjectSpec) -> SimObject {
    let [_, _, height] = spec.shape.extents_m();
    let pose = Isometry3::from_parts(
        Translation3::new(spec.x_m, spec.y_m, height / 2.0),
        UnitQuaternion::from_euler_angles(0.0, 0.0, spec.yaw_rad),
    );
    SimObject {
        id,
        spec,
        pose,
        held: false,
    }
}

pub(super) fn make_case(
    rng: &mut SmallRng,
    workspace: &WorkspaceInfo,
    table: &LabelTable,
    intrinsics: &Intrinsics,
) -> Case {
    let design_index = rng.random_range(0..3);
    let design = [SheetDesign::Plain, SheetDesign::Classic, SheetDesign::Ned2][design_index];
    let corners = corner_points(workspace);
    let placement = SheetPlacement {
        x_min: corners[3][0],
        x_max: corners[0][0],
        y_min: corners[3][1],
        y_max: corners[0][1],
        marker_radius_m: if design == SheetDesign::Classic {
            0.0105
        } else {
            0.010
        },
    };
    let tables: [[u8; 3]; 4] = [
        [118, 96, 72],
        [150, 150, 145],
        [215, 212, 205],
        [60, 58, 55],
    ];
    let mut scene = RenderScene {
        background: tables[rng.random_range(0..tables.len())],
        table_z_m: 0.0,
        quads: Vec::new(),
        discs: Vec::new(),
        solids: Vec::new(),
    };
    let distractors: Vec<Distractor> = DISTRACTORS
        .iter()
        .filter(|(_, _, p)| rng.random_bool(*p))
        .map(|(d, _, _)| *d)
        .collect();
    let has = |d: Distractor| distractors.contains(&d);

    // A second sheet beside the first, drawn first (the first lies over its edge if they
    // meet).
    if has(Distractor::SecondSheet) {
        let (dx, dy) = match rng.random_range(0..3) {
            0 => (0.0, 0.235),
            1 => (0.0, -0.235),
            _ => (-0.235, 0.0),
        };
        let second = SheetPlacement {
            x_min: placement.x_min + dx,
            x_max: placement.x_max + dx,
            y_min: placement.y_min + dy,
            y_max: placement.y_max + dy,
            ..placement
        };
        let other =
            [SheetDesign::Plain, SheetDesign::Classic, SheetDesign::Ned2][rng.random_range(0..3)];
        sheet_art(other, &second, &mut scene);
    }
    sheet_art(design, &placement, &mut scene);
    let (cx, cy) = (
        0.5 * (placement.x_min + placement.x_max),
        0.5 * (placement.y_min + placement.y_max),
    );

    // Objects on the sheet: random ones of the label table, maybe a two-coloured bar.
    let mut specs = super::super::random_objects(rng, table, workspace, 6);
    let mut truth: Vec<SimObject> = Vec::new();
    let mut multi: Option<(SimObject, Vec<Solid>)> = None;
    if rng.random_bool(0.3) {
        let length = rng.random_range(0.05..0.08);
        let width = rng.random_range(0.018..0.03);
        let height = rng.random_range(0.01..0.02);
        let margin = 0.5 * length + 0.015;
        let x = rng.random_range(placement.x_min + margin..placement.x_max - margin);
        let y = rng.random_range(placement.y_min + margin..placement.y_max - margin);
        let clear = specs.iter().all(|s| {
            let [ex, ey, _] = s.shape.extents_m();
            (s.x_m - x).hypot(s.y_m - y) > 0.5 * ex.hypot(ey) + 0.5 * length + 0.015
        });
        if clear {
            let yaw: f64 = rng.random_range(0.0..std::f64::consts::PI);
            let colours: Vec<[u8; 3]> = table.colours.iter().map(|c| c.rgb).collect();
            let a = colours[rng.random_range(0..colours.len())];
            let mut b = colours[rng.random_range(0..colours.len())];
            if a == b {
                b = [215, 175, 60]; // gold foil
            }
            // The wrapper's colour at both ends, a band of the other across the middle third.
            let (s, c) = yaw.sin_cos();
            let third = length / 3.0;
            let pieces = vec![
                box_solid(x + c * third, y + s * third, [third, width, height], yaw, a),
                box_solid(x, y, [third, width, height], yaw, b),
                box_solid(x - c * third, y - s * third, [third, width, height], yaw, a),
            ];
            let spec = ObjectSpec::new(
                "banded bar",
                ObjectShape::Box {
                    length_x_m: length,
                    width_y_m: width,
                    height_z_m: height,
                },
                a,
                x,
                y,
            )
            .with_yaw(yaw);
            multi = Some((sim_object(1000, spec), pieces));
        }
    }
    for (k, spec) in specs.drain(..).enumerate() {
        let object = sim_object(k as u32, spec);
        scene.solids.push(solid_of(&object));
        truth.push(object);
    }
    if let Some((object, pieces)) = multi {
        scene.solids.extend(pieces);
        truth.push(object);
    }

    // Distractors.
    let r = placement.marker_radius_m;
    let (x0, x1, y0, y1) = (
        placement.x_min,
        placement.x_max,
        placement.y_min,
        placement.y_max,
    );
    if has(Distractor::TapedPaper) {
        let side = rng.random_range(0.06..0.1);
        let (px, py) = (
            cx + rng.random_range(-0.02..0.02),
            cy + rng.random_range(-0.02..0.02),
        );
        let yaw: f64 = rng.random_range(-0.3..0.3);
        let (s, c) = yaw.sin_cos();
        let corner = |u: f64, v: f64| Point3::new(px + c * u - s * v, py + s * u + c * v, 0.00045);
        let hs = side / 2.0;
        scene.quads.push((
            [
                corner(-hs, -hs),
                corner(hs, -hs),
                corner(hs, hs),
                corner(-hs, hs),
            ],
            [238, 238, 232],
        ));
    }
    if has(Distractor::PencilLines) || has(Distractor::TapedPaper) && rng.random_bool(0.5) {
        // A tic-tac-toe grid in pencil: two lines each way.
        let size = rng.random_range(0.05..0.09);
        let grey = rng.random_range(80..150) as u8;
        let width = rng.random_range(0.0004..0.0012);
        for k in [-1.0, 1.0] {
            let o = k * size / 6.0;
            thick_line(
                [cx + o, cy - size / 2.0],
                [cx + o, cy + size / 2.0],
                width,
                0.0005,
                [grey; 3],
                &mut scene,
            );
            thick_line(
                [cx - size / 2.0, cy + o],
                [cx + size / 2.0, cy + o],
                width,
                0.0005,
                [grey; 3],
                &mut scene,
            );
        }
    }
    if has(Distractor::Cable) {
        // Along the sheet's border outside the markers' rectangle, from the table onto the
        // sheet's margin.
        let off = rng.random_range(1.9..3.0) * r;
        let y_side = if rng.random_bool(0.5) {
            y1 + off
        } else {
            y0 - off
        };
        let mut last = [x0 - 0.05, y_side + rng.random_range(-0.01..0.01)];
        let width = rng.random_range(0.004..0.007);
        for k in 1..=10 {
            let next = [
                x0 - 0.05 + k as f64 * 0.03,
                y_side + rng.random_range(-0.004..0.004),
            ];
            thick_line(last, next, width, 0.0006, [35, 35, 38], &mut scene);
            last = next;
        }
    }
    if has(Distractor::Hand) {
        // A hand reaching to the sheet's lower edge: palm and fingers, skin-coloured boxes.
        let skin = [205, 150, 120];
        let y = rng.random_range(y0 + 0.03..y1 - 0.03);
        scene
            .solids
            .push(box_solid(x0 - 0.09, y, [0.08, 0.08, 0.025], 0.0, skin));
        for f in 0..4 {
            let fy = y - 0.027 + f as f64 * 0.018;
            scene
                .solids
                .push(box_solid(x0 - 0.035, fy, [0.03, 0.014, 0.014], 0.0, skin));
        }
    }
    if has(Distractor::ObjectsBeside) {
        let colours: Vec<[u8; 3]> = table.colours.iter().map(|c| c.rgb).collect();
        for _ in 0..rng.random_range(1..=3) {
            let side = rng.random_range(0.02..0.04);
            let (x, y) = if rng.random_bool(0.5) {
                (
                    rng.random_range(x0..x1),
                    if rng.random_bool(0.5) {
                        y1 + 0.06
                    } else {
                        y0 - 0.06
                    },
                )
            } else {
                (x0 - 0.06, rng.random_range(y0..y1))
            };
            let colour = colours[rng.random_range(0..colours.len())];
            scene.solids.push(box_solid(
                x,
                y,
                [side, side, side],
                rng.random_range(0.0..1.5),
                colour,
            ));
        }
    }
    if has(Distractor::CornerBlobs) {
        // Cube-sized blobs by a corner marker: a dark one just outside the sheet, a green cube
        // on the sheet just inside the corner (an object to find, not a marker).
        let k = rng.random_range(0..4);
        let [mx, my] = corners[k];
        let (sx, sy) = ((mx - cx).signum(), (my - cy).signum());
        let d = rng.random_range(0.035..0.05);
        scene.solids.push(box_solid(
            mx + sx * d,
            my + sy * d * 0.3,
            [0.025, 0.025, 0.025],
            0.3,
            [38, 38, 40],
        ));
        let (gx, gy) = (mx - sx * 0.032, my - sy * 0.032);
        let clear = truth.iter().all(|o| {
            let [ex, ey, _] = o.spec.shape.extents_m();
            (o.pose.translation.x - gx).hypot(o.pose.translation.y - gy)
                > 0.5 * ex.hypot(ey) + 0.035
        });
        if clear {
            let green = table
                .colours
                .iter()
                .find(|c| c.name == "green")
                .map_or([40, 150, 60], |c| c.rgb);
            let spec = ObjectSpec::new(
                "green cube",
                ObjectShape::Box {
                    length_x_m: 0.025,
                    width_y_m: 0.025,
                    height_z_m: 0.025,
                },
                green,
                gx,
                gy,
            )
            .with_yaw(0.2);
            let object = sim_object(2000, spec);
            scene.solids.push(solid_of(&object));
            truth.push(object);
        }
    }
    let painted = has(Distractor::PaintedCentres);
    if painted {
        // Another program painted the markers' centres red.
        for [x, y] in corners {
            scene.discs.push(robotd_render::Disc {
                center: Point3::new(x, y, 0.0006),
                radius_m: 0.3 * r,
                color: [220, 30, 30],
            });
        }
    }
    let covered = has(Distractor::CoveredMarker);
    if covered {
        // A sheet of card over half of one marker.
        let [mx, my] = corners[rng.random_range(0..4)];
        let (sx, sy) = ((mx - cx).signum(), (my - cy).signum());
        scene.solids.push(box_solid(
            mx + sx * 0.02,
            my + sy * 0.001,
            [0.04, 0.03, 0.002],
            0.0,
            [200, 60, 50],
        ));
    }

    // The camera: above the sheet, tilted up to 30° in any direction, turned any way.
    let mut camera = Isometry3::identity();
    let mut in_view = false;
    let mut tilt_deg = 0.0;
    for _ in 0..40 {
        let height = rng.random_range(0.24..0.42);
        let tilt: f64 = rng.random_range(0f64..30.0).to_radians();
        tilt_deg = tilt.to_degrees();
        let azimuth: f64 = rng.random_range(0.0..std::f64::consts::TAU);
        let target = Point3::new(
            cx + rng.random_range(-0.015..0.015),
            cy + rng.random_range(-0.015..0.015),
            0.0,
        );
        let eye = Point3::new(
            target.x + height * tilt.sin() * azimuth.cos(),
            target.y + height * tilt.sin() * azimuth.sin(),
            height * tilt.cos(),
        );
        let roll: f64 = rng.random_range(0.0..std::f64::consts::TAU);
        let up = Vector3::new(roll.cos(), roll.sin(), 0.0);
        camera = look_at(&eye, &target, &up);
        let inverse = camera.inverse();
        in_view = corners.iter().all(|&[x, y]| {
            (0..8).all(|k| {
                let a = k as f64 * std::f64::consts::FRAC_PI_4;
                intrinsics
                    .project(
                        &inverse,
                        &Point3::new(x + 1.6 * r * a.cos(), y + 1.6 * r * a.sin(), 0.0),
                    )
                    .is_some_and(|p| {
                        p.x >= 6.0
                            && p.y >= 6.0
                            && p.x <= f64::from(intrinsics.width) - 7.0
                            && p.y <= f64::from(intrinsics.height) - 7.0
                    })
            })
        });
        if in_view {
            break;
        }
    }

    let photo = PhotoEffects {
        exposure: rng.random_range(0.6..1.2),
        light_gradient: [rng.random_range(-0.35..0.35), rng.random_range(-0.35..0.35)],
        white_balance: [
            rng.random_range(0.85..1.15),
            1.0,
            rng.random_range(0.8..1.15),
        ],
        vignetting: rng.random_range(0.0..0.35),
        glare: rng.random_bool(0.3).then(|| {
            (
                [rng.random_range(0.1..0.9), rng.random_range(0.1..0.9)],
                rng.random_range(0.05..0.15),
                rng.random_range(0.2..0.5),
            )
        }),
        blur_px: [0, 0, 0, 1, 1, 2][rng.random_range(0..6)],
    };
    // The tool a few centimetres from the camera, as a wrist camera is mounted.
    let eye = camera.translation.vector;
    let tool_pose = robotd_protocol::geometry::Pose::new(
        eye.x + rng.random_range(-0.04..0.04),
        eye.y + rng.random_range(-0.04..0.04),
        eye.z + rng.random_range(-0.05..0.0),
        0.0,
        0.0,
        0.0,
    );
    let camera_error = [
        rng.random_range(-0.02..0.02),
        rng.random_range(-0.02..0.02),
        rng.random_range(-0.02..0.02),
    ];
    Case {
        scene,
        camera,
        tool_pose,
        camera_error,
        photo,
        jpeg_quality: rng.random_range(40..=95),
        truth,
        design_index,
        marker_radius_m: r,
        tilt_deg,
        sheet_expected: in_view && !covered && !painted,
        covered: covered || painted,
        distractors,
    }
}
