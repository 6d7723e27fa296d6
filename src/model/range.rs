//! Admissible ranges of values: of the model's parameters and of the
//! inputs, with the checks that name a refused value's field and range.

use crate::error::{number, ModelError};
use crate::math::Vec3;

pub(crate) fn invalid(field: impl Into<String>, value: f64, reason: impl Into<String>) -> ModelError {
    ModelError::InvalidParameter { field: field.into(), value, reason: reason.into() }
}

/// Checks that `value` is finite and lies in `range`.
pub(crate) fn check_value(field: &str, value: f64, range: Range) -> Result<(), ModelError> {
    if !value.is_finite() {
        return Err(invalid(field, value, "must be a finite number"));
    }
    if range.contains(value) {
        Ok(())
    } else {
        Err(invalid(field, value, range.requirement()))
    }
}

/// The admissible range of a scalar: finite, between `min` and `max`. The
/// ceilings are physical, far beyond any machine, and keep every quantity the
/// engine derives from the values far from overflow.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Range {
    /// Lower bound.
    pub min: f64,
    /// Upper bound (included).
    pub max: f64,
    /// True if `min` itself is excluded (a positive quantity).
    pub min_excluded: bool,
}

impl Range {
    /// [min, max].
    pub const fn closed(min: f64, max: f64) -> Range {
        Range { min, max, min_excluded: false }
    }

    /// (0, max]: positive.
    pub const fn positive(max: f64) -> Range {
        Range { min: 0.0, max, min_excluded: true }
    }

    /// [−bound, bound].
    pub const fn symmetric(bound: f64) -> Range {
        Range::closed(-bound, bound)
    }

    /// What a value must be, in words and as an interval: "must be
    /// positive and at most 1e12: (0, 1e12]".
    pub fn requirement(&self) -> String {
        let words = if self.min == 0.0 && self.min_excluded {
            format!("must be positive and at most {}", number(self.max))
        } else if self.min == 0.0 {
            format!("must not be negative and at most {}", number(self.max))
        } else if self.min == -self.max {
            format!("must be finite and at most {} in magnitude", number(self.max))
        } else {
            format!("must be at least {} and at most {}", number(self.min), number(self.max))
        };
        format!("{words}: {self}")
    }

    /// True if `x` lies in the range (NaN never does).
    pub fn contains(&self, x: f64) -> bool {
        let above = if self.min_excluded { x > self.min } else { x >= self.min };
        above && x <= self.max
    }

    /// Length of the model's chain: DH lengths, centres, points, m; angles, rad.
    pub const GEOMETRY: Range = Range::symmetric(1e3);
    /// Gravity, m/s².
    pub const GRAVITY: Range = Range::symmetric(1e3);
    /// Link mass, kg.
    pub const MASS: Range = Range::positive(1e6);
    /// Entries of an inertia tensor, kg·m².
    pub const INERTIA: Range = Range::symmetric(1e9);
    /// Drive stiffness k, N/m or N·m/rad.
    pub const STIFFNESS: Range = Range::positive(1e12);
    /// Drive damping h, N·s/m or N·m·s/rad.
    pub const DAMPING: Range = Range::closed(0.0, 1e9);
    /// Drive clearance Δ, m or rad.
    pub const CLEARANCE: Range = Range::closed(0.0, 1.0);
    /// Friction coefficients μ_k, μ_s.
    pub const FRICTION_COEFFICIENT: Range = Range::closed(0.0, 2.0);
    /// Stribeck velocity v_s, m/s or rad/s (0: constant μ_k).
    pub const STRIBECK_VELOCITY: Range = Range::closed(0.0, 1e3);
    /// Viscous friction coefficient b of a joint, N·s/m or N·m·s/rad: the
    /// ceiling of the drive damping h, which has the same unit.
    pub const JOINT_VISCOUS: Range = Range::closed(0.0, 1e9);
    /// Slider length a, m.
    pub const SLIDER_LENGTH: Range = Range::positive(100.0);
    /// Slider cross-section b, c; bearing diameters and distances, m.
    pub const CONTACT_SIZE: Range = Range::closed(0.0, 100.0);
    /// Gear ratio N of a motor drive, rad/rad or rad/m.
    pub const GEAR_RATIO: Range = Range::positive(1e6);
    /// Rotor inertia J_m, kg·m².
    pub const ROTOR_INERTIA: Range = Range::positive(1e3);
    /// Viscous friction b_m of a motor, N·m·s/rad.
    pub const MOTOR_VISCOUS: Range = Range::closed(0.0, 1e6);
    /// Coulomb friction level τ_c of a motor, N·m.
    pub const MOTOR_COULOMB: Range = Range::closed(0.0, 1e6);
}

/// Admissible ranges of the drive inputs q*, q̇*, q̈* (m or rad, per s, per
/// s²), by input name: no machine comes near them, and they keep every
/// quantity the engine derives from the inputs far from overflow.
pub const INPUT_RANGES: [(&str, Range); 3] =
    [("q_star", Range::symmetric(1e3)), ("qd_star", Range::symmetric(1e3)), ("qdd_star", Range::symmetric(1e6))];

/// Admissible ranges of the motor torque input τ_m of a motor drive and of
/// its first and second time derivatives (N·m, per s, per s²), by name.
pub const MOTOR_TORQUE_RANGES: [(&str, Range); 3] =
    [("tau_m", Range::symmetric(1e6)), ("tau_m'", Range::symmetric(1e9)), ("tau_m''", Range::symmetric(1e12))];

impl std::fmt::Display for Range {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let open = if self.min_excluded { '(' } else { '[' };
        let close = if self.max.is_infinite() { ')' } else { ']' };
        write!(f, "{open}{}, {}{close}", number(self.min), number(self.max))
    }
}

pub(crate) fn check_vec(field: &str, v: &Vec3, range: Range) -> Result<(), ModelError> {
    for (k, x) in v.iter().enumerate() {
        check_value(&format!("{field}[{}]", k + 1), *x, range)?;
    }
    Ok(())
}
