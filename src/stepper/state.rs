//! The state of a simulation: what evolves in time and what is reported.

use crate::math::Vec3;
use crate::model::{Drive, Model};

/// Phase of a joint (study section 3.2, eqs. 3.16–3.18).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Rigid drive: q, q̇, q̈ are kinematic inputs.
    Prescribed,
    /// Stiction phase: the joint stands still, held by static friction; its
    /// equation is removed from the system.
    Stuck,
    /// Kinetic friction phase in direction +1 or −1; the joint has an equation
    /// of motion (3.9) and friction opposes this direction.
    Slipping(i8),
}

/// Everything that evolves, plus the reported quantities at the current time.
/// Restoring a `State` restores the exact continuation.
///
/// **Coordinates.** The vectors `q`, `qd`, `qdd`, `phase`, `margin`,
/// `friction_force`, `stick_count` and `stuck_time` run over the model's
/// generalized coordinates ([`Model::n_coordinates`]): the n joint
/// coordinates, then the rotor angle θ_m of each motor drive in chain order
/// ([`Model::motor_joints`]). The other per-joint vectors have n entries;
/// `motor_torque` has one per motor drive.
#[derive(Debug, Clone, PartialEq)]
pub struct State {
    /// Time, s.
    pub time: f64,
    /// Coordinates: joint coordinates q (m or rad), then rotor angles θ_m (rad).
    pub q: Vec<f64>,
    /// Their velocities q̇, θ̇_m.
    pub qd: Vec<f64>,
    /// Their accelerations q̈, θ̈_m.
    pub qdd: Vec<f64>,
    /// Phase of every coordinate (a rotor's: stuck or slipping in its
    /// motor friction).
    pub phase: Vec<Phase>,
    /// Drive position q* at the current time: the input of a flexible drive,
    /// the prescribed q of a rigid one, θ_m/N of a motor drive.
    pub q_star: Vec<f64>,
    /// Drive input rate q̇* at the current time.
    pub qd_star: Vec<f64>,
    /// Drive force F^d (2.1); for a rigid joint the force the drive supplies.
    pub drive_force: Vec<f64>,
    /// Damping part h·δ·(q̇* − q̇) of the drive force.
    pub damping_force: Vec<f64>,
    /// Friction force F^f, signed so that F^d − F^f is the generalized force
    /// (3.10); while stuck, the friction that holds the joint. For a rotor
    /// coordinate, the motor's Coulomb friction τ_f (while stuck, the torque
    /// that holds the rotor), N·m.
    pub friction_force: Vec<f64>,
    /// Normal load of the joint's contact, N.
    pub normal_load: Vec<f64>,
    /// Friction per unit coefficient (μ·`lever_load` = friction).
    pub lever_load: Vec<f64>,
    /// Distance to the next phase change: d·q̇ while slipping in direction d,
    /// the static reserve μ_s·L − |F^d − F*| while stuck (3.16), +∞ otherwise.
    pub margin: Vec<f64>,
    /// |q* − q| − Δ of a flexible drive with clearance Δ > 0: it changes sign
    /// where δ of (2.1) switches; +∞ for the other joints.
    pub clearance_margin: Vec<f64>,
    /// Joint force at the reaction reference point, in link i's frame as the
    /// model source describes it (see [`Joint::reported_axes`](crate::model::Joint::reported_axes)), N.
    pub reaction_force: Vec<Vec3>,
    /// Joint moment about the reaction reference point, in the same frame, N·m.
    pub reaction_moment: Vec<Vec3>,
    /// Number of stiction phases each coordinate has entered since
    /// initialization (one that starts stuck counts one).
    pub stick_count: Vec<u64>,
    /// Total time each coordinate has spent stuck since initialization, s.
    pub stuck_time: Vec<f64>,
    /// Motor torque τ_m of each motor drive at the current time, N·m.
    pub motor_torque: Vec<f64>,
    /// Gear torque F/N on the rotor of each motor drive, N·m.
    pub gear_torque: Vec<f64>,
    /// Energy account.
    pub energy: Energy,
    /// End point E of the flexible manipulator in frame 0, m.
    pub end_point: Vec3,
    /// End point of the same manipulator with rigid drives (q = q*), m.
    pub end_point_rigid: Vec3,
    /// Sub-steps taken and the error control's next proposal.
    pub steps: StepStatistics,
}

/// The record of the stepper's sub-steps since initialization.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepStatistics {
    /// Accepted sub-steps (including those that end at an event).
    pub accepted: u64,
    /// Sub-steps rejected by the error control and retried shorter.
    pub rejected: u64,
    /// Length of the last accepted sub-step, s.
    pub last_h: f64,
    /// Length the error control proposes for the next sub-step, s (0: none
    /// yet, the stepper starts with h_min).
    pub next_h: f64,
}

/// Energies and works, J.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Energy {
    /// Kinetic energy of the links.
    pub kinetic: f64,
    /// Potential energy of gravity (zero at the origin of frame 0).
    pub potential: f64,
    /// Elastic energy of the drive springs.
    pub spring: f64,
    /// Work done by the drives since initialization (flexible drive ends and
    /// rigid drives).
    pub drive_work: f64,
    /// Heat produced by joint friction since initialization.
    pub friction_heat: f64,
    /// Heat produced by drive damping since initialization.
    pub damping_heat: f64,
    /// Kinetic energy ½·J_m·θ̇_m² of the motor rotors.
    pub rotor_kinetic: f64,
    /// Heat produced by the motors' Coulomb and viscous friction since
    /// initialization.
    pub motor_heat: f64,
}

impl Energy {
    /// Kinetic (links and rotors) + gravity + spring energy.
    pub fn total(&self) -> f64 {
        self.kinetic + self.potential + self.spring + self.rotor_kinetic
    }

    /// E − (W_drive − Q_friction − Q_damping − Q_motor): constant in time
    /// when the account closes.
    pub fn balance(&self) -> f64 {
        self.total() - self.drive_work + self.friction_heat + self.damping_heat + self.motor_heat
    }
}

impl State {
    /// A state sized for `model`, at rest at q = 0.
    pub fn new(model: &Model) -> State {
        let n = model.nq();
        let nc = model.n_coordinates();
        let phase = model
            .joints
            .iter()
            .map(|j| if j.drive.is_flexible() { Phase::Stuck } else { Phase::Prescribed })
            .chain(std::iter::repeat_n(Phase::Stuck, nc - n))
            .collect();
        State {
            time: 0.0,
            q: vec![0.0; nc],
            qd: vec![0.0; nc],
            qdd: vec![0.0; nc],
            phase,
            q_star: vec![0.0; n],
            qd_star: vec![0.0; n],
            drive_force: vec![0.0; n],
            damping_force: vec![0.0; n],
            friction_force: vec![0.0; nc],
            normal_load: vec![0.0; n],
            lever_load: vec![0.0; n],
            margin: vec![f64::INFINITY; nc],
            clearance_margin: vec![f64::INFINITY; n],
            reaction_force: vec![Vec3::zeros(); n],
            reaction_moment: vec![Vec3::zeros(); n],
            stick_count: vec![0; nc],
            stuck_time: vec![0.0; nc],
            motor_torque: vec![0.0; nc - n],
            gear_torque: vec![0.0; nc - n],
            energy: Energy::default(),
            end_point: Vec3::zeros(),
            end_point_rigid: Vec3::zeros(),
            steps: StepStatistics::default(),
        }
    }

    /// Copies `other` into `self` without allocating (both must have the same
    /// number of joints; the derived `clone_from` would allocate every vector).
    pub fn copy_from(&mut self, other: &State) {
        let State {
            time,
            q,
            qd,
            qdd,
            phase,
            q_star,
            qd_star,
            drive_force,
            damping_force,
            friction_force,
            normal_load,
            lever_load,
            margin,
            clearance_margin,
            reaction_force,
            reaction_moment,
            stick_count,
            stuck_time,
            motor_torque,
            gear_torque,
            energy,
            end_point,
            end_point_rigid,
            steps,
        } = other;
        self.time = *time;
        self.q.copy_from_slice(q);
        self.qd.copy_from_slice(qd);
        self.qdd.copy_from_slice(qdd);
        self.phase.copy_from_slice(phase);
        self.q_star.copy_from_slice(q_star);
        self.qd_star.copy_from_slice(qd_star);
        self.drive_force.copy_from_slice(drive_force);
        self.damping_force.copy_from_slice(damping_force);
        self.friction_force.copy_from_slice(friction_force);
        self.normal_load.copy_from_slice(normal_load);
        self.lever_load.copy_from_slice(lever_load);
        self.margin.copy_from_slice(margin);
        self.clearance_margin.copy_from_slice(clearance_margin);
        self.reaction_force.copy_from_slice(reaction_force);
        self.reaction_moment.copy_from_slice(reaction_moment);
        self.stick_count.copy_from_slice(stick_count);
        self.stuck_time.copy_from_slice(stuck_time);
        self.motor_torque.copy_from_slice(motor_torque);
        self.gear_torque.copy_from_slice(gear_torque);
        self.energy = *energy;
        self.end_point = *end_point;
        self.end_point_rigid = *end_point_rigid;
        self.steps = *steps;
    }

    /// Makes `self` the start of a sub-step from `other`, the current state:
    /// takes its time and swaps in what a sub-step reads of its start (q, q̇,
    /// q̈, q*, q̇*, the forces whose work is booked and the phase margins) instead
    /// of copying them. Those fields of `other` are left stale: solving the
    /// sub-step overwrites every one of them.
    #[inline(always)]
    pub(crate) fn take_step_start(&mut self, other: &mut State) {
        self.time = other.time;
        std::mem::swap(&mut self.q, &mut other.q);
        std::mem::swap(&mut self.qd, &mut other.qd);
        std::mem::swap(&mut self.qdd, &mut other.qdd);
        std::mem::swap(&mut self.q_star, &mut other.q_star);
        std::mem::swap(&mut self.qd_star, &mut other.qd_star);
        std::mem::swap(&mut self.drive_force, &mut other.drive_force);
        std::mem::swap(&mut self.damping_force, &mut other.damping_force);
        std::mem::swap(&mut self.friction_force, &mut other.friction_force);
        std::mem::swap(&mut self.margin, &mut other.margin);
        std::mem::swap(&mut self.clearance_margin, &mut other.clearance_margin);
        std::mem::swap(&mut self.motor_torque, &mut other.motor_torque);
    }

    /// Number of joints n.
    pub fn nq(&self) -> usize {
        self.q_star.len()
    }

    /// Number of coordinates: n joints and the rotors of the motor drives.
    pub fn n_coordinates(&self) -> usize {
        self.q.len()
    }

    /// The coordinate index of rotor `r` (the r-th motor drive in chain
    /// order, 0-based).
    pub fn rotor_coordinate(&self, r: usize) -> usize {
        self.nq() + r
    }

    /// Rotor angle θ_m of the r-th motor drive, rad.
    pub fn theta_m(&self, r: usize) -> f64 {
        self.q[self.rotor_coordinate(r)]
    }

    /// Rotor speed θ̇_m of the r-th motor drive, rad/s.
    pub fn omega_m(&self, r: usize) -> f64 {
        self.qd[self.rotor_coordinate(r)]
    }

    /// Every value a user can read is finite: coordinates, inputs, forces,
    /// loads, reactions, stuck times, energies, end points and the last
    /// sub-step. Otherwise the first one that is not, by its field name and
    /// 1-based joint (`normal_load[1]`), and its value.
    pub fn check_finite(&self) -> Result<(), (String, f64)> {
        let joint_fields: [(&str, &[f64]); 12] = [
            ("q", &self.q),
            ("qd", &self.qd),
            ("qdd", &self.qdd),
            ("q_star", &self.q_star),
            ("qd_star", &self.qd_star),
            ("drive_force", &self.drive_force),
            ("friction_force", &self.friction_force),
            ("normal_load", &self.normal_load),
            ("lever_load", &self.lever_load),
            ("stuck_time", &self.stuck_time),
            ("motor_torque", &self.motor_torque),
            ("gear_torque", &self.gear_torque),
        ];
        for (name, values) in joint_fields {
            if let Some((i, v)) = values.iter().enumerate().find(|(_, v)| !v.is_finite()) {
                return Err((format!("{name}[{}]", i + 1), *v));
            }
        }
        for (name, vectors) in [("reaction_force", &self.reaction_force), ("reaction_moment", &self.reaction_moment)] {
            for (i, v) in vectors.iter().enumerate() {
                if let Some((k, x)) = v.iter().enumerate().find(|(_, x)| !x.is_finite()) {
                    return Err((format!("{name}[{},{}]", i + 1, k + 1), *x));
                }
            }
        }
        let e = &self.energy;
        let scalars = [
            ("energy.kinetic", e.kinetic),
            ("energy.potential", e.potential),
            ("energy.spring", e.spring),
            ("energy.drive_work", e.drive_work),
            ("energy.friction_heat", e.friction_heat),
            ("energy.damping_heat", e.damping_heat),
            ("energy.rotor_kinetic", e.rotor_kinetic),
            ("energy.motor_heat", e.motor_heat),
            ("end_point_error", self.end_point_error()),
            ("steps.last_h", self.steps.last_h),
        ];
        for (name, v) in scalars {
            if !v.is_finite() {
                return Err((name.to_string(), v));
            }
        }
        for (name, p) in [("end_point", &self.end_point), ("end_point_rigid", &self.end_point_rigid)] {
            if let Some((k, x)) = p.iter().enumerate().find(|(_, x)| !x.is_finite()) {
                return Err((format!("{name}[{}]", k + 1), *x));
            }
        }
        Ok(())
    }

    /// True if joint `i` (0-based) is in its stiction phase.
    pub fn is_stuck(&self, i: usize) -> bool {
        self.phase[i] == Phase::Stuck
    }

    /// ε_i = q*_i − q_i, the lag of joint `i` (0-based) behind its drive.
    pub fn joint_error(&self, i: usize) -> f64 {
        self.q_star[i] - self.q[i]
    }

    /// ε = |x_E(q) − x_E(q̂)| (study eq. 4.1), m.
    pub fn end_point_error(&self) -> f64 {
        (self.end_point - self.end_point_rigid).norm()
    }

    /// True if the state fits `model` (sizes, and phases that agree with the
    /// drives).
    pub fn fits(&self, model: &Model) -> bool {
        let n = model.nq();
        let nc = model.n_coordinates();
        let per_joint = [
            self.q_star.len(),
            self.qd_star.len(),
            self.drive_force.len(),
            self.damping_force.len(),
            self.normal_load.len(),
            self.lever_load.len(),
            self.clearance_margin.len(),
            self.reaction_force.len(),
            self.reaction_moment.len(),
        ];
        let per_coordinate = [
            self.q.len(),
            self.qd.len(),
            self.qdd.len(),
            self.phase.len(),
            self.friction_force.len(),
            self.margin.len(),
            self.stick_count.len(),
            self.stuck_time.len(),
        ];
        per_joint.iter().all(|&s| s == n)
            && per_coordinate.iter().all(|&s| s == nc)
            && self.motor_torque.len() == nc - n
            && self.gear_torque.len() == nc - n
            && model.joints.iter().zip(&self.phase).all(|(j, p)| match j.drive {
                Drive::Rigid => *p == Phase::Prescribed,
                Drive::Flexible { .. } | Drive::Motor { .. } => *p != Phase::Prescribed,
            })
            && self.phase[n..].iter().all(|p| *p != Phase::Prescribed)
    }
}
