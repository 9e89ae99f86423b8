//! The ways perception failed on real photos, each rebuilt from rendered pixels, and the
//! randomized frames as a regression guard.
//!
//! Real photos other than the shared ones showed five failures: a cube taken for a marker (a
//! confidently wrong workspace), four sharp markers of a phone photo not assigned, pencil lines
//! reported as objects, one multi-coloured wrapper reported as several objects, PNG files
//! refused (that one is in the root crate's `cli_detect` test). Each is rendered here with
//! Niryo's printed sheet designs and checked; a bounded run of randomized frames checks that
//! no workspace is ever reported wrong.

mod common;

use common::{sheet_scene, workspace};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use robotd_perception::detector::{ColourDetector, ColourDetectorSettings, FrameView};
use robotd_perception::eval::randomized;
use robotd_perception::labels::LabelTable;
use robotd_perception::pipeline::SheetStatus;
use robotd_perception::Pipeline;
use robotd_render::sheet_art::{thick_line, SheetDesign};
use robotd_render::{look_at, Intrinsics, RenderOptions, RenderScene, Renderer, Shape, Solid};

fn cube(x: f64, y: f64, side: f64, color: [u8; 3]) -> Solid {
    Solid {
        shape: Shape::Box {
            size_m: Vector3::new(side, side, side),
        },
        pose: Isometry3::from_parts(
            Translation3::new(x, y, side / 2.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 0.3),
        ),
        color,
    }
}

/// Renders `scene` from `height` metres straight above the sheet's centre (image top along
/// +x) and runs the pipeline; `guessed`: the pipeline is told the focal length is a guess.
fn look(
    scene: &RenderScene,
    intrinsics: Intrinsics,
    height: f64,
    guessed: bool,
) -> (Vec<robotd_protocol::objects::DetectedObject>, SheetStatus) {
    let camera = look_at(
        &Point3::new(0.25, 0.0, height),
        &Point3::new(0.25, 0.0, 0.0),
        &Vector3::x(),
    );
    let (w, h) = (intrinsics.width as usize, intrinsics.height as usize);
    let mut rgb = vec![0u8; w * h * 3];
    let mut renderer = Renderer::new(intrinsics, RenderOptions::default());
    renderer.render_into(scene, &camera, &mut rgb).unwrap();
    let detector = ColourDetector::new(LabelTable::builtin(), ColourDetectorSettings::default());
    let mut pipeline =
        Pipeline::new(&intrinsics.into(), vec![workspace()], Box::new(detector)).unwrap();
    if guessed {
        pipeline = pipeline.with_guessed_intrinsics();
    }
    let frame = FrameView {
        rgb: &rgb,
        width: w,
        height: h,
        frame_id: 1,
        timestamp_unix_ns: 0,
    };
    let (detections, status) = pipeline.process(&frame, None, true).unwrap();
    (detections.objects, status)
}

fn ned2_camera() -> Intrinsics {
    Intrinsics {
        distortion: [0.0; 5],
        ..Intrinsics::ned2()
    }
}

#[test]
fn a_cube_beside_a_corner_whose_marker_is_painted_over_is_never_a_marker() {
    for design in [SheetDesign::Classic, SheetDesign::Ned2, SheetDesign::Plain] {
        let mut scene = sheet_scene(design);
        // Another program painted the lower-right marker's centre red and over its rings; a
        // green and a dark cube stand just inside that corner.
        scene.discs.push(robotd_render::Disc {
            center: Point3::new(0.163, -0.087, 0.0006),
            radius_m: 0.0075,
            color: [220, 30, 30],
        });
        scene.solids.push(cube(0.19, -0.06, 0.025, [40, 150, 60]));
        scene.solids.push(cube(0.14, -0.11, 0.025, [40, 40, 42]));
        let (objects, status) = look(&scene, ned2_camera(), 0.3, false);
        assert_ne!(status, SheetStatus::Found, "{design:?}: {objects:?}");
        assert!(objects.is_empty(), "{design:?}");
        // Three markers are three: the message never says "4 of the 4".
        match status {
            SheetStatus::MarkersMissing { seen } => assert!(seen < 4, "{design:?}: {status}"),
            SheetStatus::NotASheet { seen, .. } => assert!(seen >= 4, "{design:?}: {status}"),
            other => panic!("{design:?}: {other}"),
        }
    }
}

#[test]
fn four_sharp_markers_of_an_empty_sheet_from_straight_above_at_3000_px_are_the_sheet() {
    // A phone photo: 2988 × 2860 pixels, from straight above, the focal length unknown (the
    // pipeline searches it), both printed designs.
    let phone = Intrinsics {
        width: 2988,
        height: 2860,
        fx: 2600.0,
        fy: 2600.0,
        cx: 1493.5,
        cy: 1429.5,
        distortion: [0.0; 5],
    };
    for design in [SheetDesign::Classic, SheetDesign::Ned2] {
        let (objects, status) = look(&sheet_scene(design), phone, 0.3, true);
        assert_eq!(status, SheetStatus::Found, "{design:?}: {status}");
        assert!(
            objects.is_empty(),
            "{design:?}: the empty sheet: {objects:?}"
        );
    }
}

#[test]
fn a_pencil_grid_on_taped_paper_is_not_an_object() {
    for design in [SheetDesign::Classic, SheetDesign::Ned2, SheetDesign::Plain] {
        let mut scene = sheet_scene(design);
        let corner = |x: f64, y: f64| Point3::new(x, y, 0.00045);
        scene.quads.push((
            [
                corner(0.21, -0.045),
                corner(0.29, -0.04),
                corner(0.295, 0.04),
                corner(0.205, 0.045),
            ],
            [238, 238, 230],
        ));
        for k in [-1.0, 1.0] {
            let o = k * 0.012;
            let grey = [110, 110, 112];
            thick_line(
                [0.25 + o, -0.035],
                [0.25 + o, 0.035],
                0.0008,
                0.0005,
                grey,
                &mut scene,
            );
            thick_line([0.215, o], [0.285, o], 0.0008, 0.0005, grey, &mut scene);
        }
        let (objects, status) = look(&scene, ned2_camera(), 0.28, false);
        assert_eq!(status, SheetStatus::Found, "{design:?}");
        assert!(objects.is_empty(), "{design:?}: {objects:#?}");
    }
}

#[test]
fn a_wrapper_printed_in_several_colours_is_one_object() {
    // A bar in a red wrapper with a gold band across it and a blue label on one end.
    let mut scene = sheet_scene(SheetDesign::Classic);
    let part = |x: f64, len: f64, width: f64, color: [u8; 3], z: f64| Solid {
        shape: Shape::Box {
            size_m: Vector3::new(len, width, z),
        },
        pose: Isometry3::from_parts(
            Translation3::new(x, 0.01, z / 2.0),
            UnitQuaternion::identity(),
        ),
        color,
    };
    scene
        .solids
        .push(part(0.2275, 0.025, 0.024, [200, 30, 30], 0.012));
    scene
        .solids
        .push(part(0.2525, 0.025, 0.024, [225, 180, 50], 0.012));
    scene
        .solids
        .push(part(0.2775, 0.025, 0.024, [200, 30, 30], 0.012));
    scene
        .solids
        .push(part(0.2275, 0.01, 0.012, [30, 60, 200], 0.0125));
    let (objects, status) = look(&scene, ned2_camera(), 0.28, false);
    assert_eq!(status, SheetStatus::Found);
    assert_eq!(objects.len(), 1, "{objects:#?}");
    let bar = &objects[0];
    let long = bar.dimensions.width_m.max(bar.dimensions.height_m);
    assert!((0.065..0.085).contains(&long), "{bar:#?}");
    let c = bar.position.center_of_mass;
    assert!(
        (c.x_m - 0.2525).abs() < 0.006 && (c.y_m - 0.01).abs() < 0.006,
        "{bar:#?}"
    );
}

#[test]
fn randomized_frames_never_give_a_wrong_workspace() {
    // Bounded for CI (about 10 s in a debug build); `robotd bench perception --randomized
    // 10000` runs the full measure.
    let figures = randomized::run(150, 20_261_128, None).unwrap();
    assert_eq!(
        figures.wrong_workspaces, 0,
        "frames with a wrong workspace: {:?}",
        figures.wrong_seeds
    );
    // The measure is not vacuous: sheets are found and objects seen. Blurred and small
    // printed markers count since the second look (it finds 76 % of these 136 frames).
    assert!(figures.found_rate() > 0.65, "{figures:?}");
    assert!(figures.objects > 100, "{figures:?}");
    assert!(figures.recall() >= 0.97, "recall {}", figures.recall());
    assert!(
        figures.precision() >= 0.97,
        "precision {}",
        figures.precision()
    );
}
