//! What the FMU's sensitivities cost (src/stepper/schedule.rs,
//! src/fmi/experiment.rs): the 2 s reference motion at 1 ms communication
//! steps and the default error control, through the engine, in one run:
//!
//! - `reference_motion_2s/free`: as every run is made;
//! - `reference_motion_2s/recording`: the same run recording its sub-step
//!   schedule (what a run with sensitivities does first; its outputs are
//!   the free run's bit for bit);
//! - `reference_motion_2s/replay`: a replay of that schedule with μ_k[1]
//!   moved by -1e-6 of its value (mu_k = mu_s here) (one column of a Jacobian: a forward
//!   difference takes p + 1 of them).

use criterion::{criterion_group, criterion_main, Criterion};
use std::sync::Arc;
use stick_slip_manipulator::model::Parameter;
use stick_slip_manipulator::motion::{reference_inputs, REFERENCE_RUN_TIME};
use stick_slip_manipulator::{DriveInputs, Model, PlannedSubStep, Simulator};

const STEP: f64 = 1e-3;

/// The reference motion through `sim` (initialized here); `prepare` runs
/// after initialization.
fn run(model: &Model, prepare: impl FnOnce(&mut Simulator)) -> Simulator {
    let mut sim = Simulator::new(model.clone()).expect("reference model");
    let (q, qd, qdd) = reference_inputs(0.0);
    let inputs = DriveInputs { q_star: &q, qd_star: &qd, qdd_star: &qdd };
    sim.initialize(0.0, &inputs, None).expect("initialize");
    prepare(&mut sim);
    let steps = (REFERENCE_RUN_TIME / STEP).round() as usize;
    for k in 0..steps {
        let (q, qd, qdd) = reference_inputs(k as f64 * STEP);
        let inputs = DriveInputs { q_star: &q, qd_star: &qd, qdd_star: &qdd };
        sim.advance(&inputs, STEP).expect("step");
    }
    sim
}

fn sensitivities(c: &mut Criterion) {
    let model = Model::reference_rrpr();
    let mut recorded = run(&model, Simulator::record_schedule);
    let plan: Arc<[PlannedSubStep]> = recorded.take_schedule().into();
    let mut moved = model.clone();
    let mu = moved.parameter(Parameter::MuKinetic, 0).expect("mu_k[1]");
    moved.set_parameter(Parameter::MuKinetic, 0, mu * (1.0 - 1e-6)).expect("mu_k[1]");
    let replayed = run(&moved, |sim| sim.replay_schedule(Arc::clone(&plan)));
    assert_eq!(replayed.schedule_departures(), 0, "the replay keeps the plan");
    let mut group = c.benchmark_group("reference_motion_2s");
    group.sample_size(10);
    group.bench_function("free", |b| b.iter(|| run(&model, |_| {})));
    group.bench_function("recording", |b| b.iter(|| run(&model, Simulator::record_schedule)));
    group.bench_function("replay", |b| b.iter(|| run(&moved, |sim| sim.replay_schedule(Arc::clone(&plan)))));
    group.finish();
}

criterion_group!(benches, sensitivities);
criterion_main!(benches);
