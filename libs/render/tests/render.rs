//! What a detector will rely on: things appear where the pinhole model says, with the right
//! size and colour, and the renderer survives any input.

use nalgebra::{Isometry3, Point2, Point3, Translation3, UnitQuaternion, Vector3};
use robotd_render::{
    encode_jpeg, look_at, Disc, Intrinsics, RenderError, RenderOptions, RenderScene, Renderer, Rgb,
    Shape, Solid,
};

const W: usize = 640;
const H: usize = 480;
const TABLE: Rgb = [118, 96, 72];
const WHITE: Rgb = [245, 245, 242];

fn clean() -> RenderOptions {
    RenderOptions {
        noise_stddev: 0.0,
        lens_distortion: false,
        seed: 7,
        shading: true,
    }
}

fn render(scene: &RenderScene, camera: &Isometry3<f64>, options: RenderOptions) -> Vec<u8> {
    let mut renderer = Renderer::new(Intrinsics::ned2(), options);
    let mut frame = vec![0u8; W * H * 3];
    renderer.render_into(scene, camera, &mut frame).unwrap();
    frame
}

/// Camera 40 cm above (0.25, 0), looking straight down, image top towards +x.
fn overhead() -> Isometry3<f64> {
    look_at(
        &Point3::new(0.25, 0.0, 0.4),
        &Point3::new(0.25, 0.0, 0.0),
        &Vector3::x(),
    )
}

fn scene(solids: Vec<Solid>) -> RenderScene {
    RenderScene {
        background: TABLE,
        table_z_m: 0.0,
        quads: vec![],
        discs: vec![],
        solids,
    }
}

fn cube(x: f64, y: f64, side: f64, color: Rgb) -> Solid {
    Solid {
        shape: Shape::Box {
            size_m: Vector3::new(side, side, side),
        },
        pose: Isometry3::translation(x, y, side / 2.0),
        color,
    }
}

fn pixel(frame: &[u8], u: usize, v: usize) -> Rgb {
    let i = (v * W + u) * 3;
    [frame[i], frame[i + 1], frame[i + 2]]
}

fn at(frame: &[u8], p: Point2<f64>) -> Rgb {
    pixel(frame, p.x.round() as usize, p.y.round() as usize)
}

fn close(a: Rgb, b: Rgb, tol: i32) -> bool {
    a.iter()
        .zip(b)
        .all(|(&x, y)| (i32::from(x) - i32::from(y)).abs() <= tol)
}

/// Centroid and count of the pixels matching `pred`.
fn blob(frame: &[u8], pred: impl Fn(Rgb) -> bool) -> (Point2<f64>, usize) {
    let (mut su, mut sv, mut n) = (0.0, 0.0, 0usize);
    for v in 0..H {
        for u in 0..W {
            if pred(pixel(frame, u, v)) {
                su += u as f64;
                sv += v as f64;
                n += 1;
            }
        }
    }
    (Point2::new(su / n as f64, sv / n as f64), n)
}

fn project(camera: &Isometry3<f64>, x: f64, y: f64, z: f64) -> Point2<f64> {
    Intrinsics::ned2()
        .project(&camera.inverse(), &Point3::new(x, y, z))
        .unwrap()
}

#[test]
fn a_box_from_above_appears_where_project_says_with_the_right_size() {
    let green = [40, 180, 60];
    let camera = overhead();
    let intr = Intrinsics::ned2();
    // Straight below the camera: only its top is visible.
    let frame = render(&scene(vec![cube(0.25, 0.0, 0.04, green)]), &camera, clean());
    let (centroid, count) = blob(&frame, |c| close(c, green, 40));
    let expected = project(&camera, 0.25, 0.0, 0.02);
    assert!(
        (centroid - expected).norm() < 2.0,
        "centroid {centroid} vs projected centre {expected}"
    );
    // The top face, 36 cm from the camera: 4 cm → fx·0.04/0.36 by fy·0.04/0.36 pixels.
    let area = intr.fx * 0.04 / 0.36 * (intr.fy * 0.04 / 0.36);
    let ratio = (count as f64 / area).sqrt();
    assert!((ratio - 1.0).abs() < 0.05, "side length ratio {ratio}");

    // Off to one side: the top face (full brightness) is still centred on its projection.
    let frame = render(
        &scene(vec![cube(0.30, 0.06, 0.04, green)]),
        &camera,
        clean(),
    );
    let (top, count) = blob(&frame, |c| close(c, green, 3));
    let expected = project(&camera, 0.30, 0.06, 0.04);
    assert!((top - expected).norm() < 1.0, "top {top} vs {expected}");
    assert!(((count as f64 / area).sqrt() - 1.0).abs() < 0.05);
    // Its sides show too, darker but the same hue.
    let (_, sides) = blob(&frame, |c| {
        c[1] > c[0] + 30 && c[1] > c[2] + 30 && !close(c, green, 3)
    });
    assert!(sides > 100, "{sides} side pixels");
}

#[test]
fn colours_sheet_and_table() {
    let red = [200, 30, 30];
    let camera = overhead();
    let mut s = scene(vec![cube(0.30, -0.05, 0.03, red)]);
    s.quads.push((
        [
            Point3::new(0.15, 0.05, 0.0005),
            Point3::new(0.22, 0.05, 0.0005),
            Point3::new(0.22, 0.12, 0.0005),
            Point3::new(0.15, 0.12, 0.0005),
        ],
        WHITE,
    ));
    let frame = render(&s, &camera, RenderOptions::default());
    let c = at(&frame, project(&camera, 0.30, -0.05, 0.03));
    assert!(c[0] > 150 && c[1] < 70 && c[2] < 70, "red box looks {c:?}");
    let c = at(&frame, project(&camera, 0.185, 0.085, 0.0));
    assert!(c.iter().all(|&v| v > 230), "sheet looks {c:?}");
    let c = at(&frame, project(&camera, 0.30, 0.10, 0.0));
    assert!(close(c, TABLE, 10), "table looks {c:?}");
    // Corners of the image are table too.
    assert!(close(pixel(&frame, 2, 2), TABLE, 10));
    assert!(close(pixel(&frame, W - 3, H - 3), TABLE, 10));
}

#[test]
fn box_tops_are_brighter_than_their_sides_and_keep_their_hue() {
    let blue = [40, 60, 200];
    // Oblique view: looking forward and down at the cube.
    let camera = look_at(
        &Point3::new(0.05, 0.0, 0.25),
        &Point3::new(0.3, 0.0, 0.0),
        &Vector3::z(),
    );
    let frame = render(&scene(vec![cube(0.3, 0.0, 0.04, blue)]), &camera, clean());
    let top = at(&frame, project(&camera, 0.3, 0.0, 0.04));
    let side = at(&frame, project(&camera, 0.28, 0.0, 0.02));
    assert_eq!(top, blue);
    assert!(
        side[2] < top[2] && side[2] > side[0] && side[2] > side[1],
        "side {side:?}"
    );
}

#[test]
fn a_cube_standing_on_a_slab_is_drawn_over_it() {
    // Depth sorting by centres (or by face centroids) gets this wrong: the slab's centre is
    // nearer the camera than the cube's.
    let (blue, red) = ([40, 60, 200], [200, 30, 30]);
    let camera = look_at(
        &Point3::new(0.0, 0.0, 0.3),
        &Point3::new(0.3, 0.0, 0.0),
        &Vector3::z(),
    );
    let slab = Solid {
        shape: Shape::Box {
            size_m: Vector3::new(0.3, 0.2, 0.02),
        },
        pose: Isometry3::translation(0.2, 0.0, 0.01),
        color: blue,
    };
    let on_top = Solid {
        shape: Shape::Box {
            size_m: Vector3::new(0.04, 0.04, 0.04),
        },
        pose: Isometry3::translation(0.3, 0.0, 0.04),
        color: red,
    };
    for solids in [vec![slab, on_top], vec![on_top, slab]] {
        let frame = render(&scene(solids), &camera, clean());
        let c = at(&frame, project(&camera, 0.28, 0.0, 0.023));
        assert!(c[0] > c[2] && c[0] > 60, "cube's front face looks {c:?}");
    }
}

#[test]
fn cylinders_show_their_top_disc() {
    let yellow = [220, 200, 30];
    let camera = overhead();
    let can = Solid {
        shape: Shape::Cylinder {
            radius_m: 0.02,
            height_m: 0.06,
        },
        pose: Isometry3::translation(0.25, 0.0, 0.03),
        color: yellow,
    };
    let frame = render(&scene(vec![can]), &camera, clean());
    let (centroid, count) = blob(&frame, |c| close(c, yellow, 3));
    let expected = project(&camera, 0.25, 0.0, 0.06);
    assert!((centroid - expected).norm() < 1.0);
    let r_px = Intrinsics::ned2().fx * 0.02 / 0.34;
    let ratio = (count as f64 / (std::f64::consts::PI * r_px * r_px)).sqrt();
    assert!((ratio - 1.0).abs() < 0.05, "radius ratio {ratio}");
}

#[test]
fn marker_rings_are_concentric() {
    let camera = overhead();
    let mut s = scene(vec![]);
    for (r, c) in [(0.02, [20, 20, 20]), (0.014, WHITE), (0.009, [20, 20, 20])] {
        s.discs.push(Disc {
            center: Point3::new(0.3, 0.05, 0.0005),
            radius_m: r,
            color: c,
        });
    }
    let frame = render(&s, &camera, clean());
    let centre = project(&camera, 0.3, 0.05, 0.0);
    assert!(close(at(&frame, centre), [20, 20, 20], 2));
    let ring = project(&camera, 0.3 + 0.0115, 0.05, 0.0);
    assert!(close(at(&frame, ring), WHITE, 2));
    let outer = project(&camera, 0.3, 0.05 + 0.017, 0.0);
    assert!(close(at(&frame, outer), [20, 20, 20], 2));
    let (c, _) = blob(&frame, |c| close(c, WHITE, 2));
    assert!((c - centre).norm() < 1.0);
}

#[test]
fn solids_behind_or_around_the_camera_draw_nothing() {
    let camera = overhead();
    let empty = render(&scene(vec![]), &camera, clean());
    let behind = cube(0.25, 0.0, 0.04, [200, 30, 30]);
    let behind = Solid {
        pose: Isometry3::translation(0.25, 0.0, 0.6),
        ..behind
    };
    // A huge box around the camera: all its faces turn away from it.
    let around = Solid {
        shape: Shape::Box {
            size_m: Vector3::new(3.0, 3.0, 3.0),
        },
        pose: Isometry3::translation(0.25, 0.0, 0.4),
        color: [0, 255, 0],
    };
    let frame = render(&scene(vec![behind, around]), &camera, clean());
    assert!(frame == empty);
}

#[test]
fn a_quad_straddling_the_camera_plane_is_clipped() {
    // Camera at the origin looking along +x; a white strip below it from x = −1 to +1.
    let camera = look_at(
        &Point3::origin(),
        &Point3::new(1.0, 0.0, 0.0),
        &Vector3::z(),
    );
    let mut s = scene(vec![]);
    s.table_z_m = -0.5;
    s.quads.push((
        [
            Point3::new(-1.0, -0.3, -0.1),
            Point3::new(1.0, -0.3, -0.1),
            Point3::new(1.0, 0.3, -0.1),
            Point3::new(-1.0, 0.3, -0.1),
        ],
        WHITE,
    ));
    let frame = render(&s, &camera, clean());
    let intr = Intrinsics::ned2();
    // The far edge (x = 1) is at v = cy + fy·0.1; below it, down to the image's bottom, white.
    let edge = intr.cy + intr.fy * 0.1;
    let u = intr.cx.round() as usize;
    for v in 0..H {
        let c = pixel(&frame, u, v);
        let white = close(c, WHITE, 2);
        if (v as f64) > edge + 2.0 {
            assert!(white, "row {v} should be the strip: {c:?}");
        } else if (v as f64) < edge - 2.0 {
            assert!(!white, "row {v} should not be the strip: {c:?}");
        }
    }
}

#[test]
fn noise_changes_pixels_but_not_the_mean() {
    let flat = [100, 120, 140];
    let camera = overhead();
    let mut s = scene(vec![]);
    s.background = flat;
    let frame = render(&s, &camera, RenderOptions::default());
    let mut sum = [0.0f64; 3];
    let mut sq = [0.0f64; 3];
    let mut changed = 0usize;
    for px in frame.chunks_exact(3) {
        for ch in 0..3 {
            let d = f64::from(px[ch]) - f64::from(flat[ch]);
            sum[ch] += d;
            sq[ch] += d * d;
        }
        changed += usize::from(px != flat);
    }
    let n = (W * H) as f64;
    for ch in 0..3 {
        let mean = sum[ch] / n;
        let sd = (sq[ch] / n).sqrt();
        assert!(mean.abs() < 1.0, "channel {ch} mean off by {mean}");
        assert!((sd - 2.0).abs() < 0.3, "channel {ch} stddev {sd}");
    }
    assert!(changed > W * H / 2, "only {changed} pixels changed");

    // Same seed, same frames; the next frame has fresh noise.
    let mut a = Renderer::new(Intrinsics::ned2(), RenderOptions::default());
    let mut b = Renderer::new(Intrinsics::ned2(), RenderOptions::default());
    let (mut fa, mut fb) = (vec![0u8; W * H * 3], vec![0u8; W * H * 3]);
    a.render_into(&s, &camera, &mut fa).unwrap();
    b.render_into(&s, &camera, &mut fb).unwrap();
    assert!(fa == fb);
    a.render_into(&s, &camera, &mut fa).unwrap();
    assert!(fa != fb);
}

#[test]
fn lens_distortion_pulls_corner_points_inwards() {
    let camera = overhead();
    let intr = Intrinsics::ned2();
    let cam_from_world = camera.inverse();
    // A small dark disc that the pinhole model puts near the bottom-right corner.
    let world = camera
        * Point3::new(
            0.38 * (580.0 - intr.cx) / intr.fx,
            0.38 * (420.0 - intr.cy) / intr.fy,
            0.38,
        );
    let world = Point3::new(world.x, world.y, 0.02);
    let ideal = intr.project(&cam_from_world, &world).unwrap();
    let mut s = scene(vec![]);
    s.background = [230, 230, 230];
    s.discs.push(Disc {
        center: world,
        radius_m: 0.004,
        color: [20, 20, 20],
    });
    let dark = |c: Rgb| c[0] < 120;

    let straight = render(&s, &camera, clean());
    let (c0, _) = blob(&straight, dark);
    assert!((c0 - ideal).norm() < 0.5, "undistorted {c0} vs {ideal}");

    let distorted = render(
        &s,
        &camera,
        RenderOptions {
            lens_distortion: true,
            ..clean()
        },
    );
    let (c1, n) = blob(&distorted, dark);
    assert!(n > 20);
    let principal = Point2::new(intr.cx, intr.cy);
    let moved_in = (ideal - principal).norm() - (c1 - principal).norm();
    assert!(
        moved_in > 20.0,
        "barrel distortion moved the point in by {moved_in} px"
    );
    let predicted = intr.distort(ideal);
    assert!(
        (c1 - predicted).norm() < 1.5,
        "at {c1}, model says {predicted}"
    );
    // Every output pixel is written, corners included.
    assert!(close(pixel(&distorted, 0, 0), [230, 230, 230], 2));
    assert!(close(pixel(&distorted, W - 1, H - 1), [230, 230, 230], 2));
}

#[test]
fn bad_input_is_an_error_or_draws_nothing_never_a_panic() {
    let camera = overhead();
    let mut renderer = Renderer::new(Intrinsics::ned2(), clean());
    let s = scene(vec![cube(0.25, 0.0, 0.04, [200, 30, 30])]);
    let mut short = vec![0u8; W * H * 3 - 1];
    assert_eq!(
        renderer.render_into(&s, &camera, &mut short),
        Err(RenderError::BufferSize {
            expected: W * H * 3,
            got: W * H * 3 - 1
        })
    );
    let mut frame = vec![0u8; W * H * 3];
    let nan = Isometry3::translation(f64::NAN, 0.0, 0.4);
    assert_eq!(
        renderer.render_into(&s, &nan, &mut frame),
        Err(RenderError::InvalidCameraPose)
    );
    let parallel_up = look_at(
        &Point3::new(0.0, 0.0, 1.0),
        &Point3::origin(),
        &Vector3::z(),
    );
    assert!(renderer.render_into(&s, &parallel_up, &mut frame).is_err());

    // NaN, infinite, zero-sized and gigantic things in the scene.
    let weird = RenderScene {
        background: TABLE,
        table_z_m: f64::NAN,
        quads: vec![
            ([Point3::new(f64::NAN, 0.0, 0.0); 4], WHITE),
            ([Point3::new(0.2, 0.0, 0.0); 4], WHITE),
            (
                [
                    Point3::new(-1e300, -1e300, 0.0),
                    Point3::new(1e300, -1e300, 0.0),
                    Point3::new(1e300, 1e300, 0.0),
                    Point3::new(-1e300, 1e300, 0.0),
                ],
                WHITE,
            ),
        ],
        discs: vec![
            Disc {
                center: Point3::new(0.25, 0.0, 0.0),
                radius_m: f64::INFINITY,
                color: WHITE,
            },
            Disc {
                center: Point3::new(0.25, 0.0, 0.0),
                radius_m: -1.0,
                color: WHITE,
            },
            Disc {
                center: Point3::new(0.25, 0.0, 0.4),
                radius_m: 0.1,
                color: WHITE,
            },
        ],
        solids: vec![
            Solid {
                shape: Shape::Box {
                    size_m: Vector3::new(f64::NAN, 1.0, 1.0),
                },
                pose: Isometry3::identity(),
                color: WHITE,
            },
            Solid {
                shape: Shape::Cylinder {
                    radius_m: 0.02,
                    height_m: 0.05,
                },
                pose: Isometry3::from_parts(
                    Translation3::new(0.25, 0.0, 0.0),
                    UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(
                        f64::NAN,
                        0.0,
                        0.0,
                        0.0,
                    )),
                ),
                color: WHITE,
            },
            Solid {
                shape: Shape::Box {
                    size_m: Vector3::new(1e200, 1e200, 1e200),
                },
                pose: Isometry3::translation(0.0, 0.0, -1e200),
                color: WHITE,
            },
            Solid {
                shape: Shape::Box {
                    size_m: Vector3::new(0.1, 0.1, 0.1),
                },
                pose: Isometry3::translation(0.25, 0.0, 0.4),
                color: WHITE,
            },
        ],
    };
    renderer.render_into(&weird, &camera, &mut frame).unwrap();
    let mut distorting = Renderer::new(
        Intrinsics::ned2(),
        RenderOptions {
            lens_distortion: true,
            noise_stddev: f64::NAN,
            ..clean()
        },
    );
    distorting.render_into(&weird, &camera, &mut frame).unwrap();

    // Unusable intrinsics: an error at render time, not a panic at construction.
    for intr in [
        Intrinsics {
            width: 0,
            ..Intrinsics::ned2()
        },
        Intrinsics {
            fx: f64::NAN,
            ..Intrinsics::ned2()
        },
        Intrinsics {
            width: 100_000,
            height: 100_000,
            ..Intrinsics::ned2()
        },
    ] {
        let mut r = Renderer::new(
            intr,
            RenderOptions {
                lens_distortion: true,
                ..clean()
            },
        );
        let mut out = vec![0u8; intr.width as usize * 3];
        assert!(r.render_into(&s, &camera, &mut out).is_err());
    }
    let huge = Intrinsics {
        width: u32::MAX,
        height: u32::MAX,
        ..Intrinsics::ned2()
    };
    let mut r = Renderer::new(huge, clean());
    assert!(r.render_into(&s, &camera, &mut []).is_err());
    assert!(encode_jpeg(&[], u32::MAX, u32::MAX, 85).is_err());

    // A rotation slightly off unit length is renormalised, not refused.
    let q = camera.rotation.into_inner() * 1.001;
    let drifted = Isometry3::from_parts(camera.translation, UnitQuaternion::new_unchecked(q));
    renderer.render_into(&s, &drifted, &mut frame).unwrap();
    let zero = Isometry3::from_parts(
        camera.translation,
        UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(0.0, 0.0, 0.0, 0.0)),
    );
    assert!(renderer.render_into(&s, &zero, &mut frame).is_err());
}

#[test]
fn jpeg_round_trip() {
    let frame = render(
        &scene(vec![cube(0.25, 0.0, 0.04, [200, 30, 30])]),
        &overhead(),
        RenderOptions::default(),
    );
    let jpeg = encode_jpeg(&frame, W as u32, H as u32, 85).unwrap();
    let decoded = image::load_from_memory_with_format(&jpeg, image::ImageFormat::Jpeg).unwrap();
    assert_eq!((decoded.width(), decoded.height()), (640, 480));
    let rgb = decoded.to_rgb8();
    let p = project(&overhead(), 0.25, 0.0, 0.04);
    let c = rgb.get_pixel(p.x.round() as u32, p.y.round() as u32).0;
    assert!(c[0] > 150 && c[1] < 80, "decoded centre {c:?}");
    assert!(matches!(
        encode_jpeg(&frame[1..], W as u32, H as u32, 85),
        Err(RenderError::BufferSize { .. })
    ));
    assert!(encode_jpeg(&[], 0, 0, 85).is_err());
}
