//! A motor drive moves its link as a two-mass oscillator, holds it through
//! the gear while the link sticks, breaks its rotor away exactly at the
//! Coulomb level, and with a huge rotor and the feed-forward torque of a
//! motion is the prescribed drive of the study.
//!
//! The rotor obeys J_m·θ̈_m = τ_m − F/N − b_m·θ̇_m − τ_f, the link
//! I·q̈ = F with F = k·(θ_m/N − q) of (2.1). In link units x = θ_m/N these
//! are two masses I and N²J_m on the spring k with the force N·τ_m on the
//! rotor: their common acceleration is N·τ_m/(N²J_m + I) and their relative
//! motion e = x − q oscillates at ω² = k·(1/(N²J_m) + 1/I) about e_s =
//! N·τ_m·I/(k·(N²J_m + I)). Each test states its tolerance.

use stick_slip_manipulator::math::{Mat3, Vec3};
use stick_slip_manipulator::model::{
    ContactGeometry, DhJoint, DhRow, Drive, FrictionCoefficients, IntegratorSettings, JointFriction, JointKind, Link,
    Parameter, Rotor,
};
use stick_slip_manipulator::stepper::{MotorTorques, Phase, RotorStart};
use stick_slip_manipulator::{DriveInputs, Model, Simulator};

/// One revolute joint about z0 turning a link of inertia `inertia` about the
/// axis, driven by a motor through a gear spring `stiffness` (no clearance,
/// no damping). With `stiction` the link sits on bearings loaded by its
/// weight across the axis (gravity along −x0, centre of mass on the axis,
/// so no gravity torque) with static coefficient `stiction`; otherwise
/// there is no gravity and no friction.
fn turntable(inertia: f64, stiffness: f64, rotor: Rotor, stiction: Option<f64>, h: f64) -> Model {
    let (friction, gravity) = match stiction {
        Some(mu) => (
            Some(JointFriction {
                coefficients: FrictionCoefficients {
                    mu_kinetic: mu,
                    mu_static: mu,
                    stribeck_velocity: 0.0,
                    viscous: 0.0,
                },
                geometry: ContactGeometry::Bearings {
                    reaction_point: Vec3::zeros(),
                    l_a: 0.05,
                    l_b: 0.05,
                    d_a: 0.1,
                    d_b: 0.1,
                    d_c: 0.1,
                },
            }),
            Vec3::new(-9.81, 0.0, 0.0),
        ),
        None => (None, Vec3::zeros()),
    };
    Model::from_dh(
        "turntable",
        &[DhJoint {
            kind: JointKind::Revolute,
            dh: DhRow { theta: 0.0, d: 0.0, a: 0.0, alpha: 0.0 },
            drive: Drive::Motor { stiffness, damping: 0.0, clearance: 0.0, rotor },
            friction,
        }],
        &[Link { mass: 10.0, com: Vec3::zeros(), inertia: Mat3::from_diagonal(&Vec3::new(inertia, inertia, inertia)) }],
        gravity,
        Vec3::new(0.1, 0.0, 0.0),
        IntegratorSettings { h_min: h, h_max: h, tolerance: 1e-13, ..IntegratorSettings::default() },
    )
    .expect("the turntable is valid")
}

const ZERO: [f64; 1] = [0.0];

fn at_rest() -> DriveInputs<'static> {
    DriveInputs { q_star: &ZERO, qd_star: &ZERO, qdd_star: &ZERO }
}

/// Runs `sim` for `duration` s in communication steps of 1 ms with the
/// constant torque `tau`, calling `record` after every step.
fn run(sim: &mut Simulator, tau: f64, duration: f64, mut record: impl FnMut(&Simulator)) {
    sim.set_motor_torques(&MotorTorques { tau_m: &[tau], tau_m_rate: &ZERO, tau_m_accel: &ZERO }).unwrap();
    let steps = (duration / 1e-3).round() as usize;
    for _ in 0..steps {
        sim.advance(&at_rest(), 1e-3).unwrap();
        record(sim);
    }
}

/// The two-mass solution: (q, θ_m) at time t from rest with the spring
/// unloaded.
fn two_mass(inertia: f64, stiffness: f64, rotor: Rotor, tau: f64, t: f64) -> (f64, f64) {
    let n = rotor.gear_ratio;
    let reflected = n * n * rotor.inertia;
    let total = reflected + inertia;
    let omega = (stiffness * (1.0 / reflected + 1.0 / inertia)).sqrt();
    let common = 0.5 * n * tau / total * t * t;
    let windup = n * tau / reflected / (omega * omega) * (1.0 - (omega * t).cos());
    let q = common - reflected / total * windup;
    let x = common + inertia / total * windup;
    (q, n * x)
}

/// Largest errors of q, of θ_m and of the wind-up e = θ_m/N − q against
/// the two-mass solution over 0.5 s, each relative to the largest value of
/// its quantity, at fixed sub-steps `h` (`None`: the error control's
/// defaults).
fn two_mass_errors(h: Option<f64>) -> (f64, f64, f64, u64) {
    let (inertia, stiffness, tau) = (0.5, 1e4, 0.2);
    let rotor = Rotor { gear_ratio: 50.0, inertia: 2e-4, viscous: 0.0, coulomb: 0.0 };
    let mut model = turntable(inertia, stiffness, rotor, None, h.unwrap_or(2e-6));
    if h.is_none() {
        model.integrator = IntegratorSettings::default();
    }
    let mut sim = Simulator::new(model).unwrap();
    sim.set_motor_torques(&MotorTorques { tau_m: &[tau], tau_m_rate: &ZERO, tau_m_accel: &ZERO }).unwrap();
    sim.initialize(0.0, &at_rest(), None).unwrap();
    let (mut eq, mut et, mut ee) = (0.0f64, 0.0f64, 0.0f64);
    let (mut q_max, mut t_max, mut e_max) = (0.0f64, 0.0f64, 0.0f64);
    run(&mut sim, tau, 0.5, |sim| {
        let s = sim.state();
        let (q, theta) = two_mass(inertia, stiffness, rotor, tau, s.time);
        eq = eq.max((s.q[0] - q).abs());
        et = et.max((s.theta_m(0) - theta).abs());
        ee = ee.max(((s.theta_m(0) - theta) / rotor.gear_ratio - (s.q[0] - q)).abs());
        q_max = q_max.max(q.abs());
        t_max = t_max.max(theta.abs());
        e_max = e_max.max((theta / rotor.gear_ratio - q).abs());
    });
    (eq / q_max, et / t_max, ee / e_max, sim.state().steps.accepted)
}

#[test]
fn two_mass_oscillator_matches_its_closed_form() {
    // ω = 200 rad/s, 16 periods in 0.5 s; the wind-up oscillates by ±2.5e-3 rad.
    let (q1, t1, e1, _) = two_mass_errors(Some(1e-6));
    let (q2, t2, e2, _) = two_mass_errors(Some(2e-6));
    eprintln!("h = 1e-6 s: q {q1:.2e}, theta_m {t1:.2e}, wind-up {e1:.2e}; h = 2e-6 s: q {q2:.2e}, theta_m {t2:.2e}, wind-up {e2:.2e}");
    assert!(q1 < 1e-6 && t1 < 1e-6, "q {q1:e}, theta_m {t1:e} relative");
    // Newmark's phase error, ω·T·(ωh)²/12 = 1.3e-6 rad of the wind-up at 2e-6 s.
    assert!(e1 < 1e-6, "wind-up {e1:e} relative");
    // Second order: halving the sub-step quarters the error.
    assert!((e2 / e1 - 4.0).abs() < 0.2, "wind-up error ratio {}", e2 / e1);
}

#[test]
fn two_mass_oscillator_at_the_default_error_control() {
    // The promise of error_tolerance (5e-4 per second of motion, weighted by
    // the spring stretch): the wind-up within 5e-4 · 0.5 s of its size.
    let (q, t, e, steps) = two_mass_errors(None);
    eprintln!("error control: q {q:.2e}, theta_m {t:.2e}, wind-up {e:.2e} relative in {steps} sub-steps");
    assert!(e < 2.5e-4, "wind-up {e:e} relative");
    assert!(q < 1e-5 && t < 1e-5, "q {q:e}, theta_m {t:e}");
    assert!(steps < 50_000, "{steps} sub-steps for 0.5 s");
}

#[test]
fn stuck_link_leaves_the_rotor_oscillating_on_the_gear_spring() {
    // Static friction holds the link up to μ_s·(R_A + R_B)·d/2 = 0.5·98.1·0.05 = 2.45 N·m;
    // the gear carries at most 2·N·τ = 1 N·m.
    let (stiffness, tau) = (1e4, 0.01);
    let rotor = Rotor { gear_ratio: 50.0, inertia: 2e-4, viscous: 0.0, coulomb: 0.0 };
    let mut sim = Simulator::new(turntable(0.5, stiffness, rotor, Some(0.5), 1e-6)).unwrap();
    let q0 = [0.3];
    sim.set_motor_torques(&MotorTorques { tau_m: &[tau], tau_m_rate: &ZERO, tau_m_accel: &ZERO }).unwrap();
    sim.initialize(0.0, &DriveInputs { q_star: &q0, qd_star: &ZERO, qdd_star: &ZERO }, None).unwrap();
    assert_eq!(sim.state().phase[0], Phase::Stuck);
    let n = rotor.gear_ratio;
    // J_m·θ̈ = τ − (k/N)·(θ/N − q0): about θ_s = N·(q0 + N·τ/k) at ω_r² = k/(N²J_m).
    let omega = (stiffness / (n * n * rotor.inertia)).sqrt();
    let theta_s = n * (0.3 + n * tau / stiffness);
    let amplitude = theta_s - n * 0.3;
    let mut worst: f64 = 0.0;
    let q_start = [0.3];
    run(&mut sim, tau, 0.3, |sim| {
        let s = sim.state();
        assert_eq!(s.q[0], q_start[0], "the link moved at t = {}", s.time);
        assert_eq!(s.phase[0], Phase::Stuck);
        let theta = theta_s - amplitude * (omega * s.time).cos();
        worst = worst.max((s.theta_m(0) - theta).abs() / amplitude);
    });
    eprintln!("rotor against a stuck link: theta_m within {worst:.2e} of its amplitude (omega_r = {omega:.1} rad/s)");
    assert!(worst < 1e-6, "rotor off its closed form by {worst:e} of the amplitude");
}

#[test]
fn rotor_breaks_away_exactly_at_the_coulomb_level() {
    // The link is held by stiction; the rotor by τ_c = 0.05 N·m until a
    // ramp τ_m = 0.2 N·m/s · t reaches it at t* = 0.25 s (F = 0 until then).
    let rotor = Rotor { gear_ratio: 50.0, inertia: 2e-4, viscous: 0.0, coulomb: 0.05 };
    for h in [2e-6, 5e-5] {
        let mut model = turntable(0.5, 1e4, rotor, Some(0.5), h);
        model.integrator = IntegratorSettings { h_min: h, h_max: h, ..model.integrator };
        let mut sim = Simulator::new(model).unwrap();
        sim.initialize(0.0, &at_rest(), None).unwrap();
        assert_eq!(sim.state().phase[1], Phase::Stuck, "the rotor starts stuck");
        let mut breakaway = None;
        for k in 0..400 {
            let t = k as f64 * 1e-3;
            sim.set_motor_torques(&MotorTorques { tau_m: &[0.2 * t], tau_m_rate: &[0.2], tau_m_accel: &ZERO }).unwrap();
            sim.advance(&at_rest(), 1e-3).unwrap();
            let (log, _) = sim.transitions();
            if let Some(tr) = log.iter().find(|tr| tr.joint == 1 && tr.from == Phase::Stuck) {
                breakaway.get_or_insert(tr.time);
            }
            sim.clear_transitions();
        }
        let t = breakaway.expect("the rotor broke away");
        eprintln!("h = {h:e} s: rotor breaks away at {t:.12} s (exact 0.25 s)");
        // Located to 1e-7 of the sub-step.
        assert!((t - 0.25).abs() < 1e-9, "breakaway at {t} s");
        assert!(sim.state().q[0] == 0.0, "the link stayed stuck");
    }
}

/// The reference motion's drive positions as the rotor of a motor drive
/// with a huge inertia follows them: τ_m = J_m·N·q̈* + F/N, the torque
/// that accelerates the rotor and holds the gear load (measured at the
/// step's start), with its rate from q⃛*.
#[test]
fn huge_rotor_with_feed_forward_is_the_prescribed_drive() {
    use stick_slip_manipulator::motion::reference_inputs;
    let flexible = Model::reference_rrpr();
    let mut motor = Model::reference_rrpr_motor();
    for j in [0, 2] {
        motor.set_parameter(Parameter::RotorInertia, j, 1e3).unwrap();
        motor.set_parameter(Parameter::MotorCoulomb, j, 0.0).unwrap();
        motor.set_parameter(Parameter::MotorViscous, j, 0.0).unwrap();
    }
    let fixed = IntegratorSettings { h_min: 2e-6, h_max: 2e-6, ..flexible.integrator };
    let (mut a, mut b) = (flexible, motor);
    a.integrator = fixed;
    b.integrator = fixed;
    let ratios: Vec<f64> = (0..4).map(|j| b.parameter(Parameter::GearRatio, j).unwrap_or(0.0)).collect();
    let (mut sa, mut sb) = (Simulator::new(a).unwrap(), Simulator::new(b).unwrap());
    let (q, qd, qdd) = reference_inputs(0.0);
    let inputs = DriveInputs { q_star: &q, qd_star: &qd, qdd_star: &qdd };
    sa.initialize(0.0, &inputs, None).unwrap();
    sb.initialize(0.0, &inputs, None).unwrap();
    let dt = 1e-3;
    let (mut worst_q, mut worst_eps, mut eps_max) = (0.0f64, 0.0f64, 0.0f64);
    let (mut worst_lag, mut lag_max) = (0.0f64, 0.0f64);
    for k in 0..1000 {
        let t = k as f64 * dt;
        let (q, qd, qdd) = reference_inputs(t);
        // q⃛* and q⁗* by central differences of q̈* (the cycloid is smooth;
        // before t = 0 it rests).
        let d = 1e-4;
        let (_, _, qdd_after) = reference_inputs(t + d);
        let (_, _, qdd_before) = reference_inputs(t - d);
        let inputs = DriveInputs { q_star: &q, qd_star: &qd, qdd_star: &qdd };
        let (mut tau, mut rate, mut accel) = ([0.0; 4], [0.0; 4], [0.0; 4]);
        for (r, j) in [0usize, 2].into_iter().enumerate() {
            let jerk = if t > 0.0 { (qdd_after[j] - qdd_before[j]) / (2.0 * d) } else { (qdd_after[j] - qdd[j]) / d };
            let snap = if t > 0.0 { (qdd_after[j] - 2.0 * qdd[j] + qdd_before[j]) / (d * d) } else { 0.0 };
            tau[j] = 1e3 * ratios[j] * qdd[j] + sb.state().gear_torque[r];
            rate[j] = 1e3 * ratios[j] * jerk;
            accel[j] = 1e3 * ratios[j] * snap;
        }
        sb.set_motor_torques(&MotorTorques { tau_m: &tau, tau_m_rate: &rate, tau_m_accel: &accel }).unwrap();
        sa.advance(&inputs, dt).unwrap();
        sb.advance(&inputs, dt).unwrap();
        let (x, y) = (sa.state(), sb.state());
        for j in [0, 2] {
            worst_q = worst_q.max((x.q[j] - y.q[j]).abs());
            worst_lag = worst_lag.max((x.joint_error(j) - y.joint_error(j)).abs());
            lag_max = lag_max.max(x.joint_error(j).abs());
        }
        worst_eps = worst_eps.max((x.end_point_error() - y.end_point_error()).abs());
        eps_max = eps_max.max(x.end_point_error());
    }
    eprintln!(
        "huge rotor vs prescribed q*: lag q* - q within {worst_lag:.2e} of max {lag_max:.3e}, eps within {worst_eps:.2e} m of max {eps_max:.3e} m, q within {worst_q:.2e}"
    );
    // The rotor's Taylor polynomial of τ_m follows q*(t) to its fifth
    // derivative; the flexible drive's q* is the quadratic Taylor polynomial
    // re-anchored every 1 ms (3e-9 rad apart): the lags agree to that level.
    assert!(worst_lag < 1e-3 * lag_max, "lag differs by {worst_lag:e}");
    assert!(worst_eps < 1e-3 * eps_max, "eps differs by {worst_eps:e} m");
    assert!(worst_q < 1e-6, "q differs by {worst_q:e}");
}

/// With Coulomb and viscous motor friction, stiction of link and rotor and
/// a motor torque that changes, the account E − E₀ = W_drive − Q_friction −
/// Q_damping − Q_motor closes to 1e-6 of the work done, as for flexible
/// drives (tests/engine/energy_conservation.rs).
#[test]
fn energy_account_closes_with_motor_drives() {
    let mut model = Model::reference_rrpr_motor();
    model.set_parameter(Parameter::Damping, 0, 50.0).unwrap();
    let mut sim = Simulator::new(model).unwrap();
    sim.set_rotor_start(RotorStart::StaticEquilibrium).unwrap();
    let q = [0.0, 0.0, 0.8, 0.0];
    let zero = [0.0; 4];
    let inputs = DriveInputs { q_star: &q, qd_star: &zero, qdd_star: &zero };
    sim.initialize(0.0, &inputs, None).unwrap();
    let hold: Vec<f64> = sim.state().gear_torque.clone();
    let e0 = sim.state().energy;
    let mut work: f64 = 0.0;
    for k in 0..1000 {
        let t = k as f64 * 1e-3;
        // A torque pulse on each motor over the holding torque.
        let pulse = |a: f64| if t < 0.3 { a * (std::f64::consts::PI * t / 0.3).sin() } else { 0.0 };
        let tau = [hold[0] + pulse(2.0), 0.0, hold[1] + pulse(0.3), 0.0];
        sim.set_motor_torques(&MotorTorques { tau_m: &tau, tau_m_rate: &zero, tau_m_accel: &zero }).unwrap();
        sim.advance(&inputs, 1e-3).unwrap();
        let e = sim.state().energy;
        work = work.max(e.drive_work.abs());
        let closed = e.balance() - e0.balance();
        assert!(closed.abs() < 1e-6 * work.max(1e-3), "t = {t}: account off by {closed:e} J of {work:e} J");
    }
    let e = sim.state().energy;
    eprintln!(
        "motor drives: W_drive {:.4e} J, Q_friction {:.4e}, Q_damping {:.4e}, Q_motor {:.4e}, E_rotor {:.4e}; account {:.2e} J",
        e.drive_work,
        e.friction_heat,
        e.damping_heat,
        e.motor_heat,
        e.rotor_kinetic,
        e.balance() - e0.balance()
    );
    assert!(e.motor_heat > 0.0 && e.friction_heat > 0.0);
    let s = sim.state();
    assert!(s.stick_count[4] + s.stick_count[5] > 2, "rotors stuck and slipped: {:?}", s.stick_count);
}

/// Static equilibrium: the rotor turned so that the gear spring holds the
/// link against gravity: the link does not move when the motor supplies the
/// reported holding torque, and the gear force equals the gravity torque.
#[test]
fn static_start_holds_the_arm_with_the_reported_torque() {
    let mut model = Model::reference_rrpr_motor();
    for j in [0, 2] {
        // No friction that could hold the arm instead.
        model.set_parameter(Parameter::MuKinetic, j, 0.0).unwrap();
        model.set_parameter(Parameter::MuStatic, j, 0.0).unwrap();
        model.set_parameter(Parameter::MotorCoulomb, j, 0.0).unwrap();
    }
    let mut sim = Simulator::new(model).unwrap();
    sim.set_rotor_start(RotorStart::StaticEquilibrium).unwrap();
    let q = [0.4, 0.3, 0.9, 0.2];
    let zero = [0.0; 4];
    let inputs = DriveInputs { q_star: &q, qd_star: &zero, qdd_star: &zero };
    sim.initialize(0.0, &inputs, None).unwrap();
    let s = sim.state();
    // Joint 3 carries the arm's weight along its tilted axis.
    assert!(s.drive_force[2].abs() > 10.0, "the slider's gear holds {} N", s.drive_force[2]);
    let hold = s.gear_torque.clone();
    assert!((hold[1] - s.drive_force[2] / (2.0 * std::f64::consts::PI / 0.01)).abs() < 1e-12);
    sim.set_motor_torques(&MotorTorques {
        tau_m: &[hold[0], 0.0, hold[1], 0.0],
        tau_m_rate: &zero,
        tau_m_accel: &zero,
    })
    .unwrap();
    let mut moved: f64 = 0.0;
    for _ in 0..200 {
        sim.advance(&inputs, 1e-3).unwrap();
        let s = sim.state();
        moved = moved.max((s.q[0] - 0.4).abs()).max((s.q[2] - 0.9).abs());
    }
    eprintln!("static start: holding torques {hold:?} N.m; links moved by at most {moved:.2e} in 0.2 s");
    assert!(moved < 1e-9, "the arm moved by {moved:e}");
}

/// The reference motion on the arm with motor drives under the motor-side
/// servo `servo::RotorServo` at the default error control: the motor
/// encoders θ_m/N follow q* to within 1e-4 of the motion, the links lag
/// behind by the gear's wind-up as with flexible drives (ε of the same
/// order), and the sub-steps stay within 2× of the flexible drives'.
#[test]
fn rotor_servo_runs_the_reference_motion_on_motor_drives() {
    use stick_slip_manipulator::motion::reference_inputs;
    use stick_slip_manipulator::servo::RotorServo;
    let run = |model: Model| {
        let mut sim = Simulator::new(model).unwrap();
        let (q, qd, qdd) = reference_inputs(0.0);
        sim.initialize(0.0, &DriveInputs { q_star: &q, qd_star: &qd, qdd_star: &qdd }, None).unwrap();
        let (mut encoder, mut eps_max) = (0.0f64, 0.0f64);
        for k in 0..2000 {
            let (q, qd, qdd) = reference_inputs(k as f64 * 1e-3);
            let (tau, rate) = RotorServo::default().torques(sim.model(), sim.state(), &q, &qd, &qdd);
            sim.set_motor_torques(&MotorTorques { tau_m: &tau, tau_m_rate: &rate, tau_m_accel: &[0.0; 4] }).unwrap();
            sim.advance(&DriveInputs { q_star: &q, qd_star: &qd, qdd_star: &qdd }, 1e-3).unwrap();
            let (q, _, _) = reference_inputs((k + 1) as f64 * 1e-3);
            let s = sim.state();
            for j in [0, 2] {
                encoder = encoder.max((s.q_star[j] - q[j]).abs());
            }
            eps_max = eps_max.max(s.end_point_error());
        }
        (encoder, eps_max, sim.state().steps.accepted, sim.state().stick_count.clone())
    };
    let (_, eps_flexible, steps_flexible, _) = run(Model::reference_rrpr());
    let (encoder, eps_motor, steps_motor, sticks) = run(Model::reference_rrpr_motor());
    eprintln!(
        "reference motion: flexible eps_max {eps_flexible:.3e} m in {steps_flexible} sub-steps; motor eps_max {eps_motor:.3e} m, \
         encoder error {encoder:.2e}, {steps_motor} sub-steps ({:.2}x), stick counts {sticks:?}",
        steps_motor as f64 / steps_flexible as f64
    );
    assert!(encoder < 1e-4 * std::f64::consts::PI / 3.0, "motor encoder off the motion by {encoder:e}");
    assert!(eps_motor > 0.3 * eps_flexible && eps_motor < 3.0 * eps_flexible);
    assert!((steps_motor as f64) < 2.0 * steps_flexible as f64, "{steps_motor} vs {steps_flexible} sub-steps");
}
