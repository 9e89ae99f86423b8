//! Checking a message before acting on it.
//!
//! Serde makes sure a message has the right *shape*; it cannot tell that a pose holds `NaN`, a
//! joint vector has five entries for a six-joint arm, or a label is empty. Every message that
//! can be wrong in such a way implements [`Validate`], and whoever receives it from outside the
//! process (an edge, an actor serving a request) calls [`Validate::validate`] before moving
//! anything. The error names the offending field with its path (`"target.x"`) so an edge can
//! turn it into the `• <field>: <message>` bullet of an MCP validation error.
//!
//! ```
//! use robotd_protocol::geometry::Pose;
//! use robotd_protocol::validate::Validate;
//!
//! let pose = Pose::new(0.25, 0.0, f64::NAN, 0.0, 1.57, 0.0);
//! let err = pose.validate().unwrap_err();
//! assert_eq!(err.to_string(), "z: must be a finite number, got NaN");
//! ```

/// Why a message is not acceptable. `field` is a dotted path into the message.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ValidationError {
    /// A number is NaN or infinite.
    #[error("{field}: must be a finite number, got {value}")]
    NotFinite {
        /// Path of the field.
        field: String,
        /// The value found.
        value: f64,
    },
    /// A number lies outside its allowed range.
    #[error("{field}: must be between {min} and {max}, got {value}")]
    OutOfRange {
        /// Path of the field.
        field: String,
        /// The value found.
        value: f64,
        /// Smallest allowed value.
        min: f64,
        /// Largest allowed value.
        max: f64,
    },
    /// A string or list that must not be empty is empty.
    #[error("{field}: must not be empty")]
    Empty {
        /// Path of the field.
        field: String,
    },
    /// A list has the wrong number of entries.
    #[error("{field}: must have {expected} entries, got {got}")]
    WrongLength {
        /// Path of the field.
        field: String,
        /// Required number of entries.
        expected: usize,
        /// Number found.
        got: usize,
    },
    /// Any other rule, stated in words.
    #[error("{field}: {reason}")]
    Invalid {
        /// Path of the field.
        field: String,
        /// What is wrong, in words a user can act on.
        reason: String,
    },
}

impl ValidationError {
    /// The dotted path of the offending field.
    pub fn field(&self) -> &str {
        match self {
            Self::NotFinite { field, .. }
            | Self::OutOfRange { field, .. }
            | Self::Empty { field }
            | Self::WrongLength { field, .. }
            | Self::Invalid { field, .. } => field,
        }
    }

    /// The same error with `prefix.` put in front of its field path.
    pub fn within(mut self, prefix: &str) -> Self {
        let field = match &mut self {
            Self::NotFinite { field, .. }
            | Self::OutOfRange { field, .. }
            | Self::Empty { field }
            | Self::WrongLength { field, .. }
            | Self::Invalid { field, .. } => field,
        };
        *field = format!("{prefix}.{field}");
        self
    }
}

/// A message (or part of one) whose content can be checked beyond its shape.
pub trait Validate {
    /// `Ok(())` if the value can be acted upon, otherwise the first problem found.
    fn validate(&self) -> Result<(), ValidationError>;
}

/// Fails unless `value` is finite.
pub fn finite(field: &str, value: f64) -> Result<(), ValidationError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(ValidationError::NotFinite {
            field: field.to_owned(),
            value,
        })
    }
}

/// Fails unless `value` is finite and within `min..=max`.
pub fn in_range(field: &str, value: f64, min: f64, max: f64) -> Result<(), ValidationError> {
    finite(field, value)?;
    if (min..=max).contains(&value) {
        Ok(())
    } else {
        Err(ValidationError::OutOfRange {
            field: field.to_owned(),
            value,
            min,
            max,
        })
    }
}

/// Fails if `value` is empty or only whitespace.
pub fn non_empty(field: &str, value: &str) -> Result<(), ValidationError> {
    if value.trim().is_empty() {
        Err(ValidationError::Empty {
            field: field.to_owned(),
        })
    } else {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_the_field_and_value() {
        assert_eq!(
            finite("x", f64::INFINITY).unwrap_err().to_string(),
            "x: must be a finite number, got inf"
        );
        assert_eq!(
            in_range("z_offset", 0.5, 0.0, 0.1).unwrap_err().to_string(),
            "z_offset: must be between 0 and 0.1, got 0.5"
        );
        assert_eq!(
            non_empty("text", "  ").unwrap_err().to_string(),
            "text: must not be empty"
        );
    }

    #[test]
    fn within_prefixes_the_path() {
        let err = finite("x", f64::NAN).unwrap_err().within("target");
        assert_eq!(err.field(), "target.x");
    }
}
