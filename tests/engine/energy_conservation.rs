//! Energy is conserved without dissipation and balanced with it.
//!
//! Friction and damping off, drive inputs held, flexible joints of the
//! reference manipulator started displaced from their drive positions: the
//! total energy E = T + V_gravity + V_spring stays constant within 1e-6 of
//! the energy that oscillates (the initial spring energy) over 0.5 s at
//! h_max = 2e-6 s. With friction and damping on and the arm following the
//! reference motion, the account E − E₀ = W_drive − Q_friction − Q_damping
//! closes to 1e-6 of the drive work; so it does with viscous joint friction
//! b·q̇ on joints 1 and 3 (b_v[1] = 5 N·m·s/rad, b_v[3] = 100 N·s/m), whose
//! heat b·∫q̇² dt is part of Q_friction (measured: 3.2e-13 of the drive work
//! with fixed sub-steps, 2.7e-9 at the default; Q_friction 5.28 J against
//! 4.81 J without the viscous part).

use stick_slip_manipulator::model::{IntegratorSettings, Parameter};
use stick_slip_manipulator::motion::reference_inputs;
use stick_slip_manipulator::{DriveInputs, InitialState, Model, Simulator};

/// The free oscillation of the arm without friction and damping over 0.5 s:
/// the largest change of the total energy, the spring energy exchanged, and
/// the sub-steps taken.
fn free_oscillation_drift(integrator: IntegratorSettings) -> (f64, f64, u64) {
    let mut model = Model::reference_rrpr();
    for joint in [0, 2] {
        model.set_parameter(Parameter::MuKinetic, joint, 0.0).unwrap();
        model.set_parameter(Parameter::MuStatic, joint, 0.0).unwrap();
    }
    model.integrator = integrator;
    let mut sim = Simulator::new(model).unwrap();
    let q_star = [0.2, 0.3, 0.9, 0.4];
    let zero = [0.0; 4];
    let inputs = DriveInputs { q_star: &q_star, qd_star: &zero, qdd_star: &zero };
    let q0 = [0.2 + 2e-3, 0.3, 0.9 + 1e-3, 0.4];
    sim.initialize(0.0, &inputs, Some(InitialState { q: &q0, qd: &zero })).unwrap();
    let e0 = sim.state().energy;
    let exchanged = e0.spring;
    assert!((exchanged - 0.5 * 1e6 * (4e-6 + 1e-6)).abs() < 1e-9);
    let mut worst: f64 = 0.0;
    let mut kinetic_peak: f64 = 0.0;
    for _ in 0..500 {
        sim.advance(&inputs, 1e-3).unwrap();
        let e = sim.state().energy;
        worst = worst.max((e.total() - e0.total()).abs());
        kinetic_peak = kinetic_peak.max(e.kinetic);
        assert_eq!(e.friction_heat, 0.0);
        assert!(e.drive_work.abs() < 1e-12 * exchanged, "held drive ends do no work: {} J", e.drive_work);
    }
    assert!(kinetic_peak > 0.5 * exchanged, "the arm really oscillates");
    (worst, exchanged, sim.state().steps.accepted)
}

#[test]
fn total_energy_is_conserved_without_friction_and_damping() {
    // Fixed sub-steps of 2e-6 s.
    let fixed = IntegratorSettings { h_min: 2e-6, h_max: 2e-6, ..Model::reference_rrpr().integrator };
    let (worst, exchanged, steps) = free_oscillation_drift(fixed);
    eprintln!("fixed 2e-6 s: energy drift {worst:.3e} J of {exchanged:.3} J exchanged in {steps} sub-steps");
    assert!(worst < 1e-6 * exchanged, "energy drift {worst} J");
}

/// With error control the drift shrinks with the tolerance: the average-
/// acceleration rule conserves the energy of a linear system exactly, and
/// what it loses on the arm's nonlinearity is a local error the control
/// bounds.
#[test]
fn energy_drift_follows_the_error_tolerance() {
    let mut previous = f64::INFINITY;
    for tolerance in [5e-3, 5e-4, 5e-5] {
        let adaptive = IntegratorSettings { error_tolerance: tolerance, ..Model::reference_rrpr().integrator };
        assert!(!adaptive.fixed_step());
        let (worst, exchanged, steps) = free_oscillation_drift(adaptive);
        eprintln!("error tolerance {tolerance:e}: energy drift {worst:.3e} J of {exchanged:.3} J in {steps} sub-steps");
        assert!(worst < 0.2 * tolerance * exchanged, "tolerance {tolerance}: energy drift {worst} J");
        assert!(worst < previous, "tolerance {tolerance}: drift {worst} J did not shrink from {previous} J");
        previous = worst;
    }
}

/// The energy account E − E₀ = W_drive − Q_friction − Q_damping over 0.4 s of
/// the reference motion with drive damping and the viscous friction
/// coefficients `viscous` of joints 1 and 3: its largest residual relative
/// to the drive work.
fn account_residual(integrator: IntegratorSettings, viscous: [f64; 2]) -> f64 {
    let mut model = Model::reference_rrpr();
    model.set_parameter(Parameter::Damping, 0, 1e3).unwrap();
    model.set_parameter(Parameter::Damping, 2, 1e3).unwrap();
    model.set_parameter(Parameter::Viscous, 0, viscous[0]).unwrap();
    model.set_parameter(Parameter::Viscous, 2, viscous[1]).unwrap();
    model.integrator = integrator;
    let mut sim = Simulator::new(model).unwrap();
    let inputs_at = reference_inputs;
    let (a, b, c) = inputs_at(0.0);
    sim.initialize(0.0, &DriveInputs { q_star: &a, qd_star: &b, qdd_star: &c }, None).unwrap();
    let balance0 = sim.state().energy.balance();
    let mut worst: f64 = 0.0;
    for k in 0..400 {
        let (a, b, c) = inputs_at(k as f64 * 1e-3);
        sim.advance(&DriveInputs { q_star: &a, qd_star: &b, qdd_star: &c }, 1e-3).unwrap();
        worst = worst.max((sim.state().energy.balance() - balance0).abs());
    }
    let e = sim.state().energy;
    eprintln!(
        "account residual {worst:.3e} J ({:.1e} of W_drive {:.4} J); Q_friction {:.4} J, Q_damping {:.4} J; {} sub-steps",
        worst / e.drive_work,
        e.drive_work,
        e.friction_heat,
        e.damping_heat,
        sim.state().steps.accepted
    );
    assert!(e.friction_heat > 0.1 && e.damping_heat > 0.0, "both dissipations are active");
    worst / e.drive_work
}

/// Average-acceleration Newmark books the work of a force over a sub-step as
/// its mean times the displacement, exact for forces linear over the
/// sub-step: the account closes to 1e-11 of the drive work with fixed 2e-6 s
/// sub-steps, and with error control to what its tolerance admits.
#[test]
fn energy_account_closes_with_friction_and_damping() {
    let default = Model::reference_rrpr().integrator;
    let fixed = IntegratorSettings { h_min: 2e-6, h_max: 2e-6, ..default };
    assert!(account_residual(fixed, [0.0; 2]) < 1e-10);
    assert!(account_residual(default, [0.0; 2]) < 1e-8);
    assert!(account_residual(IntegratorSettings { error_tolerance: 5e-5, ..default }, [0.0; 2]) < 1e-9);
}

/// The same account with viscous friction on joints 1 and 3: the viscous
/// heat b·∫q̇² dt is booked with the dry friction's, as the mean force over
/// the sub-step times its displacement.
#[test]
fn energy_account_closes_with_viscous_joint_friction() {
    let default = Model::reference_rrpr().integrator;
    let fixed = IntegratorSettings { h_min: 2e-6, h_max: 2e-6, ..default };
    let viscous = [5.0, 100.0];
    assert!(account_residual(fixed, viscous) < 1e-10);
    assert!(account_residual(default, viscous) < 1e-8);
}
