//! Scenes: the built-in ones and files parse and validate; bad values, overlaps, unreachable
//! objects and objects on markers are refused naming what is wrong; the markers' layout.

use super::*;

#[test]
fn built_in_scenes_parse_and_validate() {
    let ned2 = Scene::default_ned2();
    assert_eq!(ned2.robot, RobotModel::Ned2);
    assert_eq!(ned2.name, "default");
    let ids: Vec<&str> = ned2.workspaces.iter().map(|w| w.id.as_str()).collect();
    assert_eq!(ids, ["niryo_ws", "gazebo_1"]);
    let labels: Vec<&str> = ned2.objects.iter().map(|o| o.label.as_str()).collect();
    assert_eq!(
        labels,
        ["pencil", "red cube", "blue square", "green cylinder"]
    );
    let pencil = &ned2.objects[0];
    assert_eq!(
        pencil.shape,
        ObjectShape::Box {
            length_x_m: 0.12,
            width_y_m: 0.012,
            height_z_m: 0.010
        }
    );
    assert_eq!((pencil.x_m, pencil.y_m, pencil.yaw_rad), (0.22, -0.05, 0.0));
    assert_eq!(pencil.color, colour_by_name("yellow").unwrap());
    ned2.validate(&roughly_reachable).unwrap();

    let push = Scene::from_toml_str(PUSH_TOML, "push.toml").unwrap();
    assert!(push.objects.iter().any(|o| o.label == "large box"));
    push.validate(&roughly_reachable).unwrap();

    let widowx = Scene::default_widowx();
    assert_eq!(widowx.robot, RobotModel::WidowX250);
    assert_eq!(widowx.workspaces[0].id, "widowx_ws");
    assert!(widowx.objects.iter().any(|o| o.container));
    widowx.validate(&roughly_reachable).unwrap();
    assert_eq!(
        Scene::from_toml_str(WIDOWX_TOML, "widowx.toml")
            .unwrap()
            .objects,
        widowx.objects
    );
}

#[test]
fn scene_files_load_from_disk() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/scenes");
    let scene = Scene::load(&dir.join("default.toml")).unwrap();
    assert_eq!(scene.objects, Scene::default_ned2().objects);
    let err = Scene::load(&dir.join("missing.toml"))
        .unwrap_err()
        .to_string();
    assert!(err.contains("missing.toml"), "{err}");
}

#[test]
fn unknown_key_is_refused_naming_file_line_and_key() {
    let text = cube_toml("red cube", 0.28, 0.04, 0.03).replace("color", "colour");
    let err = parse(&text).unwrap_err().to_string();
    assert!(err.starts_with("scene file test.toml: line "), "{err}");
    assert!(err.contains("unknown field `colour`"), "{err}");

    let err = Scene::from_toml_str(&format!("{WS}\nlighting = 3"), "x.toml")
        .unwrap_err()
        .to_string();
    assert!(err.contains("x.toml") && err.contains("lighting"), "{err}");
}

#[test]
fn bad_values_are_refused() {
    let bad =
        cube_toml("red cube", 0.28, 0.04, 0.03).replace("length_x_m = 0.03", "length_x_m = -0.03");
    let err = parse(&bad).unwrap_err().to_string();
    assert!(err.contains("test.toml"), "{err}");
    assert!(err.contains("objects[0] 'red cube': length_x_m"), "{err}");
    assert!(err.contains("-0.03"), "{err}");

    let nan = cube_toml("red cube", 0.28, 0.04, 0.03).replace("x_m = 0.28", "x_m = nan");
    assert!(parse(&nan)
        .unwrap_err()
        .to_string()
        .contains("x_m must be a finite"));

    let colour = cube_toml("red cube", 0.28, 0.04, 0.03).replace("\"red\"", "\"redd\"");
    let err = parse(&colour).unwrap_err().to_string();
    assert!(err.contains("unknown colour 'redd'"), "{err}");
    let rgb = cube_toml("c", 0.28, 0.04, 0.03).replace("\"red\"", "[1, 2, 3]");
    assert_eq!(parse(&rgb).unwrap().objects[0].color, [1, 2, 3]);
    let rgb = cube_toml("c", 0.28, 0.04, 0.03).replace("\"red\"", "[1, 2, 300]");
    assert!(parse(&rgb).unwrap_err().to_string().contains("300"));

    let empty = cube_toml(" ", 0.28, 0.04, 0.03);
    assert!(parse(&empty)
        .unwrap_err()
        .to_string()
        .contains("label must not be empty"));

    let cyl_key = format!("{}diameter_m = 0.03\n", cube_toml("c", 0.28, 0.04, 0.03));
    let err = parse(&cyl_key).unwrap_err().to_string();
    assert!(
        err.contains("`diameter_m` does not apply to shape \"box\""),
        "{err}"
    );

    let missing = "[[objects]]\nlabel = \"can\"\nshape = \"cylinder\"\ndiameter_m = 0.03\n\
                   color = \"green\"\nx_m = 0.3\ny_m = 0.0\n";
    let err = parse(missing).unwrap_err().to_string();
    assert!(err.contains("a cylinder needs `height_m`"), "{err}");

    let robot = WS.replace("\"ned2\"", "\"ur5\"");
    let err = Scene::from_toml_str(&robot, "r.toml")
        .unwrap_err()
        .to_string();
    assert!(err.contains("unknown robot model 'ur5'"), "{err}");

    let ws = WS.replace("[0.163, -0.087]", "[0.4, -0.087]");
    let err = Scene::from_toml_str(&ws, "w.toml").unwrap_err().to_string();
    assert!(err.contains("far-left"), "{err}");
}

#[test]
fn overlapping_objects_are_refused_naming_both() {
    let text = format!(
        "{}{}",
        cube_toml("red cube", 0.28, 0.04, 0.03),
        cube_toml("blue cube", 0.30, 0.05, 0.03)
    );
    let err = parse(&text)
        .unwrap()
        .validate(&roughly_reachable)
        .unwrap_err()
        .to_string();
    assert!(err.starts_with("scene file test.toml:"), "{err}");
    assert!(
        err.contains("'red cube'") && err.contains("'blue cube'"),
        "{err}"
    );
    assert!(err.contains("overlap by 10.0 mm"), "{err}");
    // Touching is fine.
    let text = format!(
        "{}{}",
        cube_toml("red cube", 0.28, 0.04, 0.03),
        cube_toml("blue cube", 0.28, 0.07, 0.03)
    );
    parse(&text).unwrap().validate(&roughly_reachable).unwrap();
}

#[test]
fn unreachable_objects_are_refused() {
    let scene = parse(&cube_toml("far cube", 0.30, 0.0, 0.03)).unwrap();
    let err = scene
        .validate(&|x, _y, z| x < 0.25 && z < 0.3)
        .unwrap_err()
        .to_string();
    assert!(err.contains("test.toml"), "{err}");
    assert!(
        err.contains("'far cube'") && err.contains("out of reach of the Niryo Ned2"),
        "{err}"
    );
    assert!(err.contains("(0.300, 0.000, 0.030)"), "{err}");
}

#[test]
fn objects_on_markers_are_refused() {
    let scene = parse(&cube_toml("corner cube", 0.335, 0.085, 0.02)).unwrap();
    let err = scene.validate(&roughly_reachable).unwrap_err().to_string();
    assert!(err.contains("covers the workspace marker"), "{err}");
}

// ---- markers and sheets ----

#[test]
fn four_markers_per_sheet_one_white_centre_at_upper_left() {
    let world = World::new(&Scene::default_ned2());
    // niryo_ws and gazebo_1 share one sheet.
    let markers = world.markers();
    assert_eq!(markers.len(), 4);
    let white: Vec<&Marker> = markers.iter().filter(|m| m.white_centre).collect();
    assert_eq!(white.len(), 1);
    assert!((white[0].center.x - 0.337).abs() < 1e-12 && (white[0].center.y - 0.087).abs() < 1e-12);
    let quads = world.sheet_quads();
    assert_eq!(quads.len(), 1);
    let q = quads[0];
    for m in &markers {
        assert!(m.center.x - m.outer_radius_m > q[2].x && m.center.x + m.outer_radius_m < q[0].x);
        assert!(m.center.y - m.outer_radius_m > q[2].y && m.center.y + m.outer_radius_m < q[0].y);
    }
    assert!(markers.iter().all(|m| m.center.z > q[0].z));

    let widowx = World::new(&Scene::default_widowx());
    assert_eq!(widowx.markers().len(), 4);
}

// ---- grasping ----
