//! The outputs of the FMU: one table that the variables
//! ([`super::variables`]), fmi2GetReal/fmi2GetBoolean and the CSV writer of
//! `simulate_reference` iterate. A new output is one row of [`OUTPUTS`]: its name, how many
//! variables it has, its unit, its description and how it is read from the
//! engine's [`State`].

use super::joints::joint_label;
use crate::model::{JointKind, Model};
use crate::stepper::State;

/// How many variables an output kind has, and how they are named.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Arity {
    /// One variable, `name`.
    Single,
    /// Three components, `name[k]`.
    Vector,
    /// One per joint, `name[i]`.
    PerJoint,
    /// Three components per joint, `name[i,k]`.
    PerJointVector,
    /// One per joint with a motor drive, `name[i]`; the value reads rotor r
    /// (the component index, see [`OutputKind::value`]).
    PerRotor,
    /// One variable, `name`, in models with motor drives only.
    SingleWithRotors,
}

/// The unit of an output kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputUnit {
    /// A count or a flag.
    None,
    /// The same unit for every variable.
    Fixed(&'static str),
    /// The joint's coordinate: rad or m.
    Coordinate,
    /// Its rate: rad/s or m/s.
    Rate,
    /// Its acceleration: rad/s2 or m/s2.
    Acceleration,
    /// Its generalized force: N.m or N.
    Force,
}

/// One kind of output.
#[derive(Debug, Clone, Copy)]
pub struct OutputKind {
    /// Base name of its variables.
    pub name: &'static str,
    /// How many variables it has.
    pub arity: Arity,
    /// Their unit.
    pub unit: OutputUnit,
    /// A Boolean (`value` ≠ 0 is true) rather than a Real.
    pub boolean: bool,
    /// The description of the variable of joint `j` and component `k` (0-based).
    pub description: fn(&Model, usize, usize) -> String,
    /// Its value in a state, for joint `j` and component `k` (0-based; for
    /// [`Arity::PerRotor`] the rotor's index r among the motor drives).
    pub value: fn(&State, usize, usize) -> f64,
}

/// One output variable: row `kind` of [`OUTPUTS`], joint `joint` and
/// component `component` (0-based; 0 where the kind has none).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Output {
    /// Index into [`OUTPUTS`].
    pub kind: usize,
    /// Joint, 0-based.
    pub joint: usize,
    /// Component, 0-based.
    pub component: usize,
}

impl Output {
    /// Its row of [`OUTPUTS`].
    pub fn kind(self) -> &'static OutputKind {
        &OUTPUTS[self.kind]
    }

    /// Its value in `state` (Booleans as 1 and 0).
    pub fn value(self, state: &State) -> f64 {
        (self.kind().value)(state, self.joint, self.component)
    }
}

/// The frame the reactions of joint `j` are resolved in, in words.
fn reaction_frame(model: &Model, j: usize) -> String {
    match &model.joint_names[j] {
        Some(name) => format!("in the URDF child link frame of joint `{name}`"),
        None => "joint frame (z = joint axis)".into(),
    }
}

const fn output(
    name: &'static str,
    arity: Arity,
    unit: OutputUnit,
    description: fn(&Model, usize, usize) -> String,
    value: fn(&State, usize, usize) -> f64,
) -> OutputKind {
    OutputKind { name, arity, unit, boolean: false, description, value }
}

/// Every output kind, in the order of the variables.
pub const OUTPUTS: &[OutputKind] = &[
    output(
        "q",
        Arity::PerJoint,
        OutputUnit::Coordinate,
        |m, j, _| format!("Joint coordinate q of {}", joint_label(m, j)),
        |s, j, _| s.q[j],
    ),
    output(
        "qd",
        Arity::PerJoint,
        OutputUnit::Rate,
        |m, j, _| format!("Joint velocity q' of {}", joint_label(m, j)),
        |s, j, _| s.qd[j],
    ),
    output(
        "qdd",
        Arity::PerJoint,
        OutputUnit::Acceleration,
        |m, j, _| format!("Joint acceleration q'' of {}", joint_label(m, j)),
        |s, j, _| s.qdd[j],
    ),
    OutputKind {
        name: "stick",
        arity: Arity::PerJoint,
        unit: OutputUnit::None,
        boolean: true,
        description: |m, j, _| {
            format!("True while {} is in its stiction phase (always false for a rigid drive)", joint_label(m, j))
        },
        value: |s, j, _| f64::from(u8::from(s.is_stuck(j))),
    },
    output(
        "n_stick",
        Arity::PerJoint,
        OutputUnit::None,
        |m, j, _| {
            format!(
                "Number of stiction phases {} has entered since initialization, also those that began and ended inside a communication step (a joint that starts stuck counts one)",
                joint_label(m, j)
            )
        },
        |s, j, _| s.stick_count[j] as f64,
    ),
    output(
        "t_stick",
        Arity::PerJoint,
        OutputUnit::Fixed("s"),
        |m, j, _| format!("Total time {} has spent in stiction phases since initialization", joint_label(m, j)),
        |s, j, _| s.stuck_time[j],
    ),
    output(
        "F_drive",
        Arity::PerJoint,
        OutputUnit::Force,
        |m, j, _| format!("Drive force F^d (2.1) of {}; for a rigid drive the force it supplies", joint_label(m, j)),
        |s, j, _| s.drive_force[j],
    ),
    output(
        "F_friction",
        Arity::PerJoint,
        OutputUnit::Force,
        |m, j, _| {
            format!("Friction force F^f of {}, signed so that F_drive - F_friction is the generalized force (3.10): while moving mu(v) L sgn(v) + b_v v; while stuck, the friction that holds the joint", joint_label(m, j))
        },
        |s, j, _| s.friction_force[j],
    ),
    output(
        "N_normal",
        Arity::PerJoint,
        OutputUnit::Fixed("N"),
        |m, j, _| {
            let what = match m.joints[j].kind {
                JointKind::Prismatic => "N_s of the slider (3.11)",
                JointKind::Revolute => "R_A + R_B + |f_z| of the bearings (3.13)-(3.15)",
            };
            format!("Normal load {what} of {}; 0 without friction geometry", joint_label(m, j))
        },
        |s, j, _| s.normal_load[j],
    ),
    output(
        "f",
        Arity::PerJointVector,
        OutputUnit::Fixed("N"),
        |m, j, k| {
            format!("Component {} of the force exerted by link {j} on link {} at the reaction reference point of joint {}, {}", k + 1, j + 1, j + 1, reaction_frame(m, j))
        },
        |s, j, k| s.reaction_force[j][k],
    ),
    output(
        "n",
        Arity::PerJointVector,
        OutputUnit::Fixed("N.m"),
        |m, j, k| {
            format!("Component {} of the moment exerted by link {j} on link {} about the reaction reference point of joint {}, {}", k + 1, j + 1, j + 1, reaction_frame(m, j))
        },
        |s, j, k| s.reaction_moment[j][k],
    ),
    output(
        "eps_joint",
        Arity::PerJoint,
        OutputUnit::Coordinate,
        |m, j, _| format!("Lag eps_i = q*_i - q_i of {} behind its drive", joint_label(m, j)),
        |s, j, _| s.joint_error(j),
    ),
    output(
        "eps",
        Arity::Single,
        OutputUnit::Fixed("m"),
        |_, _, _| {
            "End point error |x_E(q) - x_E(q*)| (4.1): distance of the gripper tip from where rigid drives would put it"
                .into()
        },
        |s, _, _| s.end_point_error(),
    ),
    output(
        "x_E",
        Arity::Vector,
        OutputUnit::Fixed("m"),
        |_, _, k| format!("Coordinate {} of the end point E in the base frame 0", k + 1),
        |s, _, k| s.end_point[k],
    ),
    output(
        "E_kin",
        Arity::Single,
        OutputUnit::Fixed("J"),
        |_, _, _| "Kinetic energy of the links".into(),
        |s, _, _| s.energy.kinetic,
    ),
    output(
        "E_pot",
        Arity::Single,
        OutputUnit::Fixed("J"),
        |_, _, _| "Potential energy of gravity (zero at the origin of frame 0)".into(),
        |s, _, _| s.energy.potential,
    ),
    output(
        "E_spring",
        Arity::Single,
        OutputUnit::Fixed("J"),
        |_, _, _| "Elastic energy of the drive springs".into(),
        |s, _, _| s.energy.spring,
    ),
    output(
        "W_drive",
        Arity::Single,
        OutputUnit::Fixed("J"),
        |_, _, _| {
            "Work done by the drives since initialization (flexible drive ends, rigid drives, and the motors' torque tau_m over theta_m)".into()
        },
        |s, _, _| s.energy.drive_work,
    ),
    output(
        "Q_friction",
        Arity::Single,
        OutputUnit::Fixed("J"),
        |_, _, _| "Heat produced by joint friction (dry and viscous) since initialization".into(),
        |s, _, _| s.energy.friction_heat,
    ),
    output(
        "Q_damping",
        Arity::Single,
        OutputUnit::Fixed("J"),
        |_, _, _| "Heat produced by drive damping since initialization".into(),
        |s, _, _| s.energy.damping_heat,
    ),
    output(
        "theta_m",
        Arity::PerRotor,
        OutputUnit::Fixed("rad"),
        |m, j, _| {
            format!("Rotor angle theta_m of the motor of {} (motor side); the motor encoder reads theta_m/N = q* in joint units", joint_label(m, j))
        },
        |s, _, r| s.theta_m(r),
    ),
    output(
        "omega_m",
        Arity::PerRotor,
        OutputUnit::Fixed("rad/s"),
        |m, j, _| format!("Rotor speed theta_m' of the motor of {}", joint_label(m, j)),
        |s, _, r| s.omega_m(r),
    ),
    OutputKind {
        name: "stick_m",
        arity: Arity::PerRotor,
        unit: OutputUnit::None,
        boolean: true,
        description: |m, j, _| {
            format!("True while the rotor of the motor of {} is held by its Coulomb friction tau_c", joint_label(m, j))
        },
        value: |s, _, r| f64::from(u8::from(s.is_stuck(s.rotor_coordinate(r)))),
    },
    output(
        "n_stick_m",
        Arity::PerRotor,
        OutputUnit::None,
        |m, j, _| {
            format!(
                "Number of stiction phases the rotor of the motor of {} has entered since initialization",
                joint_label(m, j)
            )
        },
        |s, _, r| s.stick_count[s.rotor_coordinate(r)] as f64,
    ),
    output(
        "tau_load",
        Arity::PerRotor,
        OutputUnit::Fixed("N.m"),
        |m, j, _| {
            format!(
                "Gear torque F/N on the rotor of the motor of {}, motor side (F = F_drive); at rest in static equilibrium, the motor torque that holds the link",
                joint_label(m, j)
            )
        },
        |s, _, r| s.gear_torque[r],
    ),
    output(
        "tau_f_m",
        Arity::PerRotor,
        OutputUnit::Fixed("N.m"),
        |m, j, _| {
            format!(
                "Coulomb friction torque tau_f of the motor of {}; while stuck, the torque that holds the rotor",
                joint_label(m, j)
            )
        },
        |s, _, r| s.friction_force[s.rotor_coordinate(r)],
    ),
    output(
        "E_rotor",
        Arity::SingleWithRotors,
        OutputUnit::Fixed("J"),
        |_, _, _| "Kinetic energy J_m theta_m'^2/2 of the motor rotors".into(),
        |s, _, _| s.energy.rotor_kinetic,
    ),
    output(
        "Q_motor",
        Arity::SingleWithRotors,
        OutputUnit::Fixed("J"),
        |_, _, _| "Heat produced by the motors' Coulomb and viscous friction since initialization".into(),
        |s, _, _| s.energy.motor_heat,
    ),
    output(
        "n_substeps",
        Arity::Single,
        OutputUnit::None,
        |_, _, _| {
            "Newmark sub-steps accepted since initialization, including those that end at a stick-slip or clearance event".into()
        },
        |s, _, _| s.steps.accepted as f64,
    ),
    output(
        "n_rejected",
        Arity::Single,
        OutputUnit::None,
        |_, _, _| "Sub-steps the error control rejected and retried shorter since initialization".into(),
        |s, _, _| s.steps.rejected as f64,
    ),
    output(
        "h_last",
        Arity::Single,
        OutputUnit::Fixed("s"),
        |_, _, _| {
            "Length of the last accepted sub-step (h_min where the error control needs the floor, h_max where the motion is smooth)".into()
        },
        |s, _, _| s.steps.last_h,
    ),
];
