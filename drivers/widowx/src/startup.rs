//! Bringing the servo bus up: every servo pinged and its model checked, the settings the arm
//! needs written, torque on with the arm holding where it is.
//!
//! EEPROM items (operating mode, drive mode, secondary ID) can only be written with torque
//! off, and torque off drops the arm, so they are read first and written only when they
//! differ (a WidowX that was set up once is never let go on a restart). The shadows' drive
//! mode and secondary ID are written to their own IDs, as the servos require.

use crate::control_table::{
    accepted_models, address, model_name, servo_name, ALL_IDS, DRIVE_REVERSE, GRIPPER_ID,
    JOINT_IDS, MODE_POSITION, MODE_PWM, SHADOWS,
};
use crate::DxlBus;
use dynamixel2::instructions::SyncWriteData;

/// Why the bus could not be brought up; each names the servo and what to check.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StartupError {
    /// A servo did not answer its ping.
    #[error("servo {id} ({}) does not answer: {reason}; check its cable, power (12 V) and that its ID and baud rate were not changed", servo_name(*id))]
    Missing {
        /// Servo ID.
        id: u8,
        /// The bus error.
        reason: String,
    },
    /// A servo of another model answered.
    #[error("servo {id} ({}) is a {}, expected {}; is this a WidowX 250 s bus?", servo_name(*id), model_name(*found), expected.iter().map(|m| model_name(*m)).collect::<Vec<_>>().join(" or "))]
    WrongModel {
        /// Servo ID.
        id: u8,
        /// Its model number.
        found: u16,
        /// The accepted ones.
        expected: Vec<u16>,
    },
    /// A setting could not be read or written.
    #[error("servo {id} ({}): {what}: {reason}", servo_name(*id))]
    Setting {
        /// Servo ID.
        id: u8,
        /// Which setting.
        what: &'static str,
        /// The bus error.
        reason: String,
    },
}

/// The settings [`bring_up`] writes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StartupSettings {
    /// Profile Velocity of the arm servos (0 = none).
    pub profile_velocity: u32,
    /// Profile Acceleration of the arm servos (0 = none).
    pub profile_acceleration: u32,
}

/// What each servo's EEPROM must hold: (operating mode, drive-mode reverse bit, secondary ID).
fn wanted_eeprom(id: u8) -> (u8, Option<bool>, Option<u8>) {
    if id == GRIPPER_ID {
        return (MODE_PWM, None, None);
    }
    match SHADOWS.iter().find(|(shadow, _)| *shadow == id) {
        Some((_, master)) => (MODE_POSITION, Some(true), Some(*master)),
        None => (MODE_POSITION, None, None),
    }
}

/// Pings every servo, checks its model, writes what differs, and turns torque on with each
/// joint's goal at its present position.
pub fn bring_up(bus: &mut DxlBus, settings: StartupSettings) -> Result<(), StartupError> {
    for id in ALL_IDS {
        let ping = bus.ping(id).map_err(|e| StartupError::Missing {
            id,
            reason: e.to_string(),
        })?;
        let expected = accepted_models(id);
        if !expected.contains(&ping.data.model) {
            return Err(StartupError::WrongModel {
                id,
                found: ping.data.model,
                expected: expected.to_vec(),
            });
        }
    }
    for id in ALL_IDS {
        configure_eeprom(bus, id)?;
    }
    let setting = |id: u8, what: &'static str| {
        move |e: dynamixel2::TransferError| StartupError::Setting {
            id,
            what,
            reason: e.to_string(),
        }
    };
    for id in JOINT_IDS {
        bus.write_u32(
            id,
            address::PROFILE_ACCELERATION,
            settings.profile_acceleration,
        )
        .map_err(setting(id, "writing Profile Acceleration"))?;
        bus.write_u32(id, address::PROFILE_VELOCITY, settings.profile_velocity)
            .map_err(setting(id, "writing Profile Velocity"))?;
        hold_here(bus, id)?;
    }
    bus.write_u16(GRIPPER_ID, address::GOAL_PWM, 0)
        .map_err(setting(GRIPPER_ID, "writing Goal PWM"))?;
    for id in ALL_IDS {
        bus.write_u8(id, address::TORQUE_ENABLE, 1)
            .map_err(setting(id, "turning torque on"))?;
    }
    Ok(())
}

/// What [`survey`] found on one servo.
#[derive(Debug, Clone, PartialEq)]
pub struct ServoSurvey {
    /// Servo ID.
    pub id: u8,
    /// Its model, or why it could not be pinged / is the wrong model.
    pub model: Result<u16, StartupError>,
    /// Its Hardware Error Status (0 = none), when readable.
    pub hardware_error: Option<u8>,
}

/// Pings every servo, checks its model and reads its hardware error, writing nothing (for
/// `robotd doctor`).
pub fn survey(bus: &mut DxlBus) -> Vec<ServoSurvey> {
    ALL_IDS
        .iter()
        .map(|&id| {
            let model = match bus.ping(id) {
                Err(e) => Err(StartupError::Missing {
                    id,
                    reason: e.to_string(),
                }),
                Ok(ping) if !accepted_models(id).contains(&ping.data.model) => {
                    Err(StartupError::WrongModel {
                        id,
                        found: ping.data.model,
                        expected: accepted_models(id).to_vec(),
                    })
                }
                Ok(ping) => Ok(ping.data.model),
            };
            let hardware_error = model
                .is_ok()
                .then(|| bus.read_u8(id, address::HARDWARE_ERROR_STATUS).ok())
                .flatten()
                .map(|r| r.data);
            ServoSurvey {
                id,
                model,
                hardware_error,
            }
        })
        .collect()
}

/// Writes the goal of joint servo `id` to where it is, so that torque-on holds it there.
pub fn hold_here(bus: &mut DxlBus, id: u8) -> Result<(), StartupError> {
    let present =
        bus.read_u32(id, address::PRESENT_POSITION)
            .map_err(|e| StartupError::Setting {
                id,
                what: "reading Present Position",
                reason: e.to_string(),
            })?;
    bus.write_u32(id, address::GOAL_POSITION, present.data)
        .map_err(|e| StartupError::Setting {
            id,
            what: "writing Goal Position",
            reason: e.to_string(),
        })?;
    Ok(())
}

/// Brings servo `id` back after a reboot (which turns its torque off): goal at its present
/// position for a joint, PWM 0 for the gripper, then torque on.
pub fn restore_after_reboot(bus: &mut DxlBus, id: u8) -> Result<(), StartupError> {
    if JOINT_IDS.contains(&id) {
        hold_here(bus, id)?;
    } else if id == GRIPPER_ID {
        bus.write_u16(id, address::GOAL_PWM, 0)
            .map_err(|e| StartupError::Setting {
                id,
                what: "writing Goal PWM",
                reason: e.to_string(),
            })?;
    }
    bus.write_u8(id, address::TORQUE_ENABLE, 1)
        .map_err(|e| StartupError::Setting {
            id,
            what: "turning torque on",
            reason: e.to_string(),
        })?;
    Ok(())
}

/// Reads the EEPROM items of servo `id` and writes those that differ (torque off first).
fn configure_eeprom(bus: &mut DxlBus, id: u8) -> Result<(), StartupError> {
    let failed = |what: &'static str| {
        move |e: dynamixel2::TransferError| StartupError::Setting {
            id,
            what,
            reason: e.to_string(),
        }
    };
    let (mode, reverse, secondary) = wanted_eeprom(id);
    let current_mode = bus
        .read_u8(id, address::OPERATING_MODE)
        .map_err(failed("reading Operating Mode"))?
        .data;
    let current_drive = bus
        .read_u8(id, address::DRIVE_MODE)
        .map_err(failed("reading Drive Mode"))?
        .data;
    let current_secondary = bus
        .read_u8(id, address::SECONDARY_ID)
        .map_err(failed("reading Secondary ID"))?
        .data;
    let drive = match reverse {
        Some(true) => current_drive | DRIVE_REVERSE,
        Some(false) => current_drive & !DRIVE_REVERSE,
        None => current_drive,
    };
    let secondary_ok = secondary.is_none_or(|s| s == current_secondary);
    if current_mode == mode && drive == current_drive && secondary_ok {
        return Ok(());
    }
    tracing::info!(
        id,
        servo = servo_name(id),
        "writing the servo's operating mode, drive mode and secondary ID (torque off meanwhile)"
    );
    bus.write_u8(id, address::TORQUE_ENABLE, 0)
        .map_err(failed("turning torque off to write EEPROM"))?;
    if current_mode != mode {
        bus.write_u8(id, address::OPERATING_MODE, mode)
            .map_err(failed("writing Operating Mode"))?;
    }
    if drive != current_drive {
        bus.write_u8(id, address::DRIVE_MODE, drive)
            .map_err(failed("writing Drive Mode"))?;
    }
    if let Some(secondary) = secondary {
        if secondary != current_secondary {
            bus.write_u8(id, address::SECONDARY_ID, secondary)
                .map_err(failed("writing Secondary ID"))?;
        }
    }
    Ok(())
}

/// Sync-writes Goal Position of the six joint masters (the shadows follow).
pub fn write_joint_goals(bus: &mut DxlBus, ticks: &[i32; 6]) -> Result<(), dynamixel2::WriteError> {
    let data: Vec<SyncWriteData<[u8; 4]>> = JOINT_IDS
        .iter()
        .zip(ticks)
        .map(|(id, t)| SyncWriteData {
            motor_id: *id,
            data: t.to_le_bytes(),
        })
        .collect();
    bus.sync_write(address::GOAL_POSITION, 4, &data)
}
