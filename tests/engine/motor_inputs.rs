//! `Simulator::set_motor_torques` checks the motor torques like the drive
//! inputs: a slice of the wrong length (one value per joint, not per motor),
//! a NaN or infinite value, or one outside `MOTOR_TORQUE_RANGES` is refused
//! with the `StepError` naming the input (`tau_m`, `tau_m'`, `tau_m''`), the
//! 1-based joint and the value, and nothing changes: the next interval runs
//! with the torques of the last accepted call, bit for bit as a twin
//! simulator that never saw the refused call (compared through the `Debug`
//! text of the whole state, which tells every f64 apart, −0.0 included).
//! The refused calls carry *other* valid values in their good fields, so
//! that a partial store would show. All on the reference arm with motor
//! drives on joints 1 and 3 (`Model::reference_rrpr_motor`).

use stick_slip_manipulator::model::MOTOR_TORQUE_RANGES;
use stick_slip_manipulator::stepper::MotorTorques;
use stick_slip_manipulator::{DriveInputs, Model, Simulator, StepError};

const N: usize = 4;
const ZERO: [f64; N] = [0.0; N];

/// The torques of the last accepted call: joint 1's motor turns well past its
/// breakaway torque τ_c = 0.03 N·m, joint 3's pushes the slider; joints 2
/// and 4 (rigid) have none.
const TAU: [f64; N] = [0.5, 0.0, 0.2, 0.0];
const RATE: [f64; N] = [2.0, 0.0, -1.0, 0.0];
const ACCEL: [f64; N] = [10.0, 0.0, 5.0, 0.0];

/// Other valid torques, put in the good fields of a refused call.
const OTHER_TAU: [f64; N] = [-0.4, 0.0, 0.7, 0.0];
const OTHER_RATE: [f64; N] = [-3.0, 0.0, 4.0, 0.0];
const OTHER_ACCEL: [f64; N] = [-20.0, 0.0, 8.0, 0.0];

fn good() -> MotorTorques<'static> {
    MotorTorques { tau_m: &TAU, tau_m_rate: &RATE, tau_m_accel: &ACCEL }
}

fn at_rest() -> DriveInputs<'static> {
    DriveInputs { q_star: &ZERO, qd_star: &ZERO, qdd_star: &ZERO }
}

/// A simulator of the motor arm with the good torques set, initialized at t = 0.
fn initialized() -> Simulator {
    let mut sim = Simulator::new(Model::reference_rrpr_motor()).expect("the motor reference model is valid");
    sim.set_motor_torques(&good()).expect("the good torques are accepted");
    sim.initialize(0.0, &at_rest(), None).expect("the motor arm initializes");
    sim
}

/// The state after `steps` intervals of 1 ms, as text that differs for any
/// differing bit of any f64.
fn after(sim: &mut Simulator, steps: usize) -> String {
    for _ in 0..steps {
        sim.advance(&at_rest(), 1e-3).expect("the interval completes");
    }
    format!("{:?}", sim.state())
}

/// A call with `field` (0: τ_m, 1: τ̇_m, 2: τ̈_m) replaced by `bad`, the other
/// two fields the *other* valid torques.
fn call_with<'a>(field: usize, bad: &'a [f64]) -> MotorTorques<'a> {
    let mut fields: [&[f64]; 3] = [&OTHER_TAU, &OTHER_RATE, &OTHER_ACCEL];
    fields[field] = bad;
    MotorTorques { tau_m: fields[0], tau_m_rate: fields[1], tau_m_accel: fields[2] }
}

/// `sim` got a refused call after its twin's history; both run 3 ms and
/// must end bit for bit equal.
#[track_caller]
fn assert_nothing_changed(mut sim: Simulator, what: &str) {
    let mut twin = initialized();
    assert_eq!(after(&mut sim, 3), after(&mut twin, 3), "{what}: the refused call changed the next intervals");
}

// Sanity check of the comparison: torques that *were* accepted change the
// motion, and the check above would see it.
#[test]
fn other_accepted_torques_change_the_motion() {
    let mut sim = initialized();
    sim.set_motor_torques(&MotorTorques { tau_m: &OTHER_TAU, tau_m_rate: &RATE, tau_m_accel: &ACCEL }).unwrap();
    let mut twin = initialized();
    assert_ne!(after(&mut sim, 3), after(&mut twin, 3));
}

// A torque slice of the wrong length (empty, one per motor drive instead of
// one per joint, one short, one long) in any of the three fields is refused
// as `InputLength` naming the field, the joint count 4 and the length given,
// and the next intervals run with the last accepted torques.
#[test]
fn wrong_length_torques_are_refused_naming_the_input_and_change_nothing() {
    for (field, (name, _)) in MOTOR_TORQUE_RANGES.iter().enumerate() {
        for len in [0, 2, 3, 5] {
            let bad = vec![0.1; len];
            let mut sim = initialized();
            let e = sim.set_motor_torques(&call_with(field, &bad)).expect_err("a wrong length is refused");
            assert_eq!(e, StepError::InputLength { field: name, expected: N, got: len });
            let message = e.to_string();
            assert!(message.contains(&format!("`{name}`")) && message.contains(&format!("{len} values")), "{message}");
            assert_nothing_changed(sim, &format!("{name} of length {len}"));
        }
    }
}

// NaN, +inf and −inf in any field and at any joint (also a joint without a
// motor, whose value would be ignored) are refused as `NonFiniteInput`
// naming the field, the 1-based joint and the value; nothing changes.
#[test]
fn non_finite_torques_are_refused_naming_input_and_joint_and_change_nothing() {
    for (field, (name, _)) in MOTOR_TORQUE_RANGES.iter().enumerate() {
        for (joint, value) in [(0, f64::NAN), (2, f64::INFINITY), (1, f64::NEG_INFINITY), (3, f64::NAN)] {
            let mut bad = [0.1; N];
            bad[joint] = value;
            let mut sim = initialized();
            let e = sim.set_motor_torques(&call_with(field, &bad)).expect_err("a non-finite torque is refused");
            match &e {
                StepError::NonFiniteInput { field: f, joint: j, value: v } => {
                    assert_eq!((*f, *j), (*name, joint + 1), "{e}");
                    assert!(v.to_bits() == value.to_bits(), "{e}");
                }
                other => panic!("expected NonFiniteInput for {name}[{}], got {other:?}", joint + 1),
            }
            assert!(e.to_string().contains(&format!("`{name}[{}]`", joint + 1)), "{e}");
            assert_nothing_changed(sim, &format!("{name}[{}] = {value}", joint + 1));
        }
    }
}

// A value just outside its range (the next double beyond the bound, either
// sign, and 1e300) is refused as `InputOutOfRange` naming the field, the
// joint, the value and the range ([-1e6, 1e6] N·m, [-1e9, 1e9] N·m/s,
// [-1e12, 1e12] N·m/s²); nothing changes. The bounds themselves are accepted.
#[test]
fn out_of_range_torques_are_refused_with_the_range_and_change_nothing() {
    let expected_ranges = ["[-1e6, 1e6]", "[-1e9, 1e9]", "[-1e12, 1e12]"];
    for (field, (name, range)) in MOTOR_TORQUE_RANGES.iter().enumerate() {
        assert_eq!(range.to_string(), expected_ranges[field], "{name}");
        let above = f64::from_bits(range.max.to_bits() + 1);
        for (joint, value) in [(0, above), (2, -above), (1, 1e300)] {
            let mut bad = [0.1; N];
            bad[joint] = value;
            let mut sim = initialized();
            let e = sim.set_motor_torques(&call_with(field, &bad)).expect_err("an out-of-range torque is refused");
            assert_eq!(
                e,
                StepError::InputOutOfRange {
                    field: name,
                    joint: joint + 1,
                    value,
                    range: expected_ranges[field].to_string()
                }
            );
            let message = e.to_string();
            assert!(
                message.contains(&format!("`{name}[{}]`", joint + 1)) && message.contains(expected_ranges[field]),
                "{message}"
            );
            assert_nothing_changed(sim, &format!("{name}[{}] = {value:e}", joint + 1));
        }
        // The closed bounds are admissible (not stepped: ±1e12 N·m/s² is not a motion).
        let mut sim = initialized();
        for bound in [range.max, range.min] {
            let at = [bound; N];
            sim.set_motor_torques(&call_with(field, &at)).unwrap_or_else(|e| panic!("{name} = {bound:e} refused: {e}"));
        }
    }
}

// A refused call before `initialize` leaves the torques of the last accepted
// call: the simulation starts with them, bit for bit as a twin's.
#[test]
fn a_refused_call_before_initialize_keeps_the_last_accepted_torques() {
    let mut sim = Simulator::new(Model::reference_rrpr_motor()).unwrap();
    sim.set_motor_torques(&good()).unwrap();
    let bad = [f64::NAN; N];
    assert!(sim.set_motor_torques(&call_with(0, &bad)).is_err());
    assert!(sim.set_motor_torques(&call_with(2, &[1e13; N])).is_err());
    assert!(sim.set_motor_torques(&call_with(1, &[0.0; 1])).is_err());
    sim.initialize(0.0, &at_rest(), None).unwrap();
    assert_nothing_changed(sim, "refused calls before initialize");
}

// Joints without a motor drive ignore their torques: nonzero values on the
// rigid joints 2 and 4 of the motor arm, and any torques on the reference arm
// with flexible drives (no motors at all), give bit for bit the motion
// without them.
#[test]
fn joints_without_a_motor_drive_ignore_their_torques() {
    let mut sim = initialized();
    let (tau, rate, accel) = ([0.5, 7.0, 0.2, -9.0], [2.0, 1e3, -1.0, 5.0], [10.0, -1e5, 5.0, 3.0]);
    sim.set_motor_torques(&MotorTorques { tau_m: &tau, tau_m_rate: &rate, tau_m_accel: &accel }).unwrap();
    assert_nothing_changed(sim, "torques on joints 2 and 4");

    let inputs = DriveInputs { q_star: &[0.01, 0.0, 0.8, 0.0], qd_star: &[0.1, 0.0, 0.05, 0.0], qdd_star: &ZERO };
    let run = |torques: Option<MotorTorques>| {
        let mut sim = Simulator::new(Model::reference_rrpr()).unwrap();
        if let Some(t) = torques {
            sim.set_motor_torques(&t).unwrap();
        }
        sim.initialize(0.0, &inputs, None).unwrap();
        if let Some(t) = torques {
            sim.set_motor_torques(&t).unwrap();
        }
        for _ in 0..3 {
            sim.advance(&inputs, 1e-3).unwrap();
        }
        assert_eq!(sim.state().n_coordinates(), N, "the flexible arm has no rotor coordinates");
        format!("{:?}", sim.state())
    };
    let torques = MotorTorques { tau_m: &[1e6, -3.0, 2.0, 0.5], tau_m_rate: &[1e9; N], tau_m_accel: &[-1e12; N] };
    assert_eq!(run(Some(torques)), run(None));
}

// The torques are held as their Taylor polynomial "from the current time over
// the next intervals until set again" (the doc of `set_motor_torques`): set
// once at t = 0 with τ̇_m = 2 N·m/s and τ̈_m = 10 N·m/s² on joint 1, the
// torque at t = 3 ms is 0.5 + 2·0.003 + 10·0.003²/2 N·m (to 1e-12 N·m).
// Before the fix `Simulator::advance` moved the polynomial's origin to the
// start of every interval: the torque restarted from τ_m each interval (a
// sawtooth: 0.502005 N·m at every communication point). The FMU sets its
// torques before every step, so only library callers saw it.
#[test]
fn torques_set_once_follow_their_polynomial_across_intervals() {
    let mut sim = initialized();
    let mut seen = Vec::new();
    for k in 1..=3 {
        sim.advance(&at_rest(), 1e-3).unwrap();
        let t = k as f64 * 1e-3;
        let expected = TAU[0] + RATE[0] * t + 0.5 * ACCEL[0] * t * t;
        seen.push((t, sim.state().motor_torque[0], expected));
    }
    for (t, got, expected) in &seen {
        assert!(
            (got - expected).abs() < 1e-12,
            "tau_m[1] at t = {t} s is {got}, the polynomial gives {expected}: {seen:?}"
        );
    }
}
