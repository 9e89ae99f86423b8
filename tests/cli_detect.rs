//! `robotd detect IMAGE` on real photographs of Niryo workspaces, and on bad input.
//!
//! The photos are not part of the project (their licences do not allow it): they are read from
//! `../shared/real_images/` beside the repository (or `REAL_IMAGES_DIR`). The tests that need
//! them are `#[ignore]`d with that reason, so a plain run never passes them unchecked; run
//! them with `cargo nextest run --test cli_detect --run-ignored all` where the photos are
//! (`scripts/test.sh` does when the folder exists), and they fail, naming the folder, when the
//! photos are missing. What each photo should give is in that folder's README.md.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The variable naming the photos' folder (not a `ROBOTD_*` name: robotd reads those as
/// configuration keys). Kept out of robotd's environment all the same.
const PHOTOS_VAR: &str = "REAL_IMAGES_DIR";

fn photos() -> PathBuf {
    let dir = std::env::var_os(PHOTOS_VAR)
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/real_images"));
    assert!(
        dir.is_dir(),
        "the real photos are not at {} (set REAL_IMAGES_DIR to their folder)",
        dir.display()
    );
    dir
}

/// The photos of `dir` whose file name contains `part`.
fn photos_named(dir: &Path, part: &str) -> Vec<PathBuf> {
    let mut found: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension().is_some_and(|e| e == "jpg")
                && p.file_name().unwrap().to_string_lossy().contains(part)
        })
        .collect();
    found.sort();
    found
}

fn detect(args: &[&str], image: &Path) -> Value {
    let output = Command::new(env!("CARGO_BIN_EXE_robotd"))
        .arg("detect")
        .arg(image)
        .env_remove(PHOTOS_VAR)
        .args(["--json"])
        .args(args)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(
        output.status.code(),
        Some(0),
        "{}: {stderr}",
        image.display()
    );
    serde_json::from_slice(&output.stdout).unwrap_or_else(|e| {
        panic!(
            "{}: not JSON ({e}): {}",
            image.display(),
            String::from_utf8_lossy(&output.stdout)
        )
    })
}

fn objects(report: &Value) -> &Vec<Value> {
    report["objects"].as_array().unwrap()
}

#[test]
#[ignore = "needs the real photos (../shared/real_images or REAL_IMAGES_DIR), not part of the repository"]
fn the_whole_sheet_photo_gives_four_markers_and_the_eight_objects_on_the_sheet() {
    let dir = photos();
    let [photo] = &photos_named(&dir, "img_illustration")[..] else {
        panic!("the whole-sheet photo is missing from {}", dir.display());
    };
    let out = std::env::temp_dir().join(format!("robotd-detect-{}.png", std::process::id()));
    let report = detect(&["--out", out.to_str().unwrap()], photo);
    assert_eq!(report["workspace_found"], true, "{report:#}");
    assert_eq!(report["mode"], "markers");

    // Four markers make the sheet; the reference is the image's top-left one.
    let corners: Vec<&Value> = report["markers"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|m| !m["corner"].is_null())
        .collect();
    assert_eq!(corners.len(), 4, "{report:#}");
    let xy = |m: &Value| {
        [
            m["centre_px"][0].as_f64().unwrap(),
            m["centre_px"][1].as_f64().unwrap(),
        ]
    };
    let reference: Vec<&&Value> = corners.iter().filter(|m| m["reference"] == true).collect();
    assert_eq!(reference.len(), 1);
    assert_eq!(reference[0]["corner"], "upper_left");
    let [ru, rv] = xy(reference[0]);
    for m in &corners {
        let [u, v] = xy(m);
        assert!(
            ru <= u + 5.0 && rv <= v + 5.0,
            "reference not top-left: {report:#}"
        );
    }

    // The eight objects on the sheet, none of the three beside it, each named by its colour.
    let objects = objects(&report);
    assert_eq!(objects.len(), 8, "{report:#}");
    let (u_lo, u_hi) = corners
        .iter()
        .map(|m| xy(m)[0])
        .fold((f64::MAX, 0f64), |(a, b), u| (a.min(u), b.max(u)));
    let (v_lo, v_hi) = corners
        .iter()
        .map(|m| xy(m)[1])
        .fold((f64::MAX, 0f64), |(a, b), v| (a.min(v), b.max(v)));
    let mut colours: Vec<String> = Vec::new();
    for o in objects {
        let [u, v] = xy(o);
        assert!(
            (u_lo..=u_hi).contains(&u) && (v_lo..=v_hi).contains(&v),
            "object off the sheet: {o:#}"
        );
        colours.push(o["colour"].as_str().unwrap().to_owned());
        let rel = &o["workspace_rel"];
        for k in 0..2 {
            let r = rel[k].as_f64().unwrap();
            assert!((-0.05..=1.05).contains(&r), "{o:#}");
        }
    }
    colours.sort();
    assert_eq!(
        colours,
        ["blue", "blue", "green", "green", "red", "red", "yellow", "yellow"],
        "{report:#}"
    );
    let png = std::fs::read(&out).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    let _ = std::fs::remove_file(&out);
}

#[test]
#[ignore = "needs the real photos (../shared/real_images or REAL_IMAGES_DIR), not part of the repository"]
fn warped_workspace_images_give_their_objects() {
    let dir = photos();
    let [extracted] = &photos_named(&dir, "workspace_extracted")[..] else {
        panic!("the extracted workspace is missing from {}", dir.display());
    };
    let report = detect(&[], extracted);
    assert_eq!(report["mode"], "warped", "{report:#}");
    assert_eq!(objects(&report).len(), 8, "{report:#}");

    let mut crops = photos_named(&dir, "Tensorflow_data");
    crops.extend(photos_named(&dir, "data_cap"));
    assert_eq!(crops.len(), 6, "four sweets and two caps expected");
    for crop in &crops {
        let report = detect(&[], crop);
        assert_eq!(report["workspace_found"], true, "{report:#}");
        assert_eq!(report["mode"], "warped", "{report:#}");
        assert_eq!(objects(&report).len(), 1, "{}: {report:#}", crop.display());
    }
}

#[test]
#[ignore = "needs the real photos (../shared/real_images or REAL_IMAGES_DIR), not part of the repository"]
fn photos_without_a_workspace_say_so_and_give_no_objects() {
    let dir = photos();
    let mut photos = photos_named(&dir, "board_image");
    photos.extend(photos_named(&dir, "TestShapes"));
    assert_eq!(photos.len(), 2);
    for photo in &photos {
        let report = detect(&[], photo);
        assert_eq!(report["workspace_found"], false, "{report:#}");
        assert!(
            report["status"]
                .as_str()
                .unwrap()
                .contains("no workspace in view"),
            "{report:#}"
        );
        assert!(objects(&report).is_empty(), "{report:#}");
    }
}

#[test]
fn bad_input_is_refused_with_the_reason_never_a_panic() {
    let dir = std::env::temp_dir().join(format!("robotd-detect-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = dir.join("notes.jpg");
    std::fs::write(&text, "not a picture").unwrap();
    // A JPEG header claiming 60000 x 60000 pixels.
    let huge = dir.join("huge.jpg");
    let mut bytes = vec![0xFF, 0xD8, 0xFF, 0xC0, 0x00, 0x11, 0x08];
    bytes.extend_from_slice(&60000u16.to_be_bytes());
    bytes.extend_from_slice(&60000u16.to_be_bytes());
    bytes.extend_from_slice(&[3, 1, 0x22, 0, 2, 0x11, 1, 3, 0x11, 1]);
    std::fs::write(&huge, bytes).unwrap();
    let missing = dir.join("missing.jpg");
    for (file, says) in [
        (&text, "not an image"),
        (&huge, "huge.jpg"),
        (&missing, "cannot read"),
    ] {
        let output = Command::new(env!("CARGO_BIN_EXE_robotd"))
            .arg("detect")
            .arg(file)
            .env_remove(PHOTOS_VAR)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(1), "{stderr}");
        assert!(stderr.contains(says), "{stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A saved frame as a PNG (with an alpha channel, as screenshots have): the sheet and a red
/// cube rendered from above. Needs no photo.
#[test]
fn a_png_frame_is_read_like_a_jpeg() {
    use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
    use robotd_render::sheet_art::{sheet_art, SheetDesign, SheetPlacement};
    use robotd_render::{look_at, Intrinsics, RenderOptions, RenderScene, Renderer, Shape, Solid};

    let mut scene = RenderScene {
        background: [118, 96, 72],
        table_z_m: 0.0,
        quads: Vec::new(),
        discs: Vec::new(),
        solids: vec![Solid {
            shape: Shape::Box {
                size_m: Vector3::new(0.03, 0.03, 0.03),
            },
            pose: Isometry3::from_parts(
                Translation3::new(0.26, 0.02, 0.015),
                UnitQuaternion::identity(),
            ),
            color: [200, 30, 30],
        }],
    };
    let placement = SheetPlacement {
        x_min: 0.163,
        x_max: 0.337,
        y_min: -0.087,
        y_max: 0.087,
        marker_radius_m: 0.0105,
    };
    sheet_art(SheetDesign::Classic, &placement, &mut scene);
    let intrinsics = Intrinsics {
        distortion: [0.0; 5],
        ..Intrinsics::ned2()
    };
    let camera = look_at(
        &Point3::new(0.25, 0.0, 0.3),
        &Point3::new(0.25, 0.0, 0.0),
        &Vector3::x(),
    );
    let mut rgb = vec![0u8; 640 * 480 * 3];
    Renderer::new(intrinsics, RenderOptions::default())
        .render_into(&scene, &camera, &mut rgb)
        .unwrap();
    let rgba: Vec<u8> = rgb
        .chunks(3)
        .flat_map(|p| [p[0], p[1], p[2], 255])
        .collect();
    let dir = std::env::temp_dir().join(format!("robotd-detect-png-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let png = dir.join("frame.png");
    image::save_buffer_with_format(
        &png,
        &rgba,
        640,
        480,
        image::ExtendedColorType::Rgba8,
        image::ImageFormat::Png,
    )
    .unwrap();
    let report = detect(&[], &png);
    assert_eq!(report["workspace_found"], true, "{report:#}");
    let found = objects(&report);
    assert_eq!(found.len(), 1, "{report:#}");
    assert!(
        found[0]["label"].as_str().unwrap().contains("red"),
        "{report:#}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
