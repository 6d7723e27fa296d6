//! The rotor of a motor drive: its equation of motion and its friction.
//!
//! A motor drive is the spring of (2.1) whose drive end is not prescribed
//! but turned by a motor through a gear of ratio N: q* = θ_m/N. The gear
//! force F of (2.1) acts on the link as for a flexible drive, and F/N acts
//! back on the rotor (the gear transmits power: F·q̇* = (F/N)·θ̇_m):
//!
//! J_m·θ̈_m = τ_m − F/N − b_m·θ̇_m − τ_f
//!
//! with the motor torque τ_m an input, the viscous friction b_m of motor and
//! gear, and their Coulomb friction τ_f of level τ_c with true stiction,
//! treated like the joints' dry friction (3.16)–(3.18): a stuck rotor stays
//! at rest while the torque that holds it, τ_m − F/N, is within ±τ_c; a
//! slipping one feels τ_f = τ_c·sgn θ̇_m until its speed crosses zero.
//!
//! The rotor's kinetic energy is ½·J_m·θ̇_m², its own rotation only: the
//! rotor is carried by the link before it, but its inertia about the other
//! axes is lumped into that link, the standard assumption of the elastic
//! joint model (Spong 1987, "Modeling and control of elastic joint robots",
//! J. Dyn. Sys. Meas. Control 109, assumption A2); the gear ratios of robot
//! drives (50–160) make the neglected gyroscopic coupling N² times smaller
//! than the rotor's own inertia term.

use crate::model::Rotor;

/// The torques on a rotor in its current phase, and its distance to the
/// next phase change.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotorTorques {
    /// τ_f: the Coulomb friction of a slipping rotor, or while stuck the
    /// torque that holds it, τ_m − F/N, N·m.
    pub friction: f64,
    /// The rest of the rotor's equation, τ_m − F/N − b_m·θ̇_m − τ_f − J_m·θ̈_m:
    /// zero when it holds (0 for a stuck rotor), N·m.
    pub residual: f64,
    /// The phase holds while ≥ 0: the static reserve τ_c − |τ_m − F/N| of a
    /// stuck rotor; d·θ̇_m of one slipping in direction d whose friction can
    /// hold it (τ_c > 0), +∞ otherwise.
    pub margin: f64,
    /// The sum of the magnitudes of the equation's terms, N·m: the scale of
    /// its residual.
    pub scale: f64,
}

/// The torques on `rotor` driven by τ_m = `motor_torque` against the gear
/// force `gear_force` F (link side, eq. 2.1) at speed θ̇_m = `omega` and
/// acceleration θ̈_m = `alpha`; `slip` is `None` for a stuck rotor and its
/// direction ±1 for a slipping one.
#[inline(always)]
pub fn rotor_torques(
    rotor: &Rotor,
    motor_torque: f64,
    gear_force: f64,
    omega: f64,
    alpha: f64,
    slip: Option<i8>,
) -> RotorTorques {
    let load = gear_force / rotor.gear_ratio;
    let held = motor_torque - load;
    match slip {
        None => RotorTorques {
            friction: held,
            residual: 0.0,
            margin: rotor.coulomb - held.abs(),
            scale: motor_torque.abs() + load.abs(),
        },
        Some(direction) => {
            let d = direction as f64;
            let friction = d * rotor.coulomb;
            let viscous = rotor.viscous * omega;
            let inertia = rotor.inertia * alpha;
            RotorTorques {
                friction,
                residual: held - viscous - friction - inertia,
                margin: if rotor.coulomb > 0.0 { d * omega } else { f64::INFINITY },
                scale: motor_torque.abs() + load.abs() + viscous.abs() + friction.abs() + inertia.abs(),
            }
        }
    }
}

/// True if the rotor's friction can hold it at rest (τ_c > 0): only such a
/// rotor can enter a stiction phase.
#[inline(always)]
pub fn rotor_holds_statically(rotor: &Rotor) -> bool {
    rotor.coulomb > 0.0
}

/// −∂/∂θ̈_m of a slipping rotor's equation in a Newmark sub-step of length
/// `h`, without the gear: J_m + γh·b_m (θ̇_m moves by γh per unit θ̈_m).
#[inline(always)]
pub fn rotor_acceleration_inertia(rotor: &Rotor, h: f64, gamma: f64) -> f64 {
    rotor.inertia + gamma * h * rotor.viscous
}

#[cfg(test)]
mod tests {
    use super::*;

    const ROTOR: Rotor = Rotor { gear_ratio: 100.0, inertia: 2e-4, viscous: 1e-3, coulomb: 0.05 };

    /// A stuck rotor is held by exactly τ_m − F/N and stays stuck while that
    /// is within ±τ_c.
    #[test]
    fn stuck_rotor_is_held_by_the_unbalanced_torque() {
        let t = rotor_torques(&ROTOR, 0.3, 20.0, 0.0, 0.0, None);
        assert_eq!(t.friction, 0.3 - 0.2);
        assert!((t.margin - (0.05 - 0.1)).abs() < 1e-15);
        let t = rotor_torques(&ROTOR, 0.23, 20.0, 0.0, 0.0, None);
        assert!((t.margin - 0.02).abs() < 1e-15);
    }

    /// A slipping rotor's residual is its equation of motion; the margin is
    /// its speed in its direction.
    #[test]
    fn slipping_rotor_residual_is_its_equation_of_motion() {
        let (tau, f, w, a) = (0.7, 30.0, 12.0, 150.0);
        let t = rotor_torques(&ROTOR, tau, f, w, a, Some(1));
        let expected = tau - f / 100.0 - 1e-3 * w - 0.05 - 2e-4 * a;
        assert!((t.residual - expected).abs() < 1e-15);
        assert_eq!(t.margin, w);
        let t = rotor_torques(&ROTOR, tau, f, -w, a, Some(-1));
        assert_eq!(t.friction, -0.05);
        assert_eq!(t.margin, w);
        let free = Rotor { coulomb: 0.0, ..ROTOR };
        assert_eq!(rotor_torques(&free, tau, f, w, a, Some(1)).margin, f64::INFINITY);
    }
}
