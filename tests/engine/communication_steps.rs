//! Error-controlled stepping works at any communication step a master may
//! choose, from 10 µs to 1 s.
//!
//! The inputs of an interval are held as the Taylor polynomial of their values
//! at its start, so runs at different communication steps see different drive
//! motions; each is therefore compared with fixed 2e-6 s sub-steps at the same
//! communication step. The default error control gives the fixed-step answer
//! there: max and final end-point error ε within 1e-3 (the 0.1 % of the
//! error-control acceptance), the same stiction counts, and never more
//! sub-steps than the fixed grid. An interval shorter than a sub-step the
//! control would choose is one sub-step (the interval's end shortens it).

use stick_slip_manipulator::model::IntegratorSettings;
use stick_slip_manipulator::motion::reference_inputs;
use stick_slip_manipulator::{DriveInputs, Model, Simulator};

struct Run {
    max_eps: f64,
    final_eps: f64,
    stick_count: Vec<u64>,
    substeps: u64,
    intervals: u64,
}

/// The reference motion over `duration` s at communication steps `interval`,
/// with `integrator`.
fn run(integrator: IntegratorSettings, interval: f64, duration: f64) -> Run {
    let mut model = Model::reference_rrpr();
    model.integrator = integrator;
    let mut sim = Simulator::new(model).unwrap();
    let (q, qd, qdd) = reference_inputs(0.0);
    sim.initialize(0.0, &DriveInputs { q_star: &q, qd_star: &qd, qdd_star: &qdd }, None).unwrap();
    let intervals = (duration / interval).round() as u64;
    let mut max_eps = sim.state().end_point_error();
    for k in 0..intervals {
        let (q, qd, qdd) = reference_inputs(k as f64 * interval);
        sim.advance(&DriveInputs { q_star: &q, qd_star: &qd, qdd_star: &qdd }, interval)
            .unwrap_or_else(|e| panic!("interval {interval} s, step {k}: {e}"));
        let eps = sim.state().end_point_error();
        assert!(eps.is_finite());
        max_eps = max_eps.max(eps);
    }
    let s = sim.state();
    assert!((s.time - intervals as f64 * interval).abs() <= 1e-9 * duration, "ends at {} s", s.time);
    Run {
        max_eps,
        final_eps: s.end_point_error(),
        stick_count: s.stick_count.clone(),
        substeps: s.steps.accepted,
        intervals,
    }
}

#[test]
fn error_control_gives_the_fixed_step_answer_at_any_communication_step() {
    let default = Model::reference_rrpr().integrator;
    assert!(!default.fixed_step());
    let fixed = IntegratorSettings { h_min: 2e-6, h_max: 2e-6, ..default };
    // Short communication steps over the first 0.5 s (the breakaway and the
    // first slip of both joints); longer ones over the whole 2 s motion.
    for (interval, duration) in [(1e-5, 0.5), (1e-4, 0.5), (1e-3, 2.0), (1e-2, 2.0), (0.1, 2.0)] {
        let adaptive = run(default, interval, duration);
        let reference = run(fixed, interval, duration);
        eprintln!(
            "interval {interval:e} s: max ε {:.6e} / {:.6e} m, final ε {:.6e} / {:.6e} m, sub-steps {} / {}, stick counts {:?}",
            adaptive.max_eps,
            reference.max_eps,
            adaptive.final_eps,
            reference.final_eps,
            adaptive.substeps,
            reference.substeps,
            adaptive.stick_count
        );
        assert!(
            (adaptive.max_eps - reference.max_eps).abs() <= 1e-3 * reference.max_eps,
            "interval {interval}: max ε {} vs {}",
            adaptive.max_eps,
            reference.max_eps
        );
        assert!(
            (adaptive.final_eps - reference.final_eps).abs() <= 1e-3 * reference.final_eps,
            "interval {interval}: final ε {} vs {}",
            adaptive.final_eps,
            reference.final_eps
        );
        assert_eq!(adaptive.stick_count, reference.stick_count, "interval {interval}: stiction counts");
        assert!(adaptive.substeps <= reference.substeps, "interval {interval}: more sub-steps than the fixed grid");
        assert!(adaptive.substeps >= adaptive.intervals, "interval {interval}: an interval without a sub-step");
    }
}

/// Communication steps shorter than the sub-step the error control would
/// choose (10 µs against about 20 µs on the reference motion): each interval
/// is one sub-step, apart from events and the first intervals, in which the
/// length grows from h_min. (A remainder between one and two proposals is
/// split in halves; if those halves could not propose a longer sub-step, the
/// length would never grow past the interval and every interval would take
/// two sub-steps of half its length: 2.000 per interval measured before.)
#[test]
fn communication_steps_shorter_than_the_sub_step_take_one_sub_step_each() {
    let run = run(Model::reference_rrpr().integrator, 1e-5, 0.5);
    let per_interval = run.substeps as f64 / run.intervals as f64;
    eprintln!(
        "10 µs steps: {} sub-steps in {} intervals ({per_interval:.3} per interval)",
        run.substeps, run.intervals
    );
    assert!(per_interval < 1.05, "{per_interval} sub-steps per interval");
}

/// One-second communication steps: the inputs jump at each interval's start
/// (their Taylor polynomial over 1 s is far from the motion), and the stepper
/// still completes each step with a finite state, taking short sub-steps where
/// the jump excites the drives and long ones where the arm is at rest.
#[test]
fn one_second_communication_steps_complete() {
    let default = Model::reference_rrpr().integrator;
    let run = run(default, 1.0, 2.0);
    assert!(run.final_eps.is_finite() && run.max_eps.is_finite());
    eprintln!("1 s steps: {} sub-steps, max ε {:.3e} m", run.substeps, run.max_eps);
    assert!(run.substeps < 1_000_000, "{} sub-steps", run.substeps);
}
