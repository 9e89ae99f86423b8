//! Robot kinematics (placeholder: being written).
