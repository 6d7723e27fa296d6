//! Cost of one `fmi2DoStep` of 1 ms (500 sub-steps of 2e-6 s) of the packaged
//! FMU, called from Rust through the C ABI by the `fmi` crate (a real FMI
//! master), averaged over the 2 s reference motion (stiction and slip phases).
//! Build the FMU first: `bash scripts/build_fmu.sh`.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use fmi::fmi2::import::Fmi2Import;
use fmi::fmi2::instance::{CoSimulation, Common, InstanceCS};
use fmi::traits::FmiImport;
use std::time::{Duration, Instant};
use stick_slip_manipulator::motion::{reference_inputs, REFERENCE_RUN_TIME};

const STEP: f64 = 1e-3;

fn do_step(c: &mut Criterion) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/fmu/StickSlipManipulator.fmu");
    if !path.is_file() {
        // `cargo test --all-targets` runs this bench once before the FMU is packed.
        eprintln!("SKIPPED: {} is missing: run `bash scripts/build_fmu.sh` first", path.display());
        return;
    }
    let import: Fmi2Import = fmi::import::from_path(&path).expect("import the FMU");
    let md = import.model_description();
    let mut inputs = Vec::new();
    for group in ["q_star", "qd_star", "qdd_star"] {
        for i in 1..=4 {
            inputs.push(md.model_variable_by_name(&format!("{group}[{i}]")).unwrap().value_reference);
        }
    }
    let values_at = |t: f64| -> Vec<f64> {
        let (q, qd, qdd) = reference_inputs(t);
        [q, qd, qdd].concat()
    };
    let mut inst = import.instantiate_cs("bench", false, false).expect("fmi2Instantiate");
    let start = |inst: &mut InstanceCS| {
        inst.reset().expect("fmi2Reset");
        inst.setup_experiment(None, 0.0, None).expect("fmi2SetupExperiment");
        inst.enter_initialization_mode().expect("fmi2EnterInitializationMode");
        inst.set_real(&inputs, &values_at(0.0)).expect("inputs");
        inst.exit_initialization_mode().expect("fmi2ExitInitializationMode");
    };
    start(&mut inst);
    let steps = (REFERENCE_RUN_TIME / STEP).round() as usize;
    let mut k = 0;
    let mut group = c.benchmark_group("fmu");
    group.throughput(Throughput::Elements(500));
    group.bench_function("fmi2DoStep_1ms_reference_motion", |b| {
        b.iter_custom(|iters| {
            let mut total = Duration::ZERO;
            for _ in 0..iters {
                if k == steps {
                    start(&mut inst);
                    k = 0;
                }
                let t = k as f64 * STEP;
                let values = values_at(t);
                let clock = Instant::now();
                inst.set_real(&inputs, &values).expect("fmi2SetReal");
                inst.do_step(t, STEP, true).expect("fmi2DoStep");
                total += clock.elapsed();
                k += 1;
            }
            total
        })
    });
    group.finish();
}

criterion_group!(benches, do_step);
criterion_main!(benches);
