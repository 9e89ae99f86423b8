//! How robotd spells units, and the few conversions between them.
//!
//! Every quantity in the protocol is an SI base or derived unit, and the unit is in the field's
//! Rust name: `width_m` (metres), `yaw_rad` (radians), `velocities_rad_s` (radians per second),
//! `size_m2` (square metres), `backoff_ms` (milliseconds), `duration_s` (seconds),
//! `timestamp_unix_ns` (nanoseconds since the Unix epoch).
//!
//! On the wire, a field keeps its Rust name unless the Python project already fixed a name for
//! it (a pose is `{x, y, z, roll, pitch, yaw}` in its Redis metadata and in
//! `get_system_status`; an object's `gripper_rotation` and `timestamp` are part of the object
//! JSON) — there the wire name follows Python and the doc comment states the unit. A bare `x`,
//! `y`, `z` on the wire is always metres in the robot base frame; a bare angle is always radians.
//!
//! The only places other units appear are at the edges, and they convert at once:
//! `push_object` takes millimetres, text replies print centimetres and millimetres, the WidowX
//! limits are given in degrees.
//!
//! ```
//! use robotd_protocol::units::{deg_to_rad, mm_to_m};
//! assert_eq!(mm_to_m(50.0), 0.05);
//! assert!((deg_to_rad(180.0) - std::f64::consts::PI).abs() < 1e-12);
//! ```

/// Millimetres to metres.
pub fn mm_to_m(mm: f64) -> f64 {
    mm / 1000.0
}

/// Metres to millimetres.
pub fn m_to_mm(m: f64) -> f64 {
    m * 1000.0
}

/// Degrees to radians.
pub fn deg_to_rad(deg: f64) -> f64 {
    deg.to_radians()
}

/// Radians to degrees.
pub fn rad_to_deg(rad: f64) -> f64 {
    rad.to_degrees()
}

/// Nanoseconds since the Unix epoch to (fractional) seconds, as the Python tools write them.
pub fn unix_ns_to_s(ns: u64) -> f64 {
    ns as f64 / 1e9
}

/// Seconds since the Unix epoch (as the Python tools write them) to nanoseconds; negative or
/// non-finite inputs give 0.
pub fn unix_s_to_ns(s: f64) -> u64 {
    if s.is_finite() && s > 0.0 {
        (s * 1e9) as u64
    } else {
        0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conversions_round_trip() {
        assert_eq!(m_to_mm(mm_to_m(123.0)), 123.0);
        assert!((rad_to_deg(deg_to_rad(37.5)) - 37.5).abs() < 1e-12);
        assert_eq!(unix_s_to_ns(1.5), 1_500_000_000);
        assert_eq!(unix_ns_to_s(2_000_000_000), 2.0);
        assert_eq!(unix_s_to_ns(f64::NAN), 0);
        assert_eq!(unix_s_to_ns(-1.0), 0);
    }
}
