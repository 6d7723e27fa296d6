//! The FMI layer driven through its exported functions from Rust, with an
//! in-memory logger: call-sequence checks, rejected calls that change
//! nothing, panics that become the error state, foreign pointers, and FMU
//! states that continue bit for bit in another instance. (fmpy and the other
//! masters drive the packaged FMU in tests/python.)

use super::boundary::{into_component, with_instance};
use super::description::{model_description_xml, variables, MODEL_IDENTIFIER};
use super::exports::*;
use super::instance::Instance;
use super::lifecycle::{LifeCycle, States};
use super::logger::{Logger, MemoryLog as Log};
use super::status::Status;
use crate::model::{Model, ModelSource, REFERENCE_RRPR_TOML};
use fmi_sys::fmi2::*;

const OK: fmi2Status = fmi2Status_fmi2OK;
const ERROR: fmi2Status = fmi2Status_fmi2Error;

/// A fresh instance of the reference model and its log.
fn instance() -> (fmi2Component, Log) {
    let (logger, log) = Logger::memory(true);
    let instance = Instance::new(&ModelSource::toml(REFERENCE_RRPR_TOML), logger).expect("reference model");
    (into_component(instance), log)
}

fn vr(name: &str) -> fmi2ValueReference {
    let model = Model::reference_rrpr();
    variables(&model).iter().find(|v| v.name == name).unwrap_or_else(|| panic!("no variable {name}")).value_reference
}

fn last_message(log: &Log) -> (Status, &'static str, String) {
    log.borrow().last().cloned().expect("a message was logged")
}

fn set(c: fmi2Component, names: &[&str], values: &[f64]) -> fmi2Status {
    let vrs: Vec<_> = names.iter().map(|n| vr(n)).collect();
    unsafe { fmi2SetReal(c, vrs.as_ptr(), vrs.len(), values.as_ptr()) }
}

fn get(c: fmi2Component, names: &[&str]) -> Vec<f64> {
    let vrs: Vec<_> = names.iter().map(|n| vr(n)).collect();
    let mut values = vec![f64::NAN; vrs.len()];
    assert_eq!(unsafe { fmi2GetReal(c, vrs.as_ptr(), vrs.len(), values.as_mut_ptr()) }, OK);
    values
}

fn initialize(c: fmi2Component) {
    unsafe {
        assert_eq!(fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0), OK);
        assert_eq!(fmi2EnterInitializationMode(c), OK);
        assert_eq!(fmi2ExitInitializationMode(c), OK);
    }
}

/// All real and boolean outputs after `n` steps of 1 ms from `t`, with a
/// motion of joints 1 and 3, as raw bits.
fn run(c: fmi2Component, t: f64, n: usize) -> Vec<u64> {
    let model = Model::reference_rrpr();
    let vars = variables(&model);
    let reals: Vec<_> = vars
        .iter()
        .filter(|v| matches!(v.ty, super::description::Type::Real { .. }))
        .map(|v| v.value_reference)
        .collect();
    let bools: Vec<_> = vars
        .iter()
        .filter(|v| matches!(v.ty, super::description::Type::Boolean { .. }))
        .map(|v| v.value_reference)
        .collect();
    let mut bits = Vec::new();
    for k in 0..n {
        let tk = t + k as f64 * 1e-3;
        assert_eq!(
            set(
                c,
                &["q_star[1]", "qd_star[1]", "qdd_star[1]", "q_star[3]", "qd_star[3]"],
                &[0.3 * tk * tk, 0.6 * tk, 0.6, 0.01 * tk, 0.01]
            ),
            OK
        );
        assert_eq!(unsafe { fmi2DoStep(c, tk, 1e-3, 0) }, OK);
        let mut r = vec![0.0; reals.len()];
        let mut b = vec![0; bools.len()];
        unsafe {
            assert_eq!(fmi2GetReal(c, reals.as_ptr(), reals.len(), r.as_mut_ptr()), OK);
            assert_eq!(fmi2GetBoolean(c, bools.as_ptr(), bools.len(), b.as_mut_ptr()), OK);
        }
        bits.extend(r.iter().map(|x| x.to_bits()));
        bits.extend(b.iter().map(|x| *x as u64));
    }
    bits
}

#[test]
fn illegal_call_sequence_is_an_error_that_changes_nothing() {
    let (c, log) = instance();
    unsafe {
        assert_eq!(fmi2DoStep(c, 0.0, 1e-3, 0), ERROR);
        let (status, category, message) = last_message(&log);
        assert_eq!((status, category), (Status::Error, "logStatusError"));
        assert!(message.starts_with("fmi2DoStep: illegal call sequence"), "{message}");
        assert_eq!(fmi2ExitInitializationMode(c), ERROR);
        assert!(last_message(&log).2.contains("illegal call sequence"));
        // Still instantiated: the regular sequence works.
        initialize(c);
        assert_eq!(fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0), ERROR);
        fmi2FreeInstance(c);
    }
}

#[test]
fn a_rejected_set_changes_nothing_and_names_the_variable() {
    let (c, log) = instance();
    initialize(c);
    assert_eq!(set(c, &["q_star[1]"], &[0.25]), OK);
    assert_eq!(set(c, &["q_star[1]", "q_star[3]"], &[0.5, f64::NAN]), ERROR);
    assert!(last_message(&log).2.contains("`q_star[3]` = NaN"), "{:?}", last_message(&log));
    assert_eq!(get(c, &["q_star[1]"]), [0.25]);
    assert_eq!(set(c, &["q_star[1]", "k[1]"], &[0.5, -1.0]), ERROR);
    assert!(last_message(&log).2.contains("k[1]"));
    assert_eq!(get(c, &["q_star[1]", "k[1]"]), [0.25, 1e6]);
    assert_eq!(set(c, &["h_max"], &[1e-5]), ERROR);
    assert!(last_message(&log).2.contains("fixed parameter"));
    let unknown = [100_000];
    assert_eq!(unsafe { fmi2SetReal(c, unknown.as_ptr(), 1, [1.0].as_ptr()) }, ERROR);
    assert!(last_message(&log).2.contains("unknown value reference 100000"));
    unsafe { fmi2FreeInstance(c) };
}

#[test]
fn null_and_foreign_pointers_are_rejected() {
    let (c, log) = instance();
    initialize(c);
    unsafe {
        assert_eq!(fmi2DoStep(std::ptr::null_mut(), 0.0, 1e-3, 0), ERROR);
        // Zero values: pointers are not looked at.
        assert_eq!(fmi2GetReal(c, std::ptr::null(), 0, std::ptr::null_mut()), OK);
        assert_eq!(fmi2GetReal(c, std::ptr::null(), 2, std::ptr::null_mut()), ERROR);
        assert!(last_message(&log).2.contains("`vr[]` is NULL"));
        // An instance passed as an FMU state.
        assert_eq!(fmi2SetFMUstate(c, c), ERROR);
        assert!(last_message(&log).2.contains("not an FMU state"));
        let mut none: fmi2FMUstate = std::ptr::null_mut();
        assert_eq!(fmi2FreeFMUstate(c, &mut none), OK);
        assert_eq!(fmi2FreeFMUstate(c, std::ptr::null_mut()), OK);
        fmi2FreeInstance(c);
        fmi2FreeInstance(std::ptr::null_mut());
    }
}

#[test]
fn a_panic_puts_the_instance_in_the_error_state_and_reset_recovers() {
    let (c, log) = instance();
    initialize(c);
    let allowed = States::of(&[LifeCycle::StepComplete]);
    let status = unsafe { with_instance(c, "fmi2Test", allowed, |_| panic!("boom")) };
    assert_eq!(status, ERROR);
    let (_, _, message) = last_message(&log);
    assert!(message.contains("fmi2Test: internal error (boom)"), "{message}");
    unsafe {
        assert_eq!(fmi2DoStep(c, 0.0, 1e-3, 0), ERROR);
        assert!(last_message(&log).2.contains("state `error`"));
        assert_eq!(fmi2Reset(c), OK);
        initialize(c);
        assert_eq!(fmi2DoStep(c, 0.0, 1e-3, 0), OK);
        fmi2FreeInstance(c);
    }
}

#[test]
fn an_fmu_state_continues_bit_for_bit_in_the_same_and_another_instance() {
    let (a, _) = instance();
    initialize(a);
    run(a, 0.0, 40);
    let mut state: fmi2FMUstate = std::ptr::null_mut();
    unsafe { assert_eq!(fmi2GetFMUstate(a, &mut state), OK) };
    let reference = run(a, 0.04, 40);

    unsafe { assert_eq!(fmi2SetFMUstate(a, state), OK) };
    assert_eq!(run(a, 0.04, 40), reference);

    let mut size = 0;
    unsafe { assert_eq!(fmi2SerializedFMUstateSize(a, state, &mut size), OK) };
    let mut bytes = vec![0 as fmi2Byte; size];
    unsafe {
        assert_eq!(fmi2SerializeFMUstate(a, state, bytes.as_mut_ptr(), size - 1), ERROR);
        assert_eq!(fmi2SerializeFMUstate(a, state, bytes.as_mut_ptr(), size), OK);
        assert_eq!(fmi2FreeFMUstate(a, &mut state), OK);
        assert!(state.is_null());
    }

    let (b, log) = instance();
    let mut copy: fmi2FMUstate = std::ptr::null_mut();
    unsafe {
        let mut corrupted = bytes.clone();
        corrupted[size / 2] ^= 4;
        assert_eq!(fmi2DeSerializeFMUstate(b, corrupted.as_ptr(), size, &mut copy), ERROR);
        assert!(last_message(&log).2.contains("corrupted"));
        assert!(copy.is_null());
        assert_eq!(fmi2DeSerializeFMUstate(b, bytes.as_ptr(), size, &mut copy), OK);
        assert_eq!(fmi2SetFMUstate(b, copy), OK);
        assert_eq!(fmi2FreeFMUstate(b, &mut copy), OK);
    }
    assert_eq!(run(b, 0.04, 40), reference);
    unsafe {
        fmi2FreeInstance(a);
        fmi2FreeInstance(b);
    }
}

#[test]
fn parameter_relations_are_checked_at_the_next_step_and_can_be_corrected() {
    let (c, log) = instance();
    initialize(c);
    assert_eq!(set(c, &["mu_k[1]"], &[0.5]), OK);
    assert_eq!(unsafe { fmi2DoStep(c, 0.0, 1e-3, 0) }, fmi2Status_fmi2Discard);
    let (status, category, message) = last_message(&log);
    assert_eq!((status, category), (Status::Discard, "logStatusDiscard"));
    assert!(message.contains("mu_s") && message.contains("mu_k"), "{message}");
    let mut last = f64::NAN;
    assert_eq!(unsafe { fmi2GetRealStatus(c, fmi2StatusKind_fmi2LastSuccessfulTime, &mut last) }, OK);
    assert_eq!(last, 0.0);
    // Step failed: the master may correct the parameter and repeat the step.
    assert_eq!(set(c, &["mu_s[1]"], &[0.6]), OK);
    assert_eq!(unsafe { fmi2DoStep(c, 0.0, 1e-3, 0) }, OK);
    unsafe { fmi2FreeInstance(c) };
}

#[test]
fn start_values_override_the_rest_position() {
    let (c, _) = instance();
    unsafe {
        assert_eq!(fmi2EnterInitializationMode(c), OK);
        assert_eq!(get(c, &["q[1]", "q[3]"]), [0.0, 0.0]);
        // Joint 1 starts where its drive is (spring relaxed), joint 3 away and moving.
        assert_eq!(set(c, &["q_star[1]", "q_start[1]", "q_start[3]", "qd_start[3]"], &[0.1, 0.1, 0.2, 0.05]), OK);
        // Not used until switched on: q = q*.
        assert_eq!(get(c, &["q[1]", "q[3]"]), [0.1, 0.0]);
        let on = [vr("use_start_values")];
        assert_eq!(fmi2SetBoolean(c, on.as_ptr(), 1, [fmi2True as fmi2Boolean].as_ptr()), OK);
        assert_eq!(get(c, &["q[1]", "q[3]", "qd[3]"]), [0.1, 0.2, 0.05]);
        let mut stick = [9; 2];
        let sticks = [vr("stick[1]"), vr("stick[3]")];
        assert_eq!(fmi2GetBoolean(c, sticks.as_ptr(), 2, stick.as_mut_ptr()), OK);
        assert_eq!(stick, [1, 0], "joint 1 at rest sticks, joint 3 slips");
        assert_eq!(fmi2ExitInitializationMode(c), OK);
        fmi2FreeInstance(c);
    }
}

#[test]
fn input_derivatives_set_the_rates_and_higher_ones_warn() {
    let (c, log) = instance();
    initialize(c);
    let vrs = [vr("q_star[1]"), vr("q_star[1]"), vr("qd_star[3]")];
    unsafe {
        assert_eq!(fmi2SetRealInputDerivatives(c, vrs.as_ptr(), 3, [1, 2, 1].as_ptr(), [0.1, 0.2, 0.3].as_ptr()), OK);
        assert_eq!(get(c, &["qd_star[1]", "qdd_star[1]", "qdd_star[3]"]), [0.1, 0.2, 0.3]);
        assert_eq!(
            fmi2SetRealInputDerivatives(c, vrs.as_ptr(), 1, [3].as_ptr(), [1.0].as_ptr()),
            fmi2Status_fmi2Warning
        );
        assert_eq!(last_message(&log).1, "logStatusWarning");
        let q = [vr("q[1]")];
        assert_eq!(fmi2SetRealInputDerivatives(c, q.as_ptr(), 1, [1].as_ptr(), [1.0].as_ptr()), ERROR);
        fmi2FreeInstance(c);
    }
}

#[test]
fn the_description_lists_value_references_in_order_with_unique_names() {
    let model = Model::reference_rrpr();
    let vars = variables(&model);
    for (i, v) in vars.iter().enumerate() {
        assert_eq!(v.value_reference as usize, i, "{}", v.name);
    }
    let mut names: Vec<_> = vars.iter().map(|v| v.name.as_str()).collect();
    names.sort_unstable();
    names.dedup();
    assert_eq!(names.len(), vars.len());
    // One set per joint; parameters only where the joint has them.
    assert!(names.contains(&"k[3]") && !names.contains(&"k[2]"));
    assert!(names.contains(&"slider_a[3]") && !names.contains(&"slider_a[1]"));
    assert!(names.contains(&"d_A[1]") && names.contains(&"m[4]"));
}

#[test]
fn build_rs_wrote_what_the_library_writes() {
    let written =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/modelDescription/modelDescription.xml"))
            .expect("build.rs writes modelDescription/modelDescription.xml");
    assert_eq!(written, model_description_xml(&Model::reference_rrpr(), REFERENCE_RRPR_TOML));
    assert!(written.contains(&format!("modelIdentifier=\"{MODEL_IDENTIFIER}\"")));
}

#[test]
fn the_guid_follows_the_model_file() {
    let model = Model::reference_rrpr();
    let vars = variables(&model);
    let guid = super::description::guid(REFERENCE_RRPR_TOML, &vars);
    assert_eq!(guid, super::description::guid(REFERENCE_RRPR_TOML, &vars));
    assert_ne!(guid, super::description::guid(&format!("{REFERENCE_RRPR_TOML}\n# edited\n"), &vars));
    assert_eq!(guid.len(), 38);
}

/// Allocations of the current thread only, so that tests running in other
/// threads do not count.
mod counting {
    use std::alloc::{GlobalAlloc, Layout, System};
    use std::cell::Cell;

    thread_local! {
        pub static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
        pub static LIVE_BYTES: Cell<isize> = const { Cell::new(0) };
    }

    pub struct Counting;

    unsafe impl GlobalAlloc for Counting {
        unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
            ALLOCATIONS.with(|c| c.set(c.get() + 1));
            LIVE_BYTES.with(|b| b.set(b.get() + layout.size() as isize));
            unsafe { System.alloc(layout) }
        }
        unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
            LIVE_BYTES.with(|b| b.set(b.get() - layout.size() as isize));
            unsafe { System.dealloc(ptr, layout) }
        }
    }

    #[global_allocator]
    static GLOBAL: Counting = Counting;
}

#[test]
fn do_step_allocates_nothing_and_an_instance_is_small() {
    // Heap owned by an instance of the reference model (logger without debug logging).
    let before = counting::LIVE_BYTES.with(|b| b.get());
    let (logger, _log) = Logger::memory(false);
    let c = into_component(Instance::new(&ModelSource::toml(REFERENCE_RRPR_TOML), logger).expect("reference model"));
    let heap = counting::LIVE_BYTES.with(|b| b.get()) - before;
    assert!(heap > 0 && heap < 64 * 1024, "an instance owns {heap} bytes");
    initialize(c);
    let inputs = ["q_star[1]", "qd_star[1]", "q_star[3]", "qd_star[3]"];
    let vrs: Vec<_> = inputs.iter().map(|n| vr(n)).collect();
    let mut values = [0.0; 4];
    let mut step = |k: usize| {
        let t = k as f64 * 1e-3;
        values.copy_from_slice(&[0.3 * t, 0.3, 0.8 + 0.05 * t, 0.05]);
        unsafe {
            assert_eq!(fmi2SetReal(c, vrs.as_ptr(), vrs.len(), values.as_ptr()), OK);
            assert_eq!(fmi2DoStep(c, t, 1e-3, 0), OK);
        }
    };
    step(0);
    let start = counting::ALLOCATIONS.with(|a| a.get());
    for k in 1..200 {
        step(k);
    }
    let allocations = counting::ALLOCATIONS.with(|a| a.get()) - start;
    assert_eq!(allocations, 0, "fmi2SetReal + fmi2DoStep allocated {allocations} times in 199 steps");
    unsafe { fmi2FreeInstance(c) };
}
