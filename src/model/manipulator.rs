//! The immutable description of a manipulator: the chain, its drives, its
//! friction and the integrator settings.

use super::range::{check_value, check_vec, invalid, Range};
use super::{ContactGeometry, Joint, JointKind, Link, Placement};
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
/// all workspace lives in [`crate::Data`]. Build it from a model file
/// ([`Model::from_file`]: Denavit–Hartenberg rows or a URDF) or from
/// Denavit–Hartenberg joints ([`Model::from_dh`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Model {
    /// A name for logs and the FMU.
    pub name: String,
    /// Joints 1…n in chain order.
    pub joints: Vec<Joint>,
    /// The names the model source gives the joints (URDF joint names), in
    /// chain order; `None` for Denavit–Hartenberg rows.
    pub joint_names: Vec<Option<String>>,
    /// Links 1…n in chain order; link i is moved by joint i, its inertial
    /// data are in link i's frame (see [`Joint`]).
    pub links: Vec<Link>,
    /// Gravity vector in the base frame 0, m/s².
    pub gravity: Vec3,
    /// End point E (gripper tip) in the frame of the last link, m.
    pub end_point: Vec3,
    /// Stepper settings.
    pub integrator: IntegratorSettings,
    /// What the model source accepted but a user should know (a URDF
    /// inertia that violates the triangle inequality, links lumped into the
    /// chain); hosts log them when the model is loaded.
    pub warnings: Vec<String>,
}

impl Model {
    /// Number of joints n.
    pub fn nq(&self) -> usize {
        self.joints.len()
    }

    /// Checks every parameter and every relation between parameters.
    /// Errors name the field (1-based joint numbers, as in the model file).
    /// The triangle inequality of the principal moments is the model
    /// source's to check (a DH file refuses a violation, a URDF warns).
    pub fn validate(&self) -> Result<(), ModelError> {
        let n = self.joints.len();
        if n == 0 || n > MAX_JOINTS {
            return Err(ModelError::Invalid {
                field: "joint".into(),
                reason: format!("the chain has {n} joints; 1 to {MAX_JOINTS} are supported"),
            });
        }
        if self.links.len() != n || self.joint_names.len() != n {
            return Err(ModelError::Invalid {
                field: "link".into(),
                reason: format!("{} links and {} joint names for {n} joints", self.links.len(), self.joint_names.len()),
            });
        }
        check_vec("gravity", &self.gravity, Range::GRAVITY)?;
        check_vec("end_point", &self.end_point, Range::GEOMETRY)?;
        for (i, (joint, link)) in self.joints.iter().zip(&self.links).enumerate() {
            validate_joint(i + 1, joint)?;
            validate_link(i + 1, link, false)?;
        }
        // A flexible joint's equation of motion needs mass beyond it.
        for (i, joint) in self.joints.iter().enumerate() {
            if joint.drive.is_flexible() && self.links[i..].iter().all(|l| l.mass == 0.0) {
                let name = self.joint_names[i].as_ref().map_or(String::new(), |s| format!(" (`{s}`)"));
                return Err(ModelError::Invalid {
                    field: format!("joint[{}]{name}.drive", i + 1),
                    reason: "a flexible drive needs mass in the chain beyond the joint; every link from it to the tip is massless".into(),
                });
            }
        }
        validate_integrator(&self.integrator)
    }
}

/// l_A + l_B of a bearing pair, m: at least 1 mm, so that (3.15) divides by
/// a length, not by rounding.
const BEARING_SPAN: Range = Range::closed(1e-3, 200.0);
/// b + c of a slider, m: at least 1 mm, for the same reason in (3.11).
const SLIDER_SECTION: Range = Range::closed(1e-3, 200.0);

/// Checks that a placement is finite, its origin within the geometry range
/// and its rotation a proper rotation to 1e-9.
fn validate_placement(field: &str, p: &Placement) -> Result<(), ModelError> {
    check_vec(&format!("{field}.translation"), &p.translation, Range::GEOMETRY)?;
    let r = &p.rotation;
    for x in r.iter() {
        check_value(&format!("{field}.rotation"), *x, Range::symmetric(1.0 + 1e-9))?;
    }
    let defect = (r.transpose() * r - Mat3::identity()).amax();
    if defect > 1e-9 || r.determinant() < 0.0 {
        return Err(ModelError::Invalid {
            field: format!("{field}.rotation"),
            reason: format!("is not a proper rotation (|RᵀR − 1| = {defect:.1e}, det = {:.6})", r.determinant()),
        });
    }
    Ok(())
}

fn validate_joint(number: usize, joint: &Joint) -> Result<(), ModelError> {
    let f = |name: &str| format!("joint[{number}].{name}");
    validate_placement(&f("placement"), &joint.placement)?;
    check_value(&f("offset"), joint.offset, Range::GEOMETRY)?;
    validate_placement(&f("reported_axes"), &Placement { rotation: joint.reported_axes, translation: Vec3::zeros() })?;
    if let Some(spring) = joint.drive.spring() {
        check_value(&f("drive.k"), spring.stiffness, Range::STIFFNESS)?;
        check_value(&f("drive.h"), spring.damping, Range::DAMPING)?;
        check_value(&f("drive.clearance"), spring.clearance, Range::CLEARANCE)?;
    }
    if let Some(rotor) = joint.drive.rotor() {
        check_value(&f("drive.gear_ratio"), rotor.gear_ratio, Range::GEAR_RATIO)?;
        check_value(&f("drive.rotor_inertia"), rotor.inertia, Range::ROTOR_INERTIA)?;
        check_value(&f("drive.motor_viscous"), rotor.viscous, Range::MOTOR_VISCOUS)?;
        check_value(&f("drive.motor_coulomb"), rotor.coulomb, Range::MOTOR_COULOMB)?;
    }
    let Some(friction) = joint.friction else { return Ok(()) };
    let c = friction.coefficients;
    check_value(&f("friction.mu_k"), c.mu_kinetic, Range::FRICTION_COEFFICIENT)?;
    check_value(&f("friction.mu_s"), c.mu_static, Range::FRICTION_COEFFICIENT)?;
    check_value(&f("friction.v_s"), c.stribeck_velocity, Range::STRIBECK_VELOCITY)?;
    check_value(&f("friction.viscous"), c.viscous, Range::JOINT_VISCOUS)?;
    if c.mu_static < c.mu_kinetic {
        return Err(invalid(
            f("friction.mu_s"),
            c.mu_static,
            format!("static coefficient below the kinetic one (mu_k = {}); stiction would be ill-posed", c.mu_kinetic),
        ));
    }
    match (joint.kind, friction.geometry) {
        (JointKind::Revolute, ContactGeometry::Bearings { reaction_point, l_a, l_b, d_a, d_b, d_c }) => {
            check_vec(&f("bearings.reaction_point"), &reaction_point, Range::GEOMETRY)?;
            if reaction_point.x.abs() > 1e-12 || reaction_point.y.abs() > 1e-12 {
                return Err(ModelError::Invalid {
                    field: f("bearings.reaction_point"),
                    reason: "must lie on the joint axis (x = y = 0 in the joint frame)".into(),
                });
            }
            check_value(&f("bearings.l_a"), l_a, Range::CONTACT_SIZE)?;
            check_value(&f("bearings.l_b"), l_b, Range::CONTACT_SIZE)?;
            check_value(&f("bearings.l_a + bearings.l_b"), l_a + l_b, BEARING_SPAN)?;
            check_value(&f("bearings.d_a"), d_a, Range::CONTACT_SIZE)?;
            check_value(&f("bearings.d_b"), d_b, Range::CONTACT_SIZE)?;
            check_value(&f("bearings.d_c"), d_c, Range::CONTACT_SIZE)?;
        }
        (JointKind::Prismatic, ContactGeometry::Slider { centre, a, b, c }) => {
            check_vec(&f("slider.centre"), &centre, Range::GEOMETRY)?;
            check_value(&f("slider.a"), a, Range::SLIDER_LENGTH)?;
            check_value(&f("slider.b"), b, Range::CONTACT_SIZE)?;
            check_value(&f("slider.c"), c, Range::CONTACT_SIZE)?;
            check_value(&f("slider.b + slider.c"), b + c, SLIDER_SECTION)?;
        }
        (JointKind::Revolute, _) => return Err(ModelError::Invalid {
            field: f("bearings"),
            reason:
                "a revolute joint with friction needs its bearing geometry (reaction_point, l_a, l_b, d_a, d_b, d_c)"
                    .into(),
        }),
        (JointKind::Prismatic, _) => {
            return Err(ModelError::Invalid {
                field: f("slider"),
                reason: "a prismatic joint with friction needs its slider geometry (centre, a, b, c)".into(),
            })
        }
    }
    Ok(())
}

/// Checks a link's inertial data. A link of mass 0 with a zero inertia
/// tensor is massless (a URDF link without `<inertial>`); every other link
/// has a mass that is positive (or 0 in a URDF) and a positive definite
/// tensor. `strict` (a Denavit–Hartenberg file) also requires a positive
/// mass and principal moments that satisfy the triangle inequality (a URDF
/// reader accepts a violation with a warning).
pub(super) fn validate_link(number: usize, link: &Link, strict: bool) -> Result<(), ModelError> {
    let f = |name: &str| format!("joint[{number}].link.{name}");
    let i = &link.inertia;
    // Mass 0: a massless link, or (URDF) one with rotational inertia only;
    // a Denavit–Hartenberg file (`strict`) gives every link a mass.
    if link.mass != 0.0 || strict {
        check_value(&f("mass"), link.mass, Range::MASS)?;
    }
    check_vec(&f("com"), &link.com, Range::GEOMETRY)?;
    const ENTRIES: [&str; 9] = ["xx", "xy", "xz", "xy", "yy", "yz", "xz", "yz", "zz"];
    for (name, x) in ENTRIES.iter().zip(i.iter()) {
        check_value(&f(&format!("inertia.{name}")), *x, Range::INERTIA)?;
    }
    if link.mass == 0.0 && i.amax() == 0.0 {
        return Ok(());
    }
    if (i - i.transpose()).amax() > 1e-12 * i.amax().max(1e-300) {
        return Err(ModelError::Invalid { field: f("inertia"), reason: "tensor is not symmetric".into() });
    }
    let eig = Mat3::symmetric_eigenvalues(i);
    let (min, max) = (eig.min(), eig.max());
    if min <= 0.0 {
        return Err(ModelError::Invalid {
            field: f("inertia"),
            reason: format!(
                "tensor is not positive definite (principal moments {:.6e}, {:.6e}, {:.6e})",
                eig[0], eig[1], eig[2]
            ),
        });
    }
    // A rigid body's principal moments satisfy I1 + I2 ≥ I3 for every ordering.
    if strict && eig.sum() - 2.0 * max < -1e-12 * max {
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
        check_value(field, h, Range::positive(IntegratorSettings::STEP_RANGE.1))?;
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
