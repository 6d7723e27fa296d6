//! The variables of the FMU for a given model, with their value references.
//!
//! Value references are the positions in the list (0, 1, 2, …), so the
//! modelDescription index of a variable is its value reference + 1. The list
//! is, in this order (n joints, structured names with 1-based indices):
//!
//! 1. inputs `q_star[i]`, `qd_star[i]`, `qdd_star[i]`, i = 1…n, then
//!    `tau_m[i]` for the joints with a motor drive;
//! 2. outputs, kind by kind in the order of the table
//!    [`OUTPUTS`](super::OUTPUTS) (`q[i]`, …, `f[i,k]`, …, `eps`, …);
//! 3. tunable parameters, one block per [`Parameter`] in [`Parameter::ALL`]
//!    order, each over the joints that have it (`Model::has_parameter`);
//! 4. start values `use_start_values`, `q_start[i]`, `qd_start[i]` (flexible
//!    and motor joints only), and for models with motor drives
//!    `theta_m_start[i]`, `omega_m_start[i]` and `static_start`;
//! 5. fixed integrator settings in [`Setting::ALL`] order.

use super::hash::Fnv1a128;
use super::joints::{joint_label, joint_units};
use super::outputs::{Arity, Output, OutputUnit, OUTPUTS};
use crate::model::{Drive, IntegratorSettings, JointKind, Model, Parameter, Range, INPUT_RANGES, MOTOR_TORQUE_RANGES};

/// Causality of a variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Causality {
    /// Set by the master before initialization (fixed) or between steps (tunable).
    Parameter,
    /// Set by the master between steps.
    Input,
    /// Computed by the FMU.
    Output,
}

/// Variability of a variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Variability {
    /// Set before initialization only.
    Fixed,
    /// May change between steps.
    Tunable,
    /// Changes at communication points only.
    Discrete,
    /// Changes continuously in time.
    Continuous,
}

/// The `initial` attribute (not written for inputs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Initial {
    /// The start value is the value.
    Exact,
    /// Computed during initialization.
    Calculated,
}

/// Type, unit, bounds and start value of a variable.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Type {
    /// An `fmi2Real`.
    Real {
        /// Unit name from [`super::UNITS`], none for dimensionless numbers.
        unit: Option<&'static str>,
        /// Smallest admissible value.
        min: Option<f64>,
        /// Largest admissible value.
        max: Option<f64>,
        /// Start value (parameters and inputs).
        start: Option<f64>,
    },
    /// An `fmi2Boolean`.
    Boolean {
        /// Start value (parameters).
        start: Option<bool>,
    },
}

/// Which drive input an input variable is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputField {
    /// q*, or the prescribed q of a rigid joint.
    Position,
    /// q̇*.
    Velocity,
    /// q̈*.
    Acceleration,
}

impl InputField {
    /// 0, 1, 2 for q*, q̇*, q̈*: the position in [`INPUT_RANGES`].
    pub fn index(self) -> usize {
        match self {
            InputField::Position => 0,
            InputField::Velocity => 1,
            InputField::Acceleration => 2,
        }
    }
}

/// A fixed setting of the stepper.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Setting {
    /// Largest internal sub-step h_max, s.
    HMax,
    /// Newmark β.
    NewmarkBeta,
    /// Newmark γ.
    NewmarkGamma,
    /// Relative tolerance of the Newmark iteration.
    Tolerance,
    /// Smallest internal sub-step h_min, s.
    HMin,
    /// Relative tolerance of the sub-steps' local error.
    ErrorTolerance,
}

impl Setting {
    /// Every setting, in layout order.
    pub const ALL: [Setting; 6] = [
        Setting::HMax,
        Setting::NewmarkBeta,
        Setting::NewmarkGamma,
        Setting::Tolerance,
        Setting::HMin,
        Setting::ErrorTolerance,
    ];

    /// Variable name.
    pub fn name(self) -> &'static str {
        match self {
            Setting::HMax => "h_max",
            Setting::NewmarkBeta => "newmark_beta",
            Setting::NewmarkGamma => "newmark_gamma",
            Setting::Tolerance => "tolerance",
            Setting::HMin => "h_min",
            Setting::ErrorTolerance => "error_tolerance",
        }
    }

    /// The value in `s`.
    pub fn get(self, s: &IntegratorSettings) -> f64 {
        match self {
            Setting::HMax => s.h_max,
            Setting::NewmarkBeta => s.beta,
            Setting::NewmarkGamma => s.gamma,
            Setting::Tolerance => s.tolerance,
            Setting::HMin => s.h_min,
            Setting::ErrorTolerance => s.error_tolerance,
        }
    }

    /// Stores `value` in `s` (check it with [`Setting::check`] first).
    pub fn set(self, s: &mut IntegratorSettings, value: f64) {
        match self {
            Setting::HMax => s.h_max = value,
            Setting::NewmarkBeta => s.beta = value,
            Setting::NewmarkGamma => s.gamma = value,
            Setting::Tolerance => s.tolerance = value,
            Setting::HMin => s.h_min = value,
            Setting::ErrorTolerance => s.error_tolerance = value,
        }
    }

    /// The setting's range: those of `Model::validate`, declared in the
    /// modelDescription and checked at fmi2SetReal so that a bad value is
    /// rejected by the call that sets it.
    fn range(self) -> Range {
        let closed = |(min, max): (f64, f64)| Range::closed(min, max);
        match self {
            Setting::HMax | Setting::HMin => closed(IntegratorSettings::STEP_RANGE),
            Setting::ErrorTolerance => Range::positive(IntegratorSettings::ERROR_TOLERANCE_RANGE.1),
            Setting::NewmarkBeta => closed(IntegratorSettings::BETA_RANGE),
            Setting::NewmarkGamma => closed(IntegratorSettings::GAMMA_RANGE),
            Setting::Tolerance => Range::positive(IntegratorSettings::TOLERANCE_MAX),
        }
    }

    /// Checks `value` against the setting's range.
    pub fn check(self, value: f64) -> Result<(), String> {
        let range = self.range();
        if value.is_finite() && range.contains(value) {
            return Ok(());
        }
        Err(format!("`{}` = {} is out of its range {range}", self.name(), crate::error::number(value)))
    }
}

/// What a variable stands for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    /// A drive input of joint `.1` (0-based).
    Input(InputField, usize),
    /// An output.
    Output(Output),
    /// A tunable model parameter of joint `.1` (0-based).
    Parameter(Parameter, usize),
    /// A fixed stepper setting.
    Setting(Setting),
    /// Start from `q_start`, `qd_start` instead of q = q*, at rest.
    UseStartValues,
    /// Start coordinate of flexible joint `.0` (0-based).
    StartQ(usize),
    /// Start velocity of flexible joint `.0` (0-based).
    StartQd(usize),
    /// The motor torque τ_m of motor joint `.0` (0-based).
    MotorTorque(usize),
    /// Start angle θ_m of the rotor of motor joint `.0` (0-based).
    StartThetaM(usize),
    /// Start speed θ̇_m of the rotor of motor joint `.0` (0-based).
    StartOmegaM(usize),
    /// Start the rotors in static equilibrium.
    StaticStart,
}

/// One scalar variable.
#[derive(Debug, Clone, PartialEq)]
pub struct Variable {
    /// Structured name, e.g. `f[2,3]`.
    pub name: String,
    /// Value reference (= position in the list).
    pub value_reference: u32,
    /// What it is, with symbol, unit and equation of the study.
    pub description: String,
    /// Causality.
    pub causality: Causality,
    /// Variability.
    pub variability: Variability,
    /// `initial` attribute; `None` for inputs.
    pub initial: Option<Initial>,
    /// Type, unit, bounds, start.
    pub ty: Type,
    /// What it maps to.
    pub quantity: Quantity,
}

/// Collects variables, numbering them as they come.
#[derive(Default)]
struct Builder(Vec<Variable>);

impl Builder {
    fn push(
        &mut self,
        name: String,
        description: String,
        kind: (Causality, Variability),
        ty: Type,
        quantity: Quantity,
    ) {
        let (causality, variability) = kind;
        let initial = match causality {
            Causality::Input => None,
            Causality::Parameter => Some(Initial::Exact),
            Causality::Output => Some(Initial::Calculated),
        };
        let value_reference = self.0.len() as u32;
        self.0.push(Variable { name, value_reference, description, causality, variability, initial, ty, quantity });
    }
}

const INPUT: (Causality, Variability) = (Causality::Input, Variability::Continuous);
const TUNABLE: (Causality, Variability) = (Causality::Parameter, Variability::Tunable);
const FIXED: (Causality, Variability) = (Causality::Parameter, Variability::Fixed);

fn real_start(unit: Option<&'static str>, start: f64) -> Type {
    Type::Real { unit, min: None, max: None, start: Some(start) }
}

/// The variables of `model`, value reference = position.
pub fn variables(model: &Model) -> Vec<Variable> {
    let mut b = Builder::default();
    inputs(&mut b, model);
    outputs(&mut b, model);
    parameters(&mut b, model);
    start_values(&mut b, model);
    for s in Setting::ALL {
        let range = s.range();
        let (unit, what) = match s {
            Setting::HMax => (
                Some("s"),
                "Largest internal sub-step h_max of the Newmark stepper (h_min = h_max: fixed sub-steps of that length)",
            ),
            Setting::HMin => (Some("s"), "Smallest internal sub-step h_min of the error-controlled Newmark stepper"),
            Setting::ErrorTolerance => (
                None,
                "Relative tolerance of the sub-steps' local error, per second of motion, weighted by the drive deflections (fmi2SetupExperiment's tolerance sets it)",
            ),
            Setting::NewmarkBeta => (None, "Newmark beta (1/4: average acceleration)"),
            Setting::NewmarkGamma => (None, "Newmark gamma"),
            Setting::Tolerance => (
                None,
                "Relative tolerance of the Newmark iteration on accelerations, reactions and friction forces (with error control no tighter than 1e-4 error_tolerance)",
            ),
        };
        let ty = Type::Real { unit, min: Some(range.min), max: Some(range.max), start: Some(s.get(&model.integrator)) };
        let description = format!("{what}; fixed after initialization{}", excluded_min(range));
        b.push(s.name().into(), description, FIXED, ty, Quantity::Setting(s));
    }
    b.0
}

/// For a range whose lower end is excluded (FMI 2.0's `min` is inclusive):
/// "; range (0, 1e6]: min = 0 excluded"; empty otherwise.
fn excluded_min(range: Range) -> String {
    if range.min_excluded {
        format!("; range {range}: min = {} excluded", crate::error::number(range.min))
    } else {
        String::new()
    }
}

fn inputs(b: &mut Builder, model: &Model) {
    let fields = [
        (InputField::Position, "q_star", "position"),
        (InputField::Velocity, "qd_star", "velocity"),
        (InputField::Acceleration, "qdd_star", "acceleration"),
    ];
    for (field, name, what) in fields {
        for (j, joint) in model.joints.iter().enumerate() {
            let u = joint_units(joint.kind);
            let unit = match field {
                InputField::Position => u.coordinate,
                InputField::Velocity => u.rate,
                InputField::Acceleration => u.acceleration,
            };
            let role = match joint.drive {
                Drive::Flexible { .. } => format!("Drive end {what} (q*, q*', q*'' of eq. 2.1)"),
                Drive::Rigid => format!("Prescribed {what}"),
                Drive::Motor { .. } => format!(
                    "Ignored while stepping (the drive end of a motor drive is its rotor, q* = theta_m/N; set tau_m[{}]); \
                     at initialization without start values, the start {what}",
                    j + 1
                ),
            };
            let description = format!(
                "{role} of {}, at the start of the communication step; held as the polynomial q* + q*' t + q*'' t^2/2 across it",
                joint_label(model, j)
            );
            let range = INPUT_RANGES[field.index()].1;
            let ty = Type::Real { unit: Some(unit), min: Some(range.min), max: Some(range.max), start: Some(0.0) };
            b.push(format!("{name}[{}]", j + 1), description, INPUT, ty, Quantity::Input(field, j));
        }
    }
    for j in model.motor_joints() {
        let range = MOTOR_TORQUE_RANGES[0].1;
        let description = format!(
            "Motor torque tau_m of {}, on the rotor (motor side; J_m theta_m'' = tau_m - F/N - b_m theta_m' - tau_f), at the start of the \
             communication step; held as tau_m + tau_m' t + tau_m'' t^2/2 across it with the derivatives of fmi2SetRealInputDerivatives",
            joint_label(model, j)
        );
        let ty = Type::Real { unit: Some("N.m"), min: Some(range.min), max: Some(range.max), start: Some(0.0) };
        b.push(format!("tau_m[{}]", j + 1), description, INPUT, ty, Quantity::MotorTorque(j));
    }
}

/// Unit and description of parameter `p` of joint `j` (0-based).
fn parameter_meaning(model: &Model, p: Parameter, j: usize) -> (Option<&'static str>, String) {
    let u = joint_units(model.joints[j].kind);
    let (unit, what) = match p {
        Parameter::Stiffness => (Some(u.stiffness), "Drive stiffness k (2.1)"),
        Parameter::Damping => (Some(u.damping), "Drive damping h (2.1)"),
        Parameter::Clearance => (Some(u.coordinate), "Drive clearance (backlash) Delta (2.1)"),
        Parameter::MuKinetic => (None, "Kinetic friction coefficient mu_k"),
        Parameter::MuStatic => (None, "Static friction coefficient mu_s (>= mu_k), stiction limit (3.16)"),
        Parameter::StribeckVelocity => {
            (Some(u.rate), "Stribeck velocity v_s of mu(v) = mu_k + (mu_s - mu_k) exp(-|v|/v_s); 0: constant mu_k")
        }
        Parameter::Viscous => (
            Some(u.damping),
            "Viscous friction coefficient b_v: a moving joint's friction is mu(v) L sgn(v) + b_v v, the viscous part \
             independent of the normal load (0: dry friction only, the study's law)",
        ),
        Parameter::SliderA => (Some("m"), "Slider length a along the axis (3.11)"),
        Parameter::SliderB => (Some("m"), "Slider cross-section b along x of the joint frame (3.11)"),
        Parameter::SliderC => (Some("m"), "Slider cross-section c along y of the joint frame (3.11)"),
        Parameter::DiameterA => (Some("m"), "Diameter d_A of radial bearing A (3.15)"),
        Parameter::DiameterB => (Some("m"), "Diameter d_B of radial bearing B (3.15)"),
        Parameter::DiameterC => (Some("m"), "Diameter d_C of thrust bearing C (3.15)"),
        Parameter::LengthA => (Some("m"), "Distance l_A of bearing A below the reaction reference point (3.13)"),
        Parameter::LengthB => (Some("m"), "Distance l_B of bearing B above the reaction reference point (3.13)"),
        Parameter::Mass => (Some("kg"), "Mass of the link moved by"),
        Parameter::GearRatio => (
            match model.joints[j].kind {
                JointKind::Revolute => None,
                JointKind::Prismatic => Some("rad/m"),
            },
            "Gear ratio N (motor rad per joint rad, or per m of a prismatic joint): q* = theta_m/N",
        ),
        Parameter::RotorInertia => (Some("kg.m2"), "Rotor inertia J_m on the motor side"),
        Parameter::MotorViscous => (Some("N.m.s/rad"), "Viscous friction b_m of motor and gear, motor side"),
        Parameter::MotorCoulomb => {
            (Some("N.m"), "Coulomb friction level tau_c of motor and gear, motor side, with stiction (stuck while |tau_m - F/N| <= tau_c)")
        }
    };
    let of = if p == Parameter::Mass { "" } else { " of" };
    let when = if p.is_tunable() {
        "tunable between steps, relations (mu_s >= mu_k, ...) checked at the next step"
    } else {
        "fixed after initialization"
    };
    (unit, format!("{what}{of} {}; {when}", joint_label(model, j)))
}

fn parameters(b: &mut Builder, model: &Model) {
    for p in Parameter::ALL {
        for j in 0..model.nq() {
            let Some(value) = model.parameter(p, j) else { continue };
            let (unit, mut description) = parameter_meaning(model, p, j);
            // The physical range (a positive parameter declares min = 0,
            // and 0 itself is refused with its range in the message). FMI's
            // min is inclusive, so the description says that 0 is excluded.
            let range = p.range();
            description.push_str(&excluded_min(range));
            let ty = Type::Real { unit, min: Some(range.min), max: Some(range.max), start: Some(value) };
            let kind = if p.is_tunable() { TUNABLE } else { FIXED };
            b.push(format!("{}[{}]", p.name(), j + 1), description, kind, ty, Quantity::Parameter(p, j));
        }
    }
}

fn start_values(b: &mut Builder, model: &Model) {
    b.push(
        "use_start_values".into(),
        "false: flexible joints start at q = q_star, at rest (stuck where friction holds them); true: at q_start[i], qd_start[i]".into(),
        FIXED,
        Type::Boolean { start: Some(false) },
        Quantity::UseStartValues,
    );
    let flexible: Vec<usize> = (0..model.nq()).filter(|&j| model.joints[j].drive.is_flexible()).collect();
    for &j in &flexible {
        let unit = joint_units(model.joints[j].kind).coordinate;
        let description = format!("Start coordinate q of {}, used when use_start_values = true", joint_label(model, j));
        b.push(format!("q_start[{}]", j + 1), description, FIXED, real_start(Some(unit), 0.0), Quantity::StartQ(j));
    }
    for &j in &flexible {
        let unit = joint_units(model.joints[j].kind).rate;
        let description = format!("Start velocity q' of {}, used when use_start_values = true", joint_label(model, j));
        b.push(format!("qd_start[{}]", j + 1), description, FIXED, real_start(Some(unit), 0.0), Quantity::StartQd(j));
    }
    let motors = model.motor_joints();
    for &j in &motors {
        let description = format!(
            "Start angle theta_m of the rotor of {}, used when use_start_values = true and static_start = false",
            joint_label(model, j)
        );
        b.push(
            format!("theta_m_start[{}]", j + 1),
            description,
            FIXED,
            real_start(Some("rad"), 0.0),
            Quantity::StartThetaM(j),
        );
    }
    for &j in &motors {
        let description = format!(
            "Start speed theta_m' of the rotor of {}, used when use_start_values = true",
            joint_label(model, j)
        );
        b.push(
            format!("omega_m_start[{}]", j + 1),
            description,
            FIXED,
            real_start(Some("rad/s"), 0.0),
            Quantity::StartOmegaM(j),
        );
    }
    if !motors.is_empty() {
        b.push(
            "static_start".into(),
            "false: each rotor starts at rest with its gear spring unloaded, theta_m = N q (or at theta_m_start[i] with use_start_values); \
             true: at rest, turned so that the gear spring holds its link at rest against gravity and the other loads at the start \
             (theta_m = N (q + F/k + sgn(F) Delta)); tau_load[i] then reads the motor torque that holds it"
                .into(),
            FIXED,
            Type::Boolean { start: Some(false) },
            Quantity::StaticStart,
        );
    }
}

/// Fingerprint of a model file and the variable layout made from it: two
/// FMUs with the same fingerprint read and write the same variables the same
/// way.
pub fn model_hash(model_text: &str, variables: &[Variable]) -> u128 {
    let mut h = Fnv1a128::default();
    h.field(b"StickSlipManipulator FMI 2.0 co-simulation, layout 1").field(model_text.as_bytes());
    for v in variables {
        let ty = match v.ty {
            Type::Real { .. } => b"R",
            Type::Boolean { .. } => b"B",
        };
        h.field(v.name.as_bytes()).field(&v.value_reference.to_le_bytes()).field(ty);
    }
    h.finish()
}

/// The GUID of the FMU: [`model_hash`] in the usual `{8-4-4-4-12}` form.
pub fn guid(model_text: &str, variables: &[Variable]) -> String {
    let h = format!("{:032x}", model_hash(model_text, variables));
    format!("{{{}-{}-{}-{}-{}}}", &h[0..8], &h[8..12], &h[12..16], &h[16..20], &h[20..32])
}

/// The output variables of `model`, kind by kind in [`OUTPUTS`] order; a
/// per-joint vector kind runs over the joints, then the components.
fn outputs(b: &mut Builder, model: &Model) {
    let n = model.nq();
    let motors = model.motor_joints();
    for (index, kind) in OUTPUTS.iter().enumerate() {
        let members: Vec<(usize, usize, String)> = match kind.arity {
            Arity::Single => vec![(0, 0, kind.name.to_string())],
            Arity::SingleWithRotors if motors.is_empty() => vec![],
            Arity::SingleWithRotors => vec![(0, 0, kind.name.to_string())],
            Arity::PerRotor => {
                motors.iter().enumerate().map(|(r, &j)| (j, r, format!("{}[{}]", kind.name, j + 1))).collect()
            }
            Arity::Vector => (0..3).map(|k| (0, k, format!("{}[{}]", kind.name, k + 1))).collect(),
            Arity::PerJoint => (0..n).map(|j| (j, 0, format!("{}[{}]", kind.name, j + 1))).collect(),
            Arity::PerJointVector => (0..n)
                .flat_map(|j| (0..3).map(move |k| (j, k, format!("{}[{},{}]", kind.name, j + 1, k + 1))))
                .collect(),
        };
        for (j, k, name) in members {
            let units = joint_units(model.joints.get(j).map_or(JointKind::Revolute, |joint| joint.kind));
            let unit = match kind.unit {
                OutputUnit::None => None,
                OutputUnit::Fixed(u) => Some(u),
                OutputUnit::Coordinate => Some(units.coordinate),
                OutputUnit::Rate => Some(units.rate),
                OutputUnit::Acceleration => Some(units.acceleration),
                OutputUnit::Force => Some(units.force),
            };
            let (variability, ty) = if kind.boolean {
                (Variability::Discrete, Type::Boolean { start: None })
            } else {
                (Variability::Continuous, Type::Real { unit, min: None, max: None, start: None })
            };
            let quantity = Quantity::Output(Output { kind: index, joint: j, component: k });
            b.push(name, (kind.description)(model, j, k), (Causality::Output, variability), ty, quantity);
        }
    }
}
