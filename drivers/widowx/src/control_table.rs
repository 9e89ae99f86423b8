//! The servos of a WidowX 250 s and the DYNAMIXEL X-series control-table items robotd uses.
//!
//! Nine servos on one bus: the six joints' masters (waist 1, shoulder 2, elbow 4, forearm roll
//! 6, wrist angle 7, wrist rotate 8), two shadows that double the shoulder and the elbow (3
//! follows 2, 5 follows 4, mirrored) and the gripper (9). Positions are 4096 ticks per turn
//! with 2048 at 0 rad. Addresses and units: `docs/dynamixel.md`.

/// Servo IDs of the six joints, base to wrist (the shadows are not listed: they follow).
pub const JOINT_IDS: [u8; 6] = [1, 2, 4, 6, 7, 8];
/// Shadow servo → the master whose Secondary ID it takes (it executes the master's packets,
/// mirrored by Drive Mode "reverse").
pub const SHADOWS: [(u8, u8); 2] = [(3, 2), (5, 4)];
/// The gripper servo.
pub const GRIPPER_ID: u8 = 9;
/// Every servo on the bus, in ID order.
pub const ALL_IDS: [u8; 9] = [1, 2, 3, 4, 5, 6, 7, 8, 9];

/// What the servo `id` moves, for messages ("servo 4 (elbow)").
pub fn servo_name(id: u8) -> &'static str {
    match id {
        1 => "waist",
        2 => "shoulder",
        3 => "shoulder shadow",
        4 => "elbow",
        5 => "elbow shadow",
        6 => "forearm roll",
        7 => "wrist angle",
        8 => "wrist rotate",
        9 => "gripper",
        _ => "not a WidowX servo",
    }
}

/// Model Number of an XM430-W350.
pub const XM430_W350: u16 = 1020;
/// Model Number of an XL430-W250.
pub const XL430_W250: u16 = 1060;

/// Which models robotd accepts at `id` (no source settles which of the wrist servos are
/// XL430s, so both are accepted there; see docs/dynamixel.md).
pub fn accepted_models(id: u8) -> &'static [u16] {
    match id {
        1..=7 => &[XM430_W350],
        _ => &[XM430_W350, XL430_W250],
    }
}

/// A servo model's name, for messages.
pub fn model_name(model: u16) -> String {
    match model {
        XM430_W350 => "XM430-W350".into(),
        XL430_W250 => "XL430-W250".into(),
        other => format!("model {other}"),
    }
}

/// Control-table addresses (identical on the XM430 and XL430 for every item used here).
pub mod address {
    /// Model Number (2 bytes, read-only).
    pub const MODEL_NUMBER: u16 = 0;
    /// Firmware Version (1 byte, read-only).
    pub const FIRMWARE_VERSION: u16 = 6;
    /// Drive Mode (1 byte, EEPROM): bit 0 = reverse direction.
    pub const DRIVE_MODE: u16 = 10;
    /// Operating Mode (1 byte, EEPROM): 3 = position, 16 = PWM.
    pub const OPERATING_MODE: u16 = 11;
    /// Secondary ID (1 byte, EEPROM): 255 = none.
    pub const SECONDARY_ID: u16 = 12;
    /// Max Position Limit (4 bytes, EEPROM).
    pub const MAX_POSITION_LIMIT: u16 = 48;
    /// Min Position Limit (4 bytes, EEPROM).
    pub const MIN_POSITION_LIMIT: u16 = 52;
    /// Torque Enable (1 byte).
    pub const TORQUE_ENABLE: u16 = 64;
    /// Hardware Error Status (1 byte, read-only).
    pub const HARDWARE_ERROR_STATUS: u16 = 70;
    /// Goal PWM (2 bytes, signed).
    pub const GOAL_PWM: u16 = 100;
    /// Profile Acceleration (4 bytes).
    pub const PROFILE_ACCELERATION: u16 = 108;
    /// Profile Velocity (4 bytes).
    pub const PROFILE_VELOCITY: u16 = 112;
    /// Goal Position (4 bytes, signed).
    pub const GOAL_POSITION: u16 = 116;
    /// Present Current (XM) or Present Load (XL), 2 bytes, signed.
    pub const PRESENT_LOAD: u16 = 126;
    /// Present Position (4 bytes, signed).
    pub const PRESENT_POSITION: u16 = 132;
}

/// Operating Mode: position control.
pub const MODE_POSITION: u8 = 3;
/// Operating Mode: PWM (voltage) control, what the gripper uses so it can squeeze an object.
pub const MODE_PWM: u8 = 16;
/// Drive Mode bit 0: reverse direction (the shadows).
pub const DRIVE_REVERSE: u8 = 1;

/// Ticks per turn.
pub const TICKS_PER_TURN: f64 = 4096.0;
/// The tick at 0 rad.
pub const ZERO_TICK: i32 = 2048;

/// Radians → ticks (rounded).
pub fn rad_to_ticks(rad: f64) -> i32 {
    ZERO_TICK + (rad * TICKS_PER_TURN / std::f64::consts::TAU).round() as i32
}

/// Ticks → radians.
pub fn ticks_to_rad(ticks: i32) -> f64 {
    f64::from(ticks - ZERO_TICK) * std::f64::consts::TAU / TICKS_PER_TURN
}

/// What each bit of Hardware Error Status (address 70) means.
pub fn hardware_error_reasons(status: u8) -> Vec<&'static str> {
    const BITS: [(u8, &str); 5] = [
        (0x01, "input voltage out of range"),
        (0x04, "overheating"),
        (0x08, "motor encoder error"),
        (0x10, "electrical shock"),
        (0x20, "overload"),
    ];
    let mut reasons: Vec<&str> = BITS
        .iter()
        .filter(|(bit, _)| status & bit != 0)
        .map(|(_, reason)| *reason)
        .collect();
    if reasons.is_empty() && status != 0 {
        reasons.push("unknown hardware error");
    }
    reasons
}

/// The text of a status packet's error number (bits 0–6 of its error byte).
pub fn status_error_name(number: u8) -> &'static str {
    match number {
        1 => "result fail",
        2 => "instruction error",
        3 => "CRC error",
        4 => "data range error",
        5 => "data length error",
        6 => "data limit error",
        7 => "access error",
        _ => "unknown error",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_and_radians_round_trip() {
        assert_eq!(rad_to_ticks(0.0), 2048);
        assert_eq!(rad_to_ticks(std::f64::consts::PI), 4096);
        assert_eq!(rad_to_ticks(-std::f64::consts::FRAC_PI_2), 1024);
        for ticks in [0, 1, 1000, 2048, 3000, 4095] {
            assert_eq!(rad_to_ticks(ticks_to_rad(ticks)), ticks);
        }
    }

    #[test]
    fn hardware_errors_are_named() {
        assert_eq!(hardware_error_reasons(0), Vec::<&str>::new());
        assert_eq!(
            hardware_error_reasons(0x24),
            vec!["overheating", "overload"]
        );
        assert_eq!(hardware_error_reasons(0x40), vec!["unknown hardware error"]);
    }
}
