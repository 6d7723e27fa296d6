//! Cost of the Newmark sub-step: on the reference manipulator during the
//! reference motion (stiction and slip phases), and on synthetic chains of
//! growing length. Each sample advances one 1 ms interval (500 sub-steps of
//! 2e-6 s) from a saved state; divide by 500 for the cost of a sub-step.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use std::hint::black_box;
use stick_slip_manipulator::motion::reference_inputs;
use stick_slip_manipulator::servo::RotorServo;
use stick_slip_manipulator::{DriveInputs, Model, MotorTorques, Simulator, State};

const INTERVAL: f64 = 1e-3;

/// A drive that produces (q*, q̇*, q̈*) at time t for every joint.
type Drive = Box<dyn Fn(f64, &mut [f64], &mut [f64], &mut [f64])>;

fn reference_drive() -> Drive {
    Box::new(|t, q, qd, qdd| {
        let (a, b, c) = reference_inputs(t);
        q.copy_from_slice(&a);
        qd.copy_from_slice(&b);
        qdd.copy_from_slice(&c);
    })
}

/// Every joint moves at a constant rate from a spread start pose.
fn ramp_drive() -> Drive {
    Box::new(|t, q, qd, qdd| {
        for i in 0..q.len() {
            qd[i] = 0.2 * if i % 2 == 0 { 1.0 } else { -1.0 };
            q[i] = 0.1 * i as f64 + qd[i] * t;
            qdd[i] = 0.0;
        }
    })
}

struct Bench {
    sim: Simulator,
    saved: State,
    inputs: [Vec<f64>; 3],
}

/// Runs `model` under `drive` until `t`, then keeps that state. The rotors
/// of motor drives follow the drive's motion under [`RotorServo`].
fn prepare(model: Model, drive: &Drive, t: f64) -> Bench {
    let n = model.nq();
    let mut sim = Simulator::new(model).unwrap();
    let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    drive(0.0, &mut q, &mut qd, &mut qdd);
    sim.initialize(0.0, &DriveInputs { q_star: &q, qd_star: &qd, qdd_star: &qdd }, None).unwrap();
    let steps = (t / INTERVAL).round() as usize;
    for k in 0..=steps {
        drive(k as f64 * INTERVAL, &mut q, &mut qd, &mut qdd);
        servo(&mut sim, &q, &qd, &qdd);
        if k < steps {
            sim.advance(&DriveInputs { q_star: &q, qd_star: &qd, qdd_star: &qdd }, INTERVAL).unwrap();
        }
    }
    let saved = sim.state().clone();
    Bench { sim, saved, inputs: [q, qd, qdd] }
}

/// Sets the motor torques of [`RotorServo`] for the motion (q, q̇, q̈) now.
fn servo(sim: &mut Simulator, q: &[f64], qd: &[f64], qdd: &[f64]) {
    let (tau, rate) = RotorServo::default().torques(sim.model(), sim.state(), q, qd, qdd);
    let zero = vec![0.0; tau.len()];
    sim.set_motor_torques(&MotorTorques { tau_m: &tau, tau_m_rate: &rate, tau_m_accel: &zero }).unwrap();
}

impl Bench {
    fn interval(&mut self) {
        self.sim.set_state(&self.saved).unwrap();
        let [q, qd, qdd] = &self.inputs;
        self.sim.advance(black_box(&DriveInputs { q_star: q, qd_star: qd, qdd_star: qdd }), INTERVAL).unwrap();
    }
}

fn reference_manipulator(c: &mut Criterion) {
    let mut group = c.benchmark_group("reference_interval_1ms");
    group.throughput(Throughput::Elements(500));
    let drive = reference_drive();
    // t = 0.02: joints 1 and 3 stuck; 0.5: both slipping; 1.45: end of the
    // motion, stick-slip transitions inside the interval.
    for t in [0.02, 0.5, 1.45] {
        let mut bench = prepare(Model::reference_rrpr(), &drive, t);
        group.bench_function(BenchmarkId::from_parameter(format!("t={t}")), |b| b.iter(|| bench.interval()));
    }
    group.finish();
}

fn chain_growth(c: &mut Criterion) {
    let mut group = c.benchmark_group("synthetic_chain_interval_1ms");
    group.throughput(Throughput::Elements(500));
    let drive = ramp_drive();
    for n in [2, 4, 8, 16, 24] {
        let mut bench = prepare(Model::synthetic_chain(n), &drive, 0.02);
        group.bench_function(BenchmarkId::from_parameter(n), |b| b.iter(|| bench.interval()));
    }
    group.finish();
}

/// `model` with fixed sub-steps of 2e-6 s, so that an interval is 500 of them.
fn fixed_substeps(mut model: Model) -> Model {
    (model.integrator.h_min, model.integrator.h_max) = (2e-6, 2e-6);
    model
}

fn model_file(path: &str) -> Model {
    Model::from_file(format!("{}/{path}", env!("CARGO_MANIFEST_DIR"))).unwrap()
}

/// General placements (a URDF) against Denavit–Hartenberg rows on the same
/// arm, and a 7-joint URDF arm against the 4-joint reference, in one run.
fn placements(c: &mut Criterion) {
    let mut group = c.benchmark_group("placements_interval_1ms");
    group.throughput(Throughput::Elements(500));
    let drive = reference_drive();
    for (name, model) in [
        ("reference_dh", Model::reference_rrpr()),
        ("reference_urdf", model_file("models/urdf/reference_rrpr/reference_rrpr.toml")),
    ] {
        let mut bench = prepare(fixed_substeps(model), &drive, 0.5);
        group.bench_function(BenchmarkId::from_parameter(name), |b| b.iter(|| bench.interval()));
    }
    let ramp = ramp_drive();
    let mut bench = prepare(fixed_substeps(model_file("models/urdf/kuka_iiwa/kuka_iiwa.toml")), &ramp, 0.5);
    group.bench_function(BenchmarkId::from_parameter("kuka_iiwa_7"), |b| b.iter(|| bench.interval()));
    group.finish();
}

/// The reference arm with motor drives on joints 1 and 3 (a rotor each, six
/// coordinates) against flexible drives, in one run: one interval of 500
/// fixed sub-steps at t = 0.02 and 0.5 s of the reference motion (the motor arm's
/// rotors under [`RotorServo`]), and the whole 2 s motion at the default
/// error control.
fn motor_drives(c: &mut Criterion) {
    let drive = reference_drive();
    let mut group = c.benchmark_group("drive_kind_interval_1ms");
    group.throughput(Throughput::Elements(500));
    // t = 0.02: the links stuck; 0.5: links and rotors slipping.
    for t in [0.02, 0.5] {
        for (name, model) in [("flexible", Model::reference_rrpr()), ("motor", Model::reference_rrpr_motor())] {
            let mut bench = prepare(fixed_substeps(model), &drive, t);
            group.bench_function(BenchmarkId::from_parameter(format!("{name}/t={t}")), |b| b.iter(|| bench.interval()));
        }
    }
    group.finish();
    let mut group = c.benchmark_group("drive_kind_reference_motion_2s");
    group.sample_size(10);
    for (name, model) in [("flexible", Model::reference_rrpr()), ("motor", Model::reference_rrpr_motor())] {
        group.bench_function(BenchmarkId::from_parameter(name), |b| b.iter(|| prepare(model.clone(), &drive, 2.0)));
    }
    group.finish();
}

criterion_group!(benches, reference_manipulator, chain_growth, placements, motor_drives);
criterion_main!(benches);
