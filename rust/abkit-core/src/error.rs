use thiserror::Error as ThisError;

/// Errors reported by abkit-core.
///
/// Every variant names the offending parameter so that the bindings can turn
/// it into a message that tells the user which argument to fix.
#[derive(Debug, Clone, PartialEq, ThisError)]
pub enum Error {
    /// A parameter is outside its allowed domain (NaN, infinite, negative, ...).
    #[error("{name} must be {expected}, got {value:?}")]
    Domain {
        /// Parameter name as the user spells it.
        name: &'static str,
        /// What the parameter must be, in words.
        expected: String,
        /// The value that was given.
        value: f64,
    },
    /// Input arrays have inconsistent lengths.
    #[error("array length mismatch: {0}")]
    Shape(String),
    /// Bad data at a given track and sample (non-increasing or non-finite
    /// timestamps, a design that fails at a sample's step, ...).
    #[error("track {track}, sample {sample}: {msg}")]
    Data {
        /// Track index.
        track: usize,
        /// Sample index within the track (within this call).
        sample: usize,
        /// What is wrong.
        msg: String,
    },
    /// A well-formed problem has no (stabilising) solution, or none that can
    /// be computed reliably (maps to `numpy.linalg.LinAlgError`).
    #[error("{0}")]
    NoSolution(String),
}

impl Error {
    pub(crate) fn domain(name: &'static str, expected: impl Into<String>, value: f64) -> Self {
        Error::Domain {
            name,
            expected: expected.into(),
            value,
        }
    }
}
