//! A step the engine cannot take is an error, and the state stays as it was.
//!
//! NaN or infinite inputs, inputs of the wrong length, a non-positive
//! interval, stepping before initialization, a parameter change that leaves
//! the model inconsistent, and a Newmark iteration that does not converge each
//! return their error; the state afterwards equals the state before, so the
//! caller can retry with other inputs or a shorter interval. Long chains (24
//! joints) step and keep their energy account.

use crate::common;

use stick_slip_manipulator::model::Parameter;
use stick_slip_manipulator::{DriveInputs, Model, NonConvergence, Simulator, StepError};

const Q: [f64; 4] = [0.1, 0.2, 0.9, 0.3];
const V: [f64; 4] = [0.5, 0.1, 0.2, 0.3];
const A: [f64; 4] = [0.0; 4];

fn running_reference() -> Simulator {
    let mut sim = Simulator::new(Model::reference_rrpr()).unwrap();
    sim.initialize(0.0, &DriveInputs { q_star: &Q, qd_star: &A, qdd_star: &A }, None).unwrap();
    for _ in 0..20 {
        sim.advance(&DriveInputs { q_star: &Q, qd_star: &V, qdd_star: &A }, 1e-3).unwrap();
    }
    sim
}

#[test]
fn bad_inputs_are_rejected_and_change_nothing() {
    let mut sim = running_reference();
    let before = sim.state().clone();
    let mut bad = Q;
    bad[2] = f64::NAN;
    let e = sim.advance(&DriveInputs { q_star: &bad, qd_star: &V, qdd_star: &A }, 1e-3).unwrap_err();
    assert!(matches!(e, StepError::NonFiniteInput { field: "q_star", joint: 3, .. }), "{e}");
    assert!(e.to_string().contains("q_star[3]"));
    let mut bad = V;
    bad[0] = f64::INFINITY;
    let e = sim.advance(&DriveInputs { q_star: &Q, qd_star: &bad, qdd_star: &A }, 1e-3).unwrap_err();
    assert!(matches!(e, StepError::NonFiniteInput { field: "qd_star", joint: 1, .. }), "{e}");
    let e = sim.advance(&DriveInputs { q_star: &Q[..3], qd_star: &V, qdd_star: &A }, 1e-3).unwrap_err();
    assert_eq!(e, StepError::InputLength { field: "q_star", expected: 4, got: 3 });
    for interval in [0.0, -1e-3, f64::NAN, f64::INFINITY] {
        let e = sim.advance(&DriveInputs { q_star: &Q, qd_star: &V, qdd_star: &A }, interval).unwrap_err();
        assert!(matches!(e, StepError::InvalidInterval { .. }), "{e}");
    }
    assert_eq!(sim.state(), &before);
    sim.advance(&DriveInputs { q_star: &Q, qd_star: &V, qdd_star: &A }, 1e-3).unwrap();
}

#[test]
fn stepping_before_initialization_is_an_error() {
    let mut sim = Simulator::new(Model::reference_rrpr()).unwrap();
    let e = sim.advance(&DriveInputs { q_star: &Q, qd_star: &V, qdd_star: &A }, 1e-3).unwrap_err();
    assert_eq!(e, StepError::NotInitialized);
}

#[test]
fn inconsistent_parameters_surface_at_the_next_step() {
    let mut sim = running_reference();
    let before = sim.state().clone();
    let mut model = sim.model().clone();
    model.set_parameter(Parameter::MuKinetic, 2, 0.5).unwrap();
    sim.set_model(model.clone()).unwrap();
    let e = sim.advance(&DriveInputs { q_star: &Q, qd_star: &V, qdd_star: &A }, 1e-3).unwrap_err();
    assert!(matches!(e, StepError::InvalidModel { .. }), "{e}");
    assert!(e.to_string().contains("joint[3].friction.mu_s"), "{e}");
    assert_eq!(sim.state(), &before);
    model.set_parameter(Parameter::MuStatic, 2, 0.5).unwrap();
    sim.set_model(model).unwrap();
    sim.advance(&DriveInputs { q_star: &Q, qd_star: &V, qdd_star: &A }, 1e-3).unwrap();
}

#[test]
fn a_model_of_another_chain_is_refused() {
    let mut sim = running_reference();
    let e = sim.set_model(Model::synthetic_chain(4)).unwrap_err();
    assert!(e.to_string().contains("another chain"), "{e}");
    assert_eq!(sim.model(), &Model::reference_rrpr());
}

#[test]
fn a_newmark_iteration_that_does_not_converge_is_reported() {
    let mut model = Model::reference_rrpr();
    model.integrator.max_iterations = 1;
    let mut sim = Simulator::new(model).unwrap();
    sim.initialize(0.0, &DriveInputs { q_star: &Q, qd_star: &A, qdd_star: &A }, None).unwrap();
    let before = sim.state().clone();
    let e = sim.advance(&DriveInputs { q_star: &Q, qd_star: &V, qdd_star: &A }, 1e-3).unwrap_err();
    // One iteration is no judgement of convergence: the limit is named.
    assert!(
        matches!(e, StepError::NotConverged { iterations: 1, halvings: 12, cause: NonConvergence::IterationLimit, .. }),
        "{e:?}"
    );
    let message = e.to_string();
    for part in ["for joint ", "even at the shortest sub-step tried", "after 12 halvings", "raise `max_iterations`"] {
        assert!(message.contains(part), "{message}");
    }
    assert_eq!(sim.state(), &before, "state restored to the start of the interval");
}

/// A slider far too short for the load it guides (a = 5 mm, μ = 0.6 in both
/// friction joints) wedges: no slip is consistent, at any sub-step. The
/// discard says so: the joint, that the sub-step was halved to its shortest,
/// and that its friction is the cause, not the step.
#[test]
fn a_wedged_joint_is_reported_with_its_friction_as_the_cause() {
    let mut model = Model::reference_rrpr();
    model.integrator.h_min = 2e-6;
    model.integrator.h_max = 2e-6;
    model.set_parameter(Parameter::SliderA, 2, 0.005).unwrap();
    for joint in [0, 2] {
        model.set_parameter(Parameter::MuStatic, joint, 0.6).unwrap();
        model.set_parameter(Parameter::MuKinetic, joint, 0.6).unwrap();
    }
    let mut sim = Simulator::new(model).unwrap();
    let (q, qd, qdd) = stick_slip_manipulator::motion::reference_inputs(0.0);
    sim.initialize(0.0, &DriveInputs { q_star: &q, qd_star: &qd, qdd_star: &qdd }, None).unwrap();
    let e = (0..1000)
        .find_map(|k| {
            let (q, qd, qdd) = stick_slip_manipulator::motion::reference_inputs(k as f64 * 1e-3);
            sim.advance(&DriveInputs { q_star: &q, qd_star: &qd, qdd_star: &qdd }, 1e-3).err()
        })
        .expect("the wedged arm cannot finish the first second");
    let StepError::NotConverged { joint, halvings, cause, substep, .. } = e else { panic!("{e}") };
    assert_eq!((halvings, cause), (12, NonConvergence::Friction), "{e}");
    assert!((1..=4).contains(&joint) && substep < 2e-6 / 4000.0, "{e}");
    assert!(e.to_string().contains("friction") && !e.to_string().contains("shorter"), "{e}");
}

#[test]
fn a_state_can_be_restored_for_an_exact_continuation() {
    let mut sim = running_reference();
    let saved = sim.state().clone();
    let step = |sim: &mut Simulator| {
        for _ in 0..10 {
            sim.advance(&DriveInputs { q_star: &Q, qd_star: &V, qdd_star: &A }, 1e-3).unwrap();
        }
        sim.state().clone()
    };
    let first = step(&mut sim);
    sim.set_state(&saved).unwrap();
    assert_eq!(step(&mut sim), first);
    let mut other = Simulator::new(Model::reference_rrpr()).unwrap();
    other.set_state(&saved).unwrap();
    assert_eq!(step(&mut other), first, "another simulator continues identically");
    let small = Simulator::new(common::random_chain(2, 1)).unwrap();
    assert!(Simulator::new(Model::reference_rrpr()).unwrap().set_state(small.state()).is_err());
}

/// The same with damped drives with clearance under the default error
/// control, restored in the middle of the reference motion (flanks releasing
/// and closing, joints sticking): the continuation in a fresh simulator
/// equals the uninterrupted run bit for bit over the next 0.3 s, so nothing
/// the error control or the drive law uses lives outside the state.
#[test]
fn a_damped_backlash_run_continues_exactly_in_another_simulator() {
    use stick_slip_manipulator::motion::reference_inputs;
    let mut model = Model::reference_rrpr();
    for (joint, clearance) in [(0, 4.62e-4), (2, 3e-5)] {
        model.set_parameter(Parameter::Damping, joint, 50.0).unwrap();
        model.set_parameter(Parameter::Clearance, joint, clearance).unwrap();
    }
    let advance = |sim: &mut Simulator, k: usize| {
        let (q, qd, qdd) = reference_inputs(k as f64 * 1e-3);
        sim.advance(&DriveInputs { q_star: &q, qd_star: &qd, qdd_star: &qdd }, 1e-3).unwrap();
    };
    let mut sim = Simulator::new(model.clone()).unwrap();
    let (q, qd, qdd) = reference_inputs(0.0);
    sim.initialize(0.0, &DriveInputs { q_star: &q, qd_star: &qd, qdd_star: &qdd }, None).unwrap();
    (0..400).for_each(|k| advance(&mut sim, k));
    let saved = sim.state().clone();
    let mut other = Simulator::new(model).unwrap();
    other.set_state(&saved).unwrap();
    for k in 400..700 {
        advance(&mut sim, k);
        advance(&mut other, k);
        assert_eq!(other.state(), sim.state(), "interval {k}");
    }
    assert!(sim.state().energy.damping_heat > 0.0);
}

#[test]
fn a_chain_of_24_joints_steps_and_balances_energy() {
    let model = common::random_chain(24, 24);
    let n = model.nq();
    let mut sim = Simulator::new(model).unwrap();
    let mut rng = common::Rng::new(3);
    let q: Vec<f64> = (0..n).map(|_| rng.range(-1.0, 1.0)).collect();
    let v: Vec<f64> = (0..n).map(|_| rng.range(-0.2, 0.2)).collect();
    let zero = vec![0.0; n];
    sim.initialize(0.0, &DriveInputs { q_star: &q, qd_star: &zero, qdd_star: &zero }, None).unwrap();
    let b0 = sim.state().energy.balance();
    let mut q_now = q.clone();
    for k in 0..10 {
        for i in 0..n {
            q_now[i] = q[i] + v[i] * k as f64 * 1e-3;
        }
        sim.advance(&DriveInputs { q_star: &q_now, qd_star: &v, qdd_star: &zero }, 1e-3).unwrap();
    }
    let e = sim.state().energy;
    assert!(e.drive_work.abs() > 0.0);
    let residual = (e.balance() - b0).abs();
    assert!(residual < 1e-6 * (e.drive_work.abs() + e.friction_heat + e.kinetic), "energy residual {residual} J");
}

/// A state in which a reported value is not finite names it; a step whose end
/// state fails the check is refused with that name and leaves the state at
/// the start of the interval (the FMU checks its outputs by name this way).
#[test]
fn a_non_finite_reported_value_is_an_error_and_the_state_is_kept() {
    let mut sim = running_reference();
    assert_eq!(sim.state().check_finite(), Ok(()));
    let mut poisoned = sim.state().clone();
    poisoned.normal_load[0] = f64::INFINITY;
    assert_eq!(poisoned.check_finite(), Err(("normal_load[1]".to_string(), f64::INFINITY)));
    let mut poisoned = sim.state().clone();
    poisoned.reaction_moment[2].y = f64::NAN;
    assert_eq!(poisoned.check_finite().unwrap_err().0, "reaction_moment[3,2]");

    let before = sim.state().clone();
    let inputs = DriveInputs { q_star: &Q, qd_star: &V, qdd_star: &A };
    let e = sim.advance_checked(&inputs, 1e-3, |_| Err(("output `N_normal[1]`".into(), f64::INFINITY))).unwrap_err();
    assert!(matches!(e, StepError::NonFiniteOutput { .. }), "{e}");
    let text = e.to_string();
    assert!(text.contains("output `N_normal[1]`") && text.contains("likely cause"), "{text}");
    assert_eq!(sim.state(), &before);
    sim.advance(&inputs, 1e-3).unwrap();
}

/// Inputs beyond the physical ranges are refused before anything runs, with
/// the range in the message.
#[test]
fn inputs_out_of_range_are_refused() {
    let mut sim = running_reference();
    let before = sim.state().clone();
    let fast = [0.0, 1e300, 0.8, 0.0];
    let e = sim.advance(&DriveInputs { q_star: &Q, qd_star: &fast, qdd_star: &A }, 1e-3).unwrap_err();
    assert!(matches!(e, StepError::InputOutOfRange { field: "qd_star", joint: 2, .. }), "{e}");
    assert!(e.to_string().contains("[-1000, 1000]"), "{e}");
    assert_eq!(sim.state(), &before);
}
