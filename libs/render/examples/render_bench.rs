//! Times the renderer on a typical workspace view: a sheet, 4 markers of 3 rings, 6 solids.
//!
//! ```sh
//! cargo run --release -p robotd-render --example render_bench            # timings
//! cargo run --release -p robotd-render --example render_bench -- /tmp/v  # also writes the frames
//! ```

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use robotd_render::{
    encode_jpeg, look_at, Disc, Intrinsics, RenderOptions, RenderScene, Renderer, Shape, Solid,
};
use std::time::Instant;

fn scene() -> RenderScene {
    let white = [245, 245, 242];
    let black = [20, 20, 20];
    let (x0, x1, y0, y1) = (0.15, 0.35, -0.10, 0.10);
    let z = 0.0005;
    let mut discs = Vec::new();
    for (x, y) in [(x0, y0), (x0, y1), (x1, y0), (x1, y1)] {
        for (r, c) in [(0.012, black), (0.0084, white), (0.0054, black)] {
            discs.push(Disc {
                center: Point3::new(x, y, z + 0.0001),
                radius_m: r,
                color: c,
            });
        }
    }
    let solid = |shape, x: f64, y: f64, yaw: f64, half_h: f64, color| Solid {
        shape,
        pose: Isometry3::from_parts(
            Translation3::new(x, y, half_h),
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
        ),
        color,
    };
    let cube = |s: f64| Shape::Box {
        size_m: Vector3::new(s, s, s),
    };
    let can = |r: f64, h: f64| Shape::Cylinder {
        radius_m: r,
        height_m: h,
    };
    RenderScene {
        background: [118, 96, 72],
        table_z_m: 0.0,
        quads: vec![(
            [
                Point3::new(x0 - 0.02, y0 - 0.02, z),
                Point3::new(x1 + 0.02, y0 - 0.02, z),
                Point3::new(x1 + 0.02, y1 + 0.02, z),
                Point3::new(x0 - 0.02, y1 + 0.02, z),
            ],
            white,
        )],
        discs,
        solids: vec![
            solid(cube(0.03), 0.20, 0.05, 0.3, 0.015, [200, 30, 30]),
            solid(cube(0.025), 0.30, -0.04, 0.0, 0.0125, [40, 60, 200]),
            solid(
                Shape::Box {
                    size_m: Vector3::new(0.08, 0.015, 0.01),
                },
                0.24,
                -0.06,
                1.0,
                0.005,
                [230, 200, 40],
            ),
            solid(can(0.015, 0.06), 0.31, 0.05, 0.0, 0.03, [40, 170, 60]),
            solid(can(0.02, 0.02), 0.22, -0.01, 0.0, 0.01, [240, 120, 20]),
            solid(can(0.01, 0.10), 0.27, 0.02, 0.0, 0.05, [150, 50, 170]),
        ],
    }
}

fn main() {
    let out_dir = std::env::args().nth(1);
    let scene = scene();
    // Roughly the Ned2's observation pose: 35 cm up, looking down and forward.
    let camera = look_at(
        &Point3::new(0.17, 0.0, 0.35),
        &Point3::new(0.25, 0.0, 0.0),
        &Vector3::x(),
    );
    let mut frame = vec![0u8; 640 * 480 * 3];
    for (name, lens_distortion) in [("pinhole", false), ("distorted", true)] {
        let t = Instant::now();
        let mut renderer = Renderer::new(
            Intrinsics::ned2(),
            RenderOptions {
                lens_distortion,
                ..RenderOptions::default()
            },
        );
        let setup = t.elapsed();
        let mut times = Vec::with_capacity(100);
        for _ in 0..100 {
            let t = Instant::now();
            renderer
                .render_into(&scene, &camera, &mut frame)
                .expect("render");
            times.push(t.elapsed());
        }
        times.sort();
        let t = Instant::now();
        let jpeg = encode_jpeg(&frame, 640, 480, 85).expect("jpeg");
        let jpeg_time = t.elapsed();
        println!(
            "{name:>9}: render p50 {:.2} ms, p90 {:.2} ms, max {:.2} ms (setup {:.1} ms); jpeg q85 {:.2} ms, {} kB",
            times[50].as_secs_f64() * 1e3,
            times[90].as_secs_f64() * 1e3,
            times[99].as_secs_f64() * 1e3,
            setup.as_secs_f64() * 1e3,
            jpeg_time.as_secs_f64() * 1e3,
            jpeg.len() / 1024,
        );
        if let Some(dir) = &out_dir {
            let path = format!("{dir}/{name}.jpg");
            std::fs::create_dir_all(dir).expect("output directory");
            std::fs::write(&path, &jpeg).expect("write jpeg");
            let raw = format!("{dir}/{name}.rgb");
            std::fs::write(&raw, &frame).expect("write raw frame");
            println!("           wrote {path} and {raw} (raw RGB8 640x480)");
        }
    }
}
