//! One simulated DYNAMIXEL X servo: its control table and the rules a real one enforces.
//!
//! The table is 256 bytes, initialised like a factory servo (model number, ID, 1 Mbps,
//! position mode, no secondary ID, limits 0–4095). Writes follow the e-Manual: EEPROM
//! (addresses below 64) only with torque off (else Access error), read-only items refused,
//! Goal Position outside the position limits refused (Data Limit error), whole items only is
//! not enforced (the fake is lenient there, as it only needs to be as strict as robotd needs).
//! A latched hardware error sets the Alert bit of every reply, turns torque off and ignores
//! torque-on until the servo is rebooted.

use robotd_driver_widowx::control_table::address;
use std::time::{Duration, Instant};

/// Error numbers of a status packet.
pub mod error {
    /// Instruction not known.
    pub const INSTRUCTION: u8 = 2;
    /// Address or length outside the table.
    pub const DATA_RANGE: u8 = 4;
    /// Parameters of the wrong length.
    pub const DATA_LENGTH: u8 = 5;
    /// Value outside its limits.
    pub const DATA_LIMIT: u8 = 6;
    /// Read-only item, or EEPROM with torque on.
    pub const ACCESS: u8 = 7;
}

/// How long a rebooted servo stays deaf.
pub const REBOOT_TIME: Duration = Duration::from_millis(60);

/// A simulated servo.
#[derive(Debug, Clone)]
pub struct Servo {
    /// Its ID.
    pub id: u8,
    table: [u8; 256],
    deaf_until: Option<Instant>,
}

impl Servo {
    /// A factory-fresh servo of `model` with `id`, at `position` ticks.
    pub fn new(id: u8, model: u16, position: i32) -> Self {
        let mut table = [0u8; 256];
        table[0..2].copy_from_slice(&model.to_le_bytes());
        table[6] = 52; // firmware version
        table[7] = id;
        table[8] = 3; // 1 Mbps
        table[usize::from(address::OPERATING_MODE)] = 3;
        table[usize::from(address::SECONDARY_ID)] = 255;
        table[13] = 2; // protocol 2.0
        table[usize::from(address::MAX_POSITION_LIMIT)..][..4]
            .copy_from_slice(&4095i32.to_le_bytes());
        table[68] = 2; // status return level: answer everything
        let mut servo = Servo {
            id,
            table,
            deaf_until: None,
        };
        servo.set_i32(address::PRESENT_POSITION, position);
        servo.set_i32(address::GOAL_POSITION, position);
        servo
    }

    fn get_i32(&self, at: u16) -> i32 {
        let at = usize::from(at);
        i32::from_le_bytes([
            self.table[at],
            self.table[at + 1],
            self.table[at + 2],
            self.table[at + 3],
        ])
    }

    fn set_i32(&mut self, at: u16, value: i32) {
        self.table[usize::from(at)..][..4].copy_from_slice(&value.to_le_bytes());
    }

    /// Model number.
    pub fn model(&self) -> u16 {
        u16::from_le_bytes([self.table[0], self.table[1]])
    }
    /// Firmware version.
    pub fn firmware(&self) -> u8 {
        self.table[6]
    }
    /// Secondary ID (255 = none).
    pub fn secondary_id(&self) -> u8 {
        self.table[usize::from(address::SECONDARY_ID)]
    }
    /// Whether Drive Mode says "reverse".
    pub fn reversed(&self) -> bool {
        self.table[usize::from(address::DRIVE_MODE)] & 1 != 0
    }
    /// Operating Mode.
    pub fn operating_mode(&self) -> u8 {
        self.table[usize::from(address::OPERATING_MODE)]
    }
    /// Whether torque is on.
    pub fn torque_on(&self) -> bool {
        self.table[usize::from(address::TORQUE_ENABLE)] == 1
    }
    /// Goal Position.
    pub fn goal_position(&self) -> i32 {
        self.get_i32(address::GOAL_POSITION)
    }
    /// Present Position.
    pub fn present_position(&self) -> i32 {
        self.get_i32(address::PRESENT_POSITION)
    }
    /// Sets Present Position (the simulated motion).
    pub fn set_present_position(&mut self, ticks: i32) {
        self.set_i32(address::PRESENT_POSITION, ticks);
    }
    /// Goal PWM.
    pub fn goal_pwm(&self) -> i16 {
        let at = usize::from(address::GOAL_PWM);
        i16::from_le_bytes([self.table[at], self.table[at + 1]])
    }
    /// Sets Present Load / Current.
    pub fn set_present_load(&mut self, load: i16) {
        self.table[usize::from(address::PRESENT_LOAD)..][..2].copy_from_slice(&load.to_le_bytes());
    }
    /// The latched hardware error (0 = none).
    pub fn hardware_error(&self) -> u8 {
        self.table[usize::from(address::HARDWARE_ERROR_STATUS)]
    }

    /// Latches a hardware error: torque goes off, as the servo's Shutdown setting does.
    pub fn latch_hardware_error(&mut self, bits: u8) {
        self.table[usize::from(address::HARDWARE_ERROR_STATUS)] |= bits;
        self.table[usize::from(address::TORQUE_ENABLE)] = 0;
    }

    /// The error byte's Alert bit.
    pub fn alert(&self) -> u8 {
        if self.hardware_error() != 0 {
            0x80
        } else {
            0
        }
    }

    /// Whether it answers now (not rebooting).
    pub fn awake(&self, now: Instant) -> bool {
        self.deaf_until.is_none_or(|until| now >= until)
    }

    /// REBOOT: clears the hardware error, torque off, goal where it is; deaf for a moment.
    pub fn reboot(&mut self, now: Instant) {
        self.table[usize::from(address::HARDWARE_ERROR_STATUS)] = 0;
        self.table[usize::from(address::TORQUE_ENABLE)] = 0;
        self.table[usize::from(address::GOAL_PWM)..][..2].copy_from_slice(&[0, 0]);
        let here = self.present_position();
        self.set_i32(address::GOAL_POSITION, here);
        self.deaf_until = Some(now + REBOOT_TIME);
    }

    /// READ of `length` bytes at `at`.
    pub fn read(&self, at: u16, length: u16) -> Result<Vec<u8>, u8> {
        let (at, length) = (usize::from(at), usize::from(length));
        if length == 0 || at + length > self.table.len() {
            return Err(error::DATA_RANGE);
        }
        Ok(self.table[at..at + length].to_vec())
    }

    /// WRITE of `data` at `at`, with the servo's rules.
    pub fn write(&mut self, at: u16, data: &[u8]) -> Result<(), u8> {
        let start = usize::from(at);
        let end = start + data.len();
        if data.is_empty() || end > self.table.len() {
            return Err(error::DATA_RANGE);
        }
        let touches = |from: usize, to: usize| start < to && from < end;
        // Model number, firmware, and everything read-only from Hardware Error Status on.
        if touches(0, 7)
            || touches(70, 71)
            || touches(120, 256)
            || (touches(0, 64) && self.torque_on())
        {
            return Err(error::ACCESS);
        }
        let goal = usize::from(address::GOAL_POSITION);
        if start <= goal && end >= goal + 4 && self.operating_mode() == 3 {
            let value = i32::from_le_bytes([
                data[goal - start],
                data[goal - start + 1],
                data[goal - start + 2],
                data[goal - start + 3],
            ]);
            let max = self.get_i32(address::MAX_POSITION_LIMIT);
            let min = self.get_i32(address::MIN_POSITION_LIMIT);
            if value < min || value > max {
                return Err(error::DATA_LIMIT);
            }
        }
        let torque = usize::from(address::TORQUE_ENABLE);
        let mut data = data.to_vec();
        if start <= torque && torque < end && self.hardware_error() != 0 {
            // After a shutdown, torque-on is ignored until REBOOT.
            data[torque - start] = 0;
        }
        self.table[start..end].copy_from_slice(&data);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eeprom_needs_torque_off_and_goals_respect_limits() {
        let mut servo = Servo::new(1, 1020, 2048);
        assert_eq!(servo.write(address::OPERATING_MODE, &[16]), Ok(()));
        assert_eq!(servo.write(address::OPERATING_MODE, &[3]), Ok(()));
        servo.write(address::TORQUE_ENABLE, &[1]).unwrap();
        assert_eq!(
            servo.write(address::OPERATING_MODE, &[16]),
            Err(error::ACCESS)
        );
        assert_eq!(
            servo.write(address::GOAL_POSITION, &5000i32.to_le_bytes()),
            Err(error::DATA_LIMIT)
        );
        assert_eq!(
            servo.write(address::PRESENT_POSITION, &[0, 0, 0, 0]),
            Err(error::ACCESS)
        );
        assert_eq!(servo.read(250, 10), Err(error::DATA_RANGE));
    }

    #[test]
    fn a_hardware_error_holds_torque_off_until_reboot() {
        let mut servo = Servo::new(4, 1020, 2048);
        servo.write(address::TORQUE_ENABLE, &[1]).unwrap();
        servo.latch_hardware_error(0x20);
        assert!(!servo.torque_on());
        assert_eq!(servo.alert(), 0x80);
        servo.write(address::TORQUE_ENABLE, &[1]).unwrap();
        assert!(!servo.torque_on(), "torque-on is ignored after a shutdown");
        let now = Instant::now();
        servo.reboot(now);
        assert!(!servo.awake(now));
        assert!(servo.awake(now + REBOOT_TIME));
        servo.write(address::TORQUE_ENABLE, &[1]).unwrap();
        assert!(servo.torque_on());
        assert_eq!(servo.alert(), 0);
    }
}
