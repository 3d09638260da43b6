//! The error of a configuration check: the field that is out of range (its TOML path) and
//! what is wrong with it, for the `validate` methods of the stages' configurations.

/// A configuration value out of range. Displays as `field problem`, e.g.
/// `tilt.max_tilt_deg must be a positive number, got -1`.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{field} {problem}")]
pub struct FieldError {
    /// TOML path of the field, e.g. `lander.ground_z_m`.
    pub field: String,
    /// What is wrong with its value, e.g. `must be a positive number, got -1`.
    pub problem: String,
}

impl FieldError {
    /// The error of `field` with `problem`.
    pub fn new(field: impl Into<String>, problem: impl Into<String>) -> Self {
        Self {
            field: field.into(),
            problem: problem.into(),
        }
    }

    /// The same error under the section `prefix` (`prefix.field`).
    pub fn within(self, prefix: &str) -> Self {
        Self {
            field: format!("{prefix}.{}", self.field),
            ..self
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn displays_the_path_then_the_problem() {
        let e = FieldError::new("max_tilt_deg", "must be positive").within("tilt");
        assert_eq!(e.field, "tilt.max_tilt_deg");
        assert_eq!(e.to_string(), "tilt.max_tilt_deg must be positive");
    }
}
