//! A motor-side servo for motor drives: runs a motion written for
//! prescribed drive positions (such as the reference motion) on the same arm
//! with motor drives.

use crate::{Model, State};

/// A motor-side position servo with feed-forward that makes the rotor of
/// every motor drive follow a motion q*(t) of its joint, θ_m → N·q*:
///
/// τ_m = J_m·N·q̈* + F/N + K_p·(N·q* − θ_m) + K_d·(N·q̇* − θ̇_m)
///
/// (the torque that accelerates the rotor along the motion and holds the
/// gear load it measures, plus a PD correction), with K_p = J_m·ω_c² and
/// K_d = 2ζ·J_m·ω_c for the rotor alone. It reads the motor encoder, the
/// rotor speed and the gear load of the state, as a drive with a torque
/// sensor would: the way to run a motion written for flexible drives (such
/// as [`reference_inputs`](crate::motion::reference_inputs)) on the same arm with motor drives, e.g. to
/// compare their cost.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotorServo {
    /// Bandwidth ω_c of the rotor loop, rad/s.
    pub bandwidth: f64,
    /// Damping ratio ζ of the rotor loop.
    pub damping_ratio: f64,
}

impl Default for RotorServo {
    /// ω_c = 2π·40 rad/s, ζ = 0.7: well inside a 1 kHz sampling rate.
    fn default() -> Self {
        RotorServo { bandwidth: std::f64::consts::TAU * 40.0, damping_ratio: 0.7 }
    }
}

impl RotorServo {
    /// The motor torques and their rates, one per joint (0 for joints
    /// without a motor drive), that make `model`'s rotors in `state` follow
    /// the motion (`q_star`, `qd_star`, `qdd_star`) of their joints. The
    /// rate is that of the PD correction along the current motion, so that
    /// the torque held over a communication step as τ_m + τ̇_m·t changes
    /// smoothly instead of by a step at every sample, as the current loop of
    /// a drive makes it.
    pub fn torques(
        &self,
        model: &Model,
        state: &State,
        q_star: &[f64],
        qd_star: &[f64],
        qdd_star: &[f64],
    ) -> (Vec<f64>, Vec<f64>) {
        let (mut tau, mut rate) = (vec![0.0; model.nq()], vec![0.0; model.nq()]);
        for (r, j) in model.motor_joints().into_iter().enumerate() {
            let Some(rotor) = model.joints[j].drive.rotor() else { continue };
            let (n, inertia) = (rotor.gear_ratio, rotor.inertia);
            let kp = inertia * self.bandwidth * self.bandwidth;
            let kd = 2.0 * self.damping_ratio * inertia * self.bandwidth;
            let c = state.rotor_coordinate(r);
            tau[j] = inertia * n * qdd_star[j]
                + state.gear_torque[r]
                + kp * (n * q_star[j] - state.q[c])
                + kd * (n * qd_star[j] - state.qd[c]);
            rate[j] = kp * (n * qd_star[j] - state.qd[c]) + kd * (n * qdd_star[j] - state.qdd[c]);
        }
        (tau, rate)
    }
}
