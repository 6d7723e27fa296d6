//! The immutable description of a manipulator: the chain, its drives, its
//! friction and the integrator settings.

use super::{ContactGeometry, Drive, Joint, JointKind, Link};
use crate::error::ModelError;
use crate::math::{Mat3, Vec3};

/// The largest chain the engine accepts.
pub const MAX_JOINTS: usize = 64;

/// Settings of the iterative Newmark stepper (study section 3.2, after eq. 3.15).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IntegratorSettings {
    /// Smallest internal sub-step h_min, s: the error control never goes
    /// below it. Default 2·10⁻⁶ s, the step the study found converged.
    pub h_min: f64,
    /// Largest internal sub-step h_max, s. Default 5·10⁻⁴ s; h_min = h_max
    /// gives fixed sub-steps of that length (shortened only at events).
    pub h_max: f64,
    /// Relative tolerance of the local error of a sub-step (see
    /// `stepper::error_control`), default 5e-4; what fmi2SetupExperiment's
    /// tolerance sets.
    pub error_tolerance: f64,
    /// Newmark β, default ¼ (average acceleration).
    pub beta: f64,
    /// Newmark γ, default ½.
    pub gamma: f64,
    /// Relative tolerance of the iteration on accelerations, reactions and
    /// friction forces, default 1e-10.
    pub tolerance: f64,
    /// Iteration limit per sub-step, default 50.
    pub max_iterations: usize,
}

impl IntegratorSettings {
    /// Admissible range of Newmark β (both ends included).
    pub const BETA_RANGE: (f64, f64) = (0.0, 0.5);
    /// Admissible range of Newmark γ (both ends included).
    pub const GAMMA_RANGE: (f64, f64) = (0.5, 1.0);
    /// Largest admissible iteration tolerance; it must be positive.
    pub const TOLERANCE_MAX: f64 = 1e-3;
    /// Admissible range of the sub-step bounds h_min ≤ h_max, s (both ends
    /// included): below 1e-9 s rounding of the time eats the step, above
    /// 1e-2 s a sub-step spans a drive's vibration period.
    pub const STEP_RANGE: (f64, f64) = (1e-9, 1e-2);
    /// Admissible range of the error tolerance (the lower end excluded).
    pub const ERROR_TOLERANCE_RANGE: (f64, f64) = (0.0, 0.1);

    /// True when h_min = h_max: fixed sub-steps, no error control.
    pub fn fixed_step(&self) -> bool {
        self.h_min >= self.h_max
    }

    /// The relative residual at which the Newmark iteration stops: `tolerance`
    /// with fixed sub-steps; with error control no tighter than
    /// 10⁻⁴·`error_tolerance`, which keeps the iteration's error four orders
    /// below the local error the step-size control admits (a residual r moves
    /// q by about β(ωh)²·r of the drive deflection) without iterating to
    /// rounding level.
    pub fn iteration_tolerance(&self) -> f64 {
        if self.fixed_step() {
            self.tolerance
        } else {
            self.tolerance.max(1e-4 * self.error_tolerance)
        }
    }
}

impl Default for IntegratorSettings {
    fn default() -> Self {
        IntegratorSettings {
            h_min: 2e-6,
            h_max: 5e-4,
            error_tolerance: 5e-4,
            beta: 0.25,
            gamma: 0.5,
            tolerance: 1e-10,
            max_iterations: 50,
        }
    }
}

/// An open chain of n rigid links connected by revolute or prismatic joints.
///
/// Joint i (0-based index i−1 in the arrays) connects link i−1 to link i;
/// link 0 is the fixed base. The model is immutable while algorithms run:
/// all workspace lives in [`crate::Data`].
#[derive(Debug, Clone, PartialEq)]
pub struct Model {
    /// A name for logs and the FMU.
    pub name: String,
    /// Joints 1…n in chain order.
    pub joints: Vec<Joint>,
    /// Links 1…n in chain order; link i is moved by joint i.
    pub links: Vec<Link>,
    /// Gravity vector in the base frame 0, m/s².
    pub gravity: Vec3,
    /// End point E (gripper tip) in the frame of the last link, m.
    pub end_point: Vec3,
    /// Stepper settings.
    pub integrator: IntegratorSettings,
}

fn invalid(field: impl Into<String>, value: f64, reason: impl Into<String>) -> ModelError {
    ModelError::InvalidParameter { field: field.into(), value, reason: reason.into() }
}

/// Checks that `value` is finite and lies in the range described by `check`.
pub(crate) fn check_value(field: &str, value: f64, range: Range) -> Result<(), ModelError> {
    if !value.is_finite() {
        return Err(invalid(field, value, "must be a finite number"));
    }
    let ok = match range {
        Range::Any => true,
        Range::Positive => value > 0.0,
        Range::NonNegative => value >= 0.0,
    };
    if ok {
        Ok(())
    } else {
        Err(invalid(field, value, range.reason()))
    }
}

/// Admissible range of a scalar parameter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Range {
    Any,
    Positive,
    NonNegative,
}

impl Range {
    fn reason(self) -> &'static str {
        match self {
            Range::Any => "must be finite",
            Range::Positive => "must be positive",
            Range::NonNegative => "must not be negative",
        }
    }
}

fn check_vec(field: &str, v: &Vec3) -> Result<(), ModelError> {
    for (k, x) in v.iter().enumerate() {
        check_value(&format!("{field}[{}]", k + 1), *x, Range::Any)?;
    }
    Ok(())
}

impl Model {
    /// Number of joints n.
    pub fn nq(&self) -> usize {
        self.joints.len()
    }

    /// Checks every parameter and every relation between parameters.
    /// Errors name the field (1-based joint numbers, as in the model file).
    pub fn validate(&self) -> Result<(), ModelError> {
        let n = self.joints.len();
        if n == 0 || n > MAX_JOINTS {
            return Err(ModelError::Invalid {
                field: "joint".into(),
                reason: format!("the chain has {n} joints; 1 to {MAX_JOINTS} are supported"),
            });
        }
        if self.links.len() != n {
            return Err(ModelError::Invalid {
                field: "link".into(),
                reason: format!("{} links for {n} joints", self.links.len()),
            });
        }
        check_vec("gravity", &self.gravity)?;
        check_vec("end_point", &self.end_point)?;
        for (i, (joint, link)) in self.joints.iter().zip(&self.links).enumerate() {
            validate_joint(i + 1, joint)?;
            validate_link(i + 1, link)?;
        }
        validate_integrator(&self.integrator)
    }
}

fn validate_joint(number: usize, joint: &Joint) -> Result<(), ModelError> {
    let f = |name: &str| format!("joint[{number}].{name}");
    check_value(&f("theta"), joint.dh.theta, Range::Any)?;
    check_value(&f("d"), joint.dh.d, Range::Any)?;
    check_value(&f("a"), joint.dh.a, Range::Any)?;
    check_value(&f("alpha"), joint.dh.alpha, Range::Any)?;
    if let Drive::Flexible { stiffness, damping, clearance } = joint.drive {
        check_value(&f("drive.k"), stiffness, Range::Positive)?;
        check_value(&f("drive.h"), damping, Range::NonNegative)?;
        check_value(&f("drive.clearance"), clearance, Range::NonNegative)?;
    }
    let Some(friction) = joint.friction else { return Ok(()) };
    let c = friction.coefficients;
    check_value(&f("friction.mu_k"), c.mu_kinetic, Range::NonNegative)?;
    check_value(&f("friction.mu_s"), c.mu_static, Range::NonNegative)?;
    check_value(&f("friction.v_s"), c.stribeck_velocity, Range::NonNegative)?;
    if c.mu_static < c.mu_kinetic {
        return Err(invalid(
            f("friction.mu_s"),
            c.mu_static,
            format!("static coefficient below the kinetic one (mu_k = {}); stiction would be ill-posed", c.mu_kinetic),
        ));
    }
    match (joint.kind, friction.geometry) {
        (JointKind::Revolute, ContactGeometry::Bearings { reaction_point, l_a, l_b, d_a, d_b, d_c }) => {
            check_vec(&f("bearings.reaction_point"), &reaction_point)?;
            if reaction_point.x.abs() > 1e-12 || reaction_point.y.abs() > 1e-12 {
                return Err(ModelError::Invalid {
                    field: f("bearings.reaction_point"),
                    reason: "must lie on the joint axis z (x = y = 0 in frame i-1)".into(),
                });
            }
            check_value(&f("bearings.l_a"), l_a, Range::NonNegative)?;
            check_value(&f("bearings.l_b"), l_b, Range::NonNegative)?;
            check_value(&f("bearings.l_a + bearings.l_b"), l_a + l_b, Range::Positive)?;
            check_value(&f("bearings.d_a"), d_a, Range::NonNegative)?;
            check_value(&f("bearings.d_b"), d_b, Range::NonNegative)?;
            check_value(&f("bearings.d_c"), d_c, Range::NonNegative)?;
        }
        (JointKind::Prismatic, ContactGeometry::Slider { centre, a, b, c }) => {
            check_vec(&f("slider.centre"), &centre)?;
            check_value(&f("slider.a"), a, Range::Positive)?;
            check_value(&f("slider.b"), b, Range::NonNegative)?;
            check_value(&f("slider.c"), c, Range::NonNegative)?;
            check_value(&f("slider.b^2 + slider.c^2"), b * b + c * c, Range::Positive)?;
        }
        (JointKind::Revolute, _) => {
            return Err(ModelError::Invalid {
                field: f("bearings"),
                reason: "a revolute joint with friction needs its bearing geometry (reaction_point, l_a, l_b, d_a, d_b, d_c)".into(),
            })
        }
        (JointKind::Prismatic, _) => {
            return Err(ModelError::Invalid {
                field: f("slider"),
                reason: "a prismatic joint with friction needs its slider geometry (centre, a, b, c)".into(),
            })
        }
    }
    Ok(())
}

fn validate_link(number: usize, link: &Link) -> Result<(), ModelError> {
    let f = |name: &str| format!("joint[{number}].link.{name}");
    check_value(&f("mass"), link.mass, Range::Positive)?;
    check_vec(&f("com"), &link.com)?;
    let i = &link.inertia;
    const ENTRIES: [&str; 9] = ["xx", "xy", "xz", "xy", "yy", "yz", "xz", "yz", "zz"];
    for (name, x) in ENTRIES.iter().zip(i.iter()) {
        check_value(&f(&format!("inertia.{name}")), *x, Range::Any)?;
    }
    if (i - i.transpose()).amax() > 1e-12 * i.amax().max(1e-300) {
        return Err(ModelError::Invalid { field: f("inertia"), reason: "tensor is not symmetric".into() });
    }
    let eig = Mat3::symmetric_eigenvalues(i);
    let (min, max) = (eig.min(), eig.max());
    if min <= 0.0 {
        return Err(ModelError::Invalid {
            field: f("inertia"),
            reason: format!("tensor is not positive definite (principal moments {:.6e}, {:.6e}, {:.6e})", eig[0], eig[1], eig[2]),
        });
    }
    // A rigid body's principal moments satisfy I1 + I2 ≥ I3 for every ordering.
    if eig.sum() - 2.0 * max < -1e-12 * max {
        return Err(ModelError::Invalid {
            field: f("inertia"),
            reason: format!(
                "principal moments {:.6e}, {:.6e}, {:.6e} violate the triangle inequality I1 + I2 >= I3",
                eig[0], eig[1], eig[2]
            ),
        });
    }
    Ok(())
}

fn validate_integrator(s: &IntegratorSettings) -> Result<(), ModelError> {
    let (h0, h1) = IntegratorSettings::STEP_RANGE;
    for (field, h) in [("integrator.h_min", s.h_min), ("integrator.h_max", s.h_max)] {
        check_value(field, h, Range::Positive)?;
        if !(h0..=h1).contains(&h) {
            return Err(invalid(field, h, format!("must lie in [{h0:e}, {h1:e}] s")));
        }
    }
    if s.h_min > s.h_max {
        return Err(invalid("integrator.h_min", s.h_min, format!("must not exceed h_max = {:e} s", s.h_max)));
    }
    let (e0, e1) = IntegratorSettings::ERROR_TOLERANCE_RANGE;
    if !(s.error_tolerance > e0 && s.error_tolerance <= e1) {
        return Err(invalid("integrator.error_tolerance", s.error_tolerance, format!("must lie in ({e0}, {e1}]")));
    }
    let (b0, b1) = IntegratorSettings::BETA_RANGE;
    if !(b0..=b1).contains(&s.beta) {
        return Err(invalid("integrator.beta", s.beta, format!("Newmark beta must lie in [{b0}, {b1}]")));
    }
    let (g0, g1) = IntegratorSettings::GAMMA_RANGE;
    if !(g0..=g1).contains(&s.gamma) {
        return Err(invalid("integrator.gamma", s.gamma, format!("Newmark gamma must lie in [{g0}, {g1}]")));
    }
    let t1 = IntegratorSettings::TOLERANCE_MAX;
    if !(s.tolerance > 0.0 && s.tolerance <= t1) {
        return Err(invalid("integrator.tolerance", s.tolerance, format!("must lie in (0, {t1:e}]")));
    }
    if s.max_iterations == 0 || s.max_iterations > 10_000 {
        return Err(invalid("integrator.max_iterations", s.max_iterations as f64, "must lie in 1..=10000"));
    }
    Ok(())
}
