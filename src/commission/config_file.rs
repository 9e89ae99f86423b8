//! The config file `robotd commission --write FILE` writes: the configuration file commissioning
//! ran with (`--config`, comments and all) with the measured values set in it, so that
//! `robotd --config FILE serve` runs the robot with everything the lab configured plus what
//! was measured. Without `--config` it holds the measured values alone (over the built-in
//! defaults, as any config file is).
//!
//! What it sets, each with a comment saying how well it was measured:
//! - `robot.driver`: the driver the values were measured through;
//! - `[robot.camera.mount]`, with `measured_for`, the fingerprint of the robot it was measured
//!   on, which `robotd doctor` compares;
//! - for a Ned2, `[robot.niryo] images_rectified`;
//! - for a WidowX, `[robot.widowx]` gripper ticks and `gripper_holding_load`.
//!
//! It is always a new file: commissioning never edits one that exists (`--write` to an
//! existing path is refused before anything moves).

use super::camera::CameraReport;
use super::gripper::GripperReport;
use anyhow::{bail, Context, Result};
use robotd_config::Config;
use std::path::Path;
use toml_edit::{value, DocumentMut, Item, Table};

/// The table at the dotted `path` of `document`, made when missing.
fn table<'a>(document: &'a mut DocumentMut, path: &[&str]) -> Result<&'a mut Table> {
    let mut at: &mut Table = document.as_table_mut();
    for (depth, key) in path.iter().enumerate() {
        let item = at.entry(key).or_insert_with(|| {
            let mut table = Table::new();
            table.set_implicit(depth + 1 < path.len());
            Item::Table(table)
        });
        let name = path[..=depth].join(".");
        // An inline table (`mount = { … }`) becomes a table of its own.
        if let Some(inline) = item.as_inline_table().cloned() {
            *item = Item::Table(inline.into_table());
        }
        let Some(next) = item.as_table_mut() else {
            bail!("the config file's `{name}` is not a table: commissioning cannot set its keys");
        };
        at = next;
    }
    Ok(at)
}

/// How each comment this file writes starts; one left by an earlier commissioning (the
/// file given as `--config` was written by one) is replaced, the user's own are kept.
const MARK: &str = "# Measured by `robotd commission`";

/// Puts `comment` (lines without `#`, the first starting with [`MARK`]'s words) above the
/// table at `path`, below the comments already there.
fn comment(document: &mut DocumentMut, path: &[&str], comment: &str) -> Result<()> {
    let decor = table(document, path)?.decor_mut();
    let before = decor
        .prefix()
        .and_then(|p| p.as_str())
        .unwrap_or_default()
        .to_owned();
    // The user's part: everything above an earlier commissioning's comment.
    let kept = match before.find(MARK) {
        Some(at) => before[..at].to_owned(),
        None => before,
    };
    let kept = if kept.trim().is_empty() {
        "\n".to_owned()
    } else {
        kept
    };
    let lines: String = comment.lines().map(|l| format!("# {l}\n")).collect();
    decor.set_prefix(format!("{kept}{lines}"));
    Ok(())
}

/// The first lines of the file.
const HEADER: &str = "# Written by `robotd commission`: the config file it ran with (if any) and \
                      the values it\n# measured on the robot. Run robotd with it: robotd \
                      --config THIS_FILE serve\n";

/// The text of the file: `base` (the `--config` file's text, or empty) with the measured
/// values set.
pub fn render(
    base: &str,
    config: &Config,
    camera: Option<&CameraReport>,
    gripper: Option<&GripperReport>,
) -> Result<String> {
    let base = base.strip_prefix(HEADER).unwrap_or(base);
    let mut document: DocumentMut = base
        .parse()
        .context("reading the config file commissioning ran with")?;
    table(&mut document, &["robot"])?["driver"] = value(config.robot.driver.name());
    match camera {
        Some(camera) => {
            let [x, y, z, roll, pitch, yaw] = camera.mount;
            let round = |v: f64, places: i32| (v * 10f64.powi(places)).round() / 10f64.powi(places);
            let path = ["robot", "camera", "mount"];
            let mount = table(&mut document, &path)?;
            for (key, v, places) in [
                ("x_m", x, 5),
                ("y_m", y, 5),
                ("z_m", z, 5),
                ("roll_deg", roll, 3),
                ("pitch_deg", pitch, 3),
                ("yaw_deg", yaw, 3),
            ] {
                mount[key] = value(round(v, places));
            }
            mount["measured_for"] = value(config.robot.commissioning_fingerprint());
            comment(
                &mut document,
                &path,
                &format!(
                    "Measured by `robotd commission`: hand-eye calibration on the sheet '{}', \
                     {} views,\nmarkers within {:.2} mm (rms {:.2} mm); table at z = {:.4} m.",
                    camera.workspace,
                    camera.views_used,
                    camera.residual_mm_max,
                    camera.residual_mm_rms,
                    camera.table_z_m
                ),
            )?;
            if let Some(rectified) = camera.images_rectified {
                table(&mut document, &["robot", "niryo"])?["images_rectified"] = value(rectified);
                comment(
                    &mut document,
                    &["robot", "niryo"],
                    &format!(
                        "Measured by `robotd commission`: the robot's images are {}rectified \
                         (worst marker\n{:.2} mm read as raw, {:.2} mm read as rectified).",
                        if rectified { "" } else { "not " },
                        camera.residual_mm_max_as_raw.unwrap_or(f64::NAN),
                        camera.residual_mm_max_as_rectified.unwrap_or(f64::NAN),
                    ),
                )?;
            }
        }
        None => document
            .decor_mut()
            .set_suffix("\n# The camera step did not run or failed: nothing measured.\n"),
    }
    if let Some(gripper) = gripper {
        let widowx = table(&mut document, &["robot", "widowx"])?;
        widowx["gripper_closed_ticks"] = value(i64::from(gripper.closed_ticks));
        widowx["gripper_open_ticks"] = value(i64::from(gripper.open_ticks));
        widowx["gripper_holding_load"] = value(i64::from(gripper.holding_load));
        comment(
            &mut document,
            &["robot", "widowx"],
            &format!(
                "Measured by `robotd commission`: the gripper's mechanical stops (configured: {} \
                 closed, {} open),\nand the load that counts as holding: half the stall load at \
                 the closed stop ({} at PWM {}),\nscaled to gripper_pwm (configured: {}).",
                gripper.configured_closed_ticks,
                gripper.configured_open_ticks,
                gripper.empty_close_load,
                gripper.empty_close_pwm,
                gripper.configured_holding_load,
            ),
        )?;
    }
    Ok(format!("{HEADER}{document}"))
}

/// Writes [`render`]'s text for the `--config` file `base` (if any) to `path`, a new file.
pub fn write(
    path: &Path,
    base: Option<&Path>,
    config: &Config,
    camera: Option<&CameraReport>,
    gripper: Option<&GripperReport>,
) -> Result<()> {
    let base_text = match base {
        Some(base) => std::fs::read_to_string(base)
            .with_context(|| format!("reading the config file {}", base.display()))?,
        None => String::new(),
    };
    let text = render(&base_text, config, camera, gripper)?;
    let mut file = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)
        .with_context(|| format!("creating {} (it must not exist)", path.display()))?;
    std::io::Write::write_all(&mut file, text.as_bytes())
        .with_context(|| format!("writing {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_runtime::config::LoadOptions;

    fn gripper() -> GripperReport {
        GripperReport {
            closed_ticks: 1_620,
            open_ticks: 2_980,
            configured_closed_ticks: 1_520,
            configured_open_ticks: 2_880,
            empty_close_load: 300,
            empty_close_pwm: 250,
            holding_load: 180,
            configured_holding_load: 150,
        }
    }

    #[test]
    fn the_users_file_is_kept_and_the_measured_values_set_in_it() {
        let base = "# our lab's WidowX\n[robot]\ndriver = \"widowx\"\ncontrol_rate_hz = 50\n\n\
                    # the lab's gripper, fixed in May\n[robot.widowx]\n# our gripper\n\
                    gripper_closed_ticks = 1520\ngripper_pwm = 300\n";
        let dir = tempfile::tempdir().unwrap();
        let base_path = dir.path().join("lab.toml");
        std::fs::write(&base_path, base).unwrap();
        let load = |path: &Path| {
            Config::load_with_env(
                LoadOptions {
                    file: Some(path.to_owned()),
                    overrides: Vec::new(),
                },
                Vec::<(String, String)>::new(),
            )
            .unwrap()
        };
        let config = load(&base_path);
        let text = render(base, &config, None, Some(&gripper())).unwrap();
        for kept in [
            "# our lab's WidowX",
            "# our gripper",
            "control_rate_hz = 50",
        ] {
            assert!(text.contains(kept), "{kept:?} lost:\n{text}");
        }
        let written = dir.path().join("commissioned.toml");
        std::fs::write(&written, &text).unwrap();
        let commissioned = load(&written);
        let widowx = &commissioned.robot.widowx;
        assert_eq!(
            (
                widowx.gripper_closed_ticks,
                widowx.gripper_open_ticks,
                widowx.gripper_holding_load,
                widowx.gripper_pwm
            ),
            (1_620, 2_980, 180, 300),
            "{text}"
        );
        assert_eq!(commissioned.robot.driver.name(), "widowx");

        // Commissioning again from the written file: its comment is replaced, not repeated.
        let again = render(&text, &commissioned, None, Some(&gripper())).unwrap();
        assert_eq!(again.matches(MARK).count(), 1, "{again}");
        assert_eq!(again.matches(HEADER).count(), 1, "{again}");
        assert!(
            again.contains("# the lab's gripper, fixed in May"),
            "{again}"
        );
    }

    #[test]
    fn a_key_that_is_not_a_table_is_refused_naming_it() {
        let config =
            Config::load_with_env(LoadOptions::default(), Vec::<(String, String)>::new()).unwrap();
        let error = render("robot = 3\n", &config, None, Some(&gripper())).unwrap_err();
        assert!(
            error.to_string().contains("`robot` is not a table"),
            "{error}"
        );
    }
}
