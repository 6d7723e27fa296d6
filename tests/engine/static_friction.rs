//! Static friction holds a joint exactly while it can (3.16) and lets go
//! the moment it cannot (3.18).
//!
//! A block on an inclined prismatic joint (tilt φ from the horizontal) is
//! loaded by gravity only: the joint must supply F* = m·g·sin φ along the
//! axis and static friction can give μ_s·m·g·cos φ. With tan φ ≤ μ_s the
//! block stays stuck, its coordinate unchanged to the last bit; with
//! tan φ > μ_s it slips from the first sub-step. When the drive end then
//! moves at speed v, the joint breaks away at t_b = m·g·(sin φ + μ_s·cos φ)/(k·v),
//! located to 1e-9 relative, i.e. inside the sub-step in which the static
//! limit is exceeded.

use crate::common;

use common::sliding_block;
use stick_slip_manipulator::model::FrictionCoefficients;
use stick_slip_manipulator::{DriveInputs, Phase, Simulator};

const G: f64 = 9.81;
const FRICTION: FrictionCoefficients =
    FrictionCoefficients { mu_kinetic: 0.25, mu_static: 0.3, stribeck_velocity: 0.0, viscous: 0.0 };

fn held(sim: &mut Simulator, q_star: f64, duration: f64) {
    let inputs = DriveInputs { q_star: &[q_star], qd_star: &[0.0], qdd_star: &[0.0] };
    for _ in 0..(duration / 1e-3).round() as usize {
        sim.advance(&inputs, 1e-3).unwrap();
    }
}

#[test]
fn gravity_below_the_static_limit_is_held_exactly() {
    let (m, tilt) = (2.0, 0.9 * FRICTION.mu_static.atan());
    let mut sim = Simulator::new(sliding_block(m, 1e5, 0.0, FRICTION, tilt)).unwrap();
    sim.initialize(0.0, &DriveInputs { q_star: &[0.3], qd_star: &[0.0], qdd_star: &[0.0] }, None).unwrap();
    held(&mut sim, 0.3, 0.2);
    let s = sim.state();
    assert_eq!(s.phase[0], Phase::Stuck);
    assert_eq!(s.q[0], 0.3, "a stuck joint does not creep");
    assert_eq!(s.qd[0], 0.0);
    // The friction holds the whole weight component: F^f = F^d − F* = −m g sin φ.
    assert!((s.friction_force[0] + m * G * tilt.sin()).abs() < 1e-9 * m * G);
    assert!((s.normal_load[0] - m * G * tilt.cos()).abs() < 1e-9 * m * G);
    assert!(sim.transitions().0.is_empty());
}

#[test]
fn gravity_above_the_static_limit_slips_at_once() {
    let (m, tilt) = (2.0, 1.1 * FRICTION.mu_static.atan());
    let mut sim = Simulator::new(sliding_block(m, 1e5, 0.0, FRICTION, tilt)).unwrap();
    sim.initialize(0.0, &DriveInputs { q_star: &[0.3], qd_star: &[0.0], qdd_star: &[0.0] }, None).unwrap();
    let (log, _) = sim.transitions();
    assert_eq!(log.len(), 1);
    assert_eq!((log[0].time, log[0].to), (0.0, Phase::Slipping(-1)), "slips down at t = 0");
    // The first acceleration is the kinetic one: g (sin φ − μ_k cos φ) downwards.
    let a = -G * (tilt.sin() - FRICTION.mu_kinetic * tilt.cos());
    assert!((sim.state().qdd[0] - a).abs() < 1e-9 * G, "q̈ = {} vs {a}", sim.state().qdd[0]);
}

#[test]
fn moving_drive_breaks_the_joint_away_inside_the_sub_step() {
    let (m, k, v, tilt) = (2.0, 1e5, 0.05, 0.5 * FRICTION.mu_static.atan());
    let mut sim = Simulator::new(sliding_block(m, k, 0.0, FRICTION, tilt)).unwrap();
    let t_b = m * G * (tilt.sin() + FRICTION.mu_static * tilt.cos()) / (k * v);
    sim.initialize(0.0, &DriveInputs { q_star: &[0.0], qd_star: &[v], qdd_star: &[0.0] }, None).unwrap();
    let interval = 1e-4;
    let mut t = 0.0;
    while t + interval < t_b {
        sim.advance(&DriveInputs { q_star: &[v * t], qd_star: &[v], qdd_star: &[0.0] }, interval).unwrap();
        t += interval;
        assert_eq!(sim.state().phase[0], Phase::Stuck, "still held at t = {t}");
        assert_eq!(sim.state().q[0], 0.0);
    }
    sim.advance(&DriveInputs { q_star: &[v * t], qd_star: &[v], qdd_star: &[0.0] }, interval).unwrap();
    let (log, _) = sim.transitions();
    assert_eq!(log.len(), 1, "{log:?}");
    assert_eq!(log[0].to, Phase::Slipping(1));
    assert!(((log[0].time - t_b) / t_b).abs() < 1e-9, "breakaway at {} s, expected {t_b} s", log[0].time);
    assert!(sim.state().qd[0] > 0.0);
}
