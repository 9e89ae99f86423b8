//! What `robotd fake-niryo` and `robotd fake-widowx` can get wrong on purpose, so that
//! `robotd commission` has something to measure: a camera mounted elsewhere than robotd
//! believes (`--mount-offset`), images the robot already rectified (`fake-niryo --rectified`),
//! a gripper whose mechanical range is not the configured one (`fake-widowx --gripper-ticks`),
//! joints that obey a stop late (`fake-widowx --stopping-lag-ms`), motions that start late
//! (`fake-niryo --stopping-lag-ms`; both in the fakes' crates).
//!
//! The fake simulates the *true* robot; robotd, started with the same config file, keeps
//! believing the configured values. For the mount, the fake renders from the configured mount
//! moved by the offset, expressed in the camera's own optical frame (x = image right,
//! y = image down, z = viewing direction): `--mount-offset 8,0,0,0,3,0` is a camera 8 mm to
//! the image's right of where robotd believes it is, turned 3° about the image's vertical axis.

use anyhow::{bail, Context, Result};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use robotd_config::Config;
use robotd_driver::config::CameraMountConfig;

/// Parses `DX_MM,DY_MM,DZ_MM,DROLL_DEG,DPITCH_DEG,DYAW_DEG` (`--mount-offset`).
pub fn parse_mount_offset(text: &str) -> Result<Isometry3<f64>> {
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("--mount-offset {text:?}: not six numbers"))?;
    let [x, y, z, roll, pitch, yaw] = values[..] else {
        bail!(
            "--mount-offset {text:?}: needs six numbers, DX_MM,DY_MM,DZ_MM,DROLL_DEG,DPITCH_DEG,\
             DYAW_DEG (e.g. 8,0,0,0,3,0), got {}",
            values.len()
        );
    };
    if values.iter().any(|v| !v.is_finite()) || [x, y, z].iter().any(|v| v.abs() > 100.0) {
        bail!("--mount-offset {text:?}: millimetres up to 100 and finite degrees");
    }
    Ok(Isometry3::from_parts(
        Translation3::new(x / 1000.0, y / 1000.0, z / 1000.0),
        UnitQuaternion::from_euler_angles(roll.to_radians(), pitch.to_radians(), yaw.to_radians()),
    ))
}

/// Makes `config`'s camera mount the true one: the configured mount moved by `offset`.
pub fn apply_mount_offset(config: &mut Config, offset: &Isometry3<f64>) -> Result<()> {
    let believed = config.robot.camera_mount().context("robot.camera.mount")?;
    let truth = believed.offset_by(offset);
    config.robot.camera.mount = Some(CameraMountConfig::from_array(truth.to_xyz_rpy_deg()));
    Ok(())
}

/// Parses `CLOSED,OPEN` servo ticks (`--gripper-ticks`).
pub fn parse_ticks(text: &str) -> Result<(u16, u16)> {
    let Some((closed, open)) = text.split_once(',') else {
        bail!("--gripper-ticks {text:?}: write CLOSED,OPEN ticks, e.g. 1500,2600");
    };
    let tick = |v: &str| {
        v.trim()
            .parse::<u16>()
            .ok()
            .filter(|t| *t < 4096)
            .with_context(|| format!("--gripper-ticks {text:?}: {v:?} is not a tick (0 to 4095)"))
    };
    let (closed, open) = (tick(closed)?, tick(open)?);
    if closed == open {
        bail!("--gripper-ticks {text:?}: closed and open must differ");
    }
    Ok((closed, open))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_and_ticks_parse_or_say_why() {
        let offset = parse_mount_offset("8, 0, 0, 0, 3, 0").unwrap();
        assert!((offset.translation.vector.x - 0.008).abs() < 1e-12);
        assert!((offset.rotation.angle().to_degrees() - 3.0).abs() < 1e-9);
        let short = parse_mount_offset("8,0").unwrap_err().to_string();
        assert!(short.contains("six numbers"), "{short}");
        assert_eq!(parse_ticks("1500,2600").unwrap(), (1500, 2600));
        assert!(parse_ticks("1500")
            .unwrap_err()
            .to_string()
            .contains("CLOSED,OPEN"));
        assert!(parse_ticks("1500,5000").is_err());
    }
}
