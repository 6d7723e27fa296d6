//! The packaged FMU called from Rust through the C ABI by the `fmi` crate (a
//! real FMI master) over the 2 s reference motion (stiction and slip phases):
//!
//! - `fmi2DoStep_1ms_reference_motion`: one `fmi2DoStep` of 1 ms with fixed
//!   sub-steps of 2e-6 s (500 per step), averaged over the motion;
//! - `reference_motion_2s/{fixed_2e-6, error_control}`: the whole motion at
//!   1 ms communication steps, `fmi2SetReal` of the inputs, `fmi2DoStep` and
//!   `fmi2GetReal` of every Real output after each step, with fixed sub-steps
//!   and with the default error control, measured in the same run.
//!
//! Build the FMU first: `bash scripts/build_fmu.sh`.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use fmi::fmi2::import::Fmi2Import;
use fmi::fmi2::instance::{CoSimulation, Common, InstanceCS};
use fmi::traits::FmiImport;
use std::time::{Duration, Instant};
use stick_slip_manipulator::fmi::description::{variables, Quantity, Type};
use stick_slip_manipulator::motion::{reference_inputs, REFERENCE_RUN_TIME};
use stick_slip_manipulator::Model;

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
    let vr = |name: &str| md.model_variable_by_name(name).unwrap().value_reference;
    let steps_vrs = [vr("h_min"), vr("h_max")];
    // Every Real output of the packaged (reference) model, from the FMU's own table.
    let outputs: Vec<u32> = variables(&Model::reference_rrpr())
        .into_iter()
        .filter(|v| matches!((v.quantity, v.ty), (Quantity::Output(_), Type::Real { .. })))
        .map(|v| v.value_reference)
        .collect();
    let mut inst = import.instantiate_cs("bench", false, false).expect("fmi2Instantiate");
    // `fixed`: h_min = h_max = 2e-6 s; otherwise the model's error control;
    // `parameters` set before initialization.
    let start = |inst: &mut InstanceCS, fixed: bool, parameters: &[(u32, f64)]| {
        inst.reset().expect("fmi2Reset");
        if fixed {
            inst.set_real(&steps_vrs, &[2e-6, 2e-6]).expect("fixed sub-steps");
        }
        for &(vr, value) in parameters {
            inst.set_real(&[vr], &[value]).expect("parameter");
        }
        inst.setup_experiment(None, 0.0, None).expect("fmi2SetupExperiment");
        inst.enter_initialization_mode().expect("fmi2EnterInitializationMode");
        inst.set_real(&inputs, &values_at(0.0)).expect("inputs");
        inst.exit_initialization_mode().expect("fmi2ExitInitializationMode");
    };
    start(&mut inst, true, &[]);
    let steps = (REFERENCE_RUN_TIME / STEP).round() as usize;
    let mut k = 0;
    let mut group = c.benchmark_group("fmu");
    group.throughput(Throughput::Elements(500));
    group.bench_function("fmi2DoStep_1ms_reference_motion", |b| {
        b.iter_custom(|iters| {
            let mut total = Duration::ZERO;
            for _ in 0..iters {
                if k == steps {
                    start(&mut inst, true, &[]);
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

    let damped_backlash: Vec<(u32, f64)> = [
        ("h[1]", 50.0),
        ("h[3]", 50.0),
        ("Delta[1]", 4.62e-4),
        ("Delta[3]", 3e-5),
        ("mu_s[1]", 0.21),
        ("mu_k[1]", 0.19),
        ("mu_s[3]", 0.21),
        ("mu_k[3]", 0.19),
    ]
    .into_iter()
    .map(|(name, value)| (vr(name), value))
    .collect();
    let decreasing: Vec<(u32, f64)> = [1, 3]
        .into_iter()
        .flat_map(|j| [(format!("mu_s[{j}]"), 0.2), (format!("mu_k[{j}]"), 0.12), (format!("v_s[{j}]"), 0.01)])
        .map(|(name, value)| (vr(&name), value))
        .collect();
    let mut values = vec![0.0; outputs.len()];
    let groups = [
        ("reference_motion_2s", &[][..]),
        ("damped_backlash_2s", &damped_backlash[..]),
        ("decreasing_characteristic_2s", &decreasing[..]),
    ];
    for (group_name, parameters) in groups {
        let mut group = c.benchmark_group(group_name);
        group.sample_size(10);
        for (name, fixed) in [("fixed_2e-6", true), ("error_control", false)] {
            group.bench_function(name, |b| {
                b.iter_custom(|iters| {
                    let mut total = Duration::ZERO;
                    for _ in 0..iters {
                        start(&mut inst, fixed, parameters);
                        for k in 0..steps {
                            let t = k as f64 * STEP;
                            let inputs_now = values_at(t);
                            let clock = Instant::now();
                            inst.set_real(&inputs, &inputs_now).expect("fmi2SetReal");
                            inst.do_step(t, STEP, true).expect("fmi2DoStep");
                            inst.get_real(&outputs, &mut values).expect("fmi2GetReal");
                            total += clock.elapsed();
                        }
                    }
                    total
                })
            });
        }
        group.finish();
    }
}

criterion_group!(benches, do_step);
criterion_main!(benches);
