//! The closed-form steady state of the Singer filter (Yoon & Hong's
//! Hamiltonian route).

use crate::singer::SteadyState;
use crate::{Error, Result};

/// Closed-form steady state (see the module docs).
pub fn steady_state_closed(_theta: f64, _qn: f64, _rv: f64) -> Result<SteadyState> {
    Err(Error::NoSolution("closed form not available".into()))
}
