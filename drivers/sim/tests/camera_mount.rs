//! `[robot.camera.mount]` decides where the simulated camera is: the frames are rendered from
//! it and carry its pose, so a camera mounted elsewhere sees the sheet elsewhere in the image.
//! A mount that cannot be one is refused by the config's checks with the key and the reason.

use robotd_driver::config::{CameraMountConfig, RobotConfig};
use robotd_kinematics::CameraMount;
use robotd_runtime::config::{Checks, Section};

/// The frame's camera pose and the image's darkest pixels' centroid (the sheet's markers).
fn look(config: &RobotConfig) -> (nalgebra::Isometry3<f64>, [f64; 2]) {
    let mut config = config.clone();
    config.camera.noise_stddev = 0.0;
    let sim = robotd_driver_sim::open(&config).expect("the simulator opens");
    let ws = config.workspaces()[0].clone();
    let q = sim
        .robot
        .kinematics()
        .inverse(
            &robotd_kinematics::pose_to_isometry(&robotd_protocol::geometry::Pose::from_array(
                ws.observation_pose,
            )),
            None,
        )
        .expect("the observation pose is reachable");
    sim.robot.teleport(&q).unwrap();
    let (w, h) = sim.drivers.camera.size();
    let mut rgb = vec![0u8; (w * h * 3) as usize];
    let info = sim.drivers.camera.capture_into(&mut rgb).unwrap();
    let (mut sum, mut n) = ([0.0, 0.0], 0.0);
    for (i, px) in rgb.chunks_exact(3).enumerate() {
        if px.iter().all(|&c| c < 60) {
            sum[0] += (i % w as usize) as f64;
            sum[1] += (i / w as usize) as f64;
            n += 1.0;
        }
    }
    assert!(n > 50.0, "the markers are in view ({n} dark pixels)");
    (info.camera_pose, [sum[0] / n, sum[1] / n])
}

fn ned2() -> RobotConfig {
    toml::from_str("driver = \"sim-ned2\"").unwrap()
}

#[test]
fn a_moved_mount_moves_the_camera_and_what_it_sees() {
    let config = ned2();
    let nominal = CameraMount::default_for(config.model());
    let mut values = nominal.to_xyz_rpy_deg();
    values[1] += 0.02; // 2 cm along the wrist's y axis
    values[4] += 3.0; // 3° more pitch
    let mut moved = config.clone();
    moved.camera.mount = Some(CameraMountConfig::from_array(values));

    let (pose_a, markers_a) = look(&config);
    let (pose_b, markers_b) = look(&moved);
    let gap = (pose_b.translation.vector - pose_a.translation.vector).norm();
    let turn = pose_a.rotation.angle_to(&pose_b.rotation).to_degrees();
    assert!((gap - 0.02).abs() < 1e-6, "the camera moved {gap} m");
    assert!((turn - 3.0).abs() < 1e-6, "the camera turned {turn}°");
    let shift =
        ((markers_b[0] - markers_a[0]).powi(2) + (markers_b[1] - markers_a[1]).powi(2)).sqrt();
    assert!(shift > 10.0, "the sheet moved {shift:.1} px in the image");
}

#[test]
fn a_mount_that_cannot_be_one_is_refused_by_key() {
    let mut config = ned2();
    config.camera.mount = Some(CameraMountConfig::from_array([
        0.0,
        45.0,
        0.0,
        0.0,
        f64::NAN,
        0.0,
    ]));
    let mut problems = Vec::new();
    config.check(&mut Checks::new("robot", &mut problems));
    let text = format!("{problems:?}");
    assert!(
        text.contains("robot.camera.mount.y_m") && text.contains("not millimetres"),
        "{text}"
    );
    assert!(text.contains("robot.camera.mount.pitch_deg"), "{text}");
    assert!(config.camera_mount().is_err());
    assert!(robotd_driver_sim::open(&config).is_err());
}
