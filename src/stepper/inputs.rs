//! Drive inputs and their Taylor polynomial across a communication interval.

use crate::error::StepError;
use crate::model::Range;
pub use crate::model::{INPUT_RANGES, MOTOR_TORQUE_RANGES};

/// Drive inputs at the start of a communication interval. For a flexible
/// joint they are the drive end q*, q̇*, q̈*; for a rigid joint the prescribed
/// q, q̇, q̈. Each slice has one value per joint.
#[derive(Debug, Clone, Copy)]
pub struct DriveInputs<'a> {
    /// q*, m or rad.
    pub q_star: &'a [f64],
    /// q̇*, m/s or rad/s.
    pub qd_star: &'a [f64],
    /// q̈*, m/s² or rad/s².
    pub qdd_star: &'a [f64],
}

/// Motor torques τ_m of the motor drives and their first two time
/// derivatives at the start of a communication interval, one value per
/// joint (joints without a motor drive ignore theirs), N·m, N·m/s, N·m/s².
/// Held across the interval as their Taylor polynomial, like the drive
/// inputs.
#[derive(Debug, Clone, Copy)]
pub struct MotorTorques<'a> {
    /// τ_m, N·m.
    pub tau_m: &'a [f64],
    /// dτ_m/dt, N·m/s.
    pub tau_m_rate: &'a [f64],
    /// d²τ_m/dt², N·m/s².
    pub tau_m_accel: &'a [f64],
}

/// The inputs held across an interval as their second-order Taylor
/// polynomial about its start t0, so that a drive end moves smoothly instead
/// of jumping (a step of q* would hammer a 10⁶ N/m spring).
#[derive(Debug, Clone, PartialEq)]
pub struct InputPolynomial {
    /// Start of the interval, s.
    pub t0: f64,
    /// q*(t0).
    pub q: Vec<f64>,
    /// q̇*(t0).
    pub qd: Vec<f64>,
    /// q̈*(t0).
    pub qdd: Vec<f64>,
}

impl InputPolynomial {
    /// A polynomial for `n` joints, all zero.
    pub fn new(n: usize) -> Self {
        InputPolynomial { t0: 0.0, q: vec![0.0; n], qd: vec![0.0; n], qdd: vec![0.0; n] }
    }

    /// Takes new inputs at `t0`, without allocating.
    pub fn set(&mut self, t0: f64, inputs: &DriveInputs) {
        self.set_values(t0, [inputs.q_star, inputs.qd_star, inputs.qdd_star]);
    }

    /// Takes a value and its first two derivatives at `t0`, without allocating.
    pub fn set_values(&mut self, t0: f64, [x, xd, xdd]: [&[f64]; 3]) {
        self.t0 = t0;
        self.q.copy_from_slice(x);
        self.qd.copy_from_slice(xd);
        self.qdd.copy_from_slice(xdd);
    }

    /// (q*, q̇*, q̈*) of joint `i` at time `t`.
    #[inline(always)]
    pub fn eval(&self, i: usize, t: f64) -> (f64, f64, f64) {
        let tau = t - self.t0;
        let a = self.qdd[i];
        (self.q[i] + tau * (self.qd[i] + 0.5 * tau * a), self.qd[i] + tau * a, a)
    }
}

/// Checks three input vectors (a value and its two derivatives) against
/// their names and ranges: n values each, finite, inside the range.
pub(super) fn check_input_values(
    n: usize,
    ranges: [(&'static str, Range); 3],
    values: [&[f64]; 3],
) -> Result<(), StepError> {
    for ((field, range), values) in ranges.into_iter().zip(values) {
        if values.len() != n {
            return Err(StepError::InputLength { field, expected: n, got: values.len() });
        }
        if let Some((i, v)) = values.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(StepError::NonFiniteInput { field, joint: i + 1, value: *v });
        }
        if let Some((i, v)) = values.iter().enumerate().find(|(_, v)| !range.contains(**v)) {
            return Err(StepError::InputOutOfRange { field, joint: i + 1, value: *v, range: range.to_string() });
        }
    }
    Ok(())
}
