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
        // An instance passed as an FMU state: aligned, but not a live state.
        assert_eq!(fmi2SetFMUstate(c, c), ERROR);
        assert!(last_message(&log).2.contains("is not a live FMU state of this FMU"), "{:?}", last_message(&log));
        // A misaligned pointer (never read) is said to be one, for set and free alike.
        let misaligned: fmi2FMUstate = c.cast::<u8>().wrapping_add(1).cast();
        assert_eq!(fmi2SetFMUstate(c, misaligned), ERROR);
        assert!(last_message(&log).2.contains("misaligned (not aligned to 8 bytes)"), "{:?}", last_message(&log));
        let mut freeing = misaligned;
        assert_eq!(fmi2FreeFMUstate(c, &mut freeing), ERROR);
        assert!(last_message(&log).2.contains("misaligned"), "{:?}", last_message(&log));
        assert_eq!(freeing, misaligned, "a pointer that is not a state is left to the master");
        // NULL for set: said to be NULL.
        assert_eq!(fmi2SetFMUstate(c, std::ptr::null_mut()), ERROR);
        assert!(last_message(&log).2.contains("the FMU state is NULL"), "{:?}", last_message(&log));
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
    assert!(names.contains(&"b_v[1]") && names.contains(&"b_v[3]") && !names.contains(&"b_v[2]"));
}

/// The viscous friction coefficient `b_v[i]` of each joint with friction: a
/// tunable parameter in the joint's damping unit, its range [0, 1e9], its
/// start value the model file's, placed after `v_s[i]`.
#[test]
fn the_viscous_friction_parameter_is_declared_per_joint_with_friction() {
    use super::description::{Causality, Type, Variability};
    use crate::model::Parameter;
    let mut model = Model::reference_rrpr();
    model.set_parameter(Parameter::Viscous, 2, 35.0).unwrap();
    let vars = variables(&model);
    let position = |name: &str| vars.iter().position(|v| v.name == name).unwrap();
    for (name, unit, start) in [("b_v[1]", "N.m.s/rad", 0.0), ("b_v[3]", "N.s/m", 35.0)] {
        let v = &vars[position(name)];
        assert_eq!((v.causality, v.variability), (Causality::Parameter, Variability::Tunable), "{name}");
        assert_eq!(v.ty, Type::Real { unit: Some(unit), min: Some(0.0), max: Some(1e9), start: Some(start) }, "{name}");
        assert!(v.description.contains("mu(v) L sgn(v) + b_v v"), "{name}: {}", v.description);
    }
    assert_eq!(position("b_v[1]"), position("v_s[3]") + 1);
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
    eprintln!("heap of a reference FMU instance: {heap} bytes");
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

/// The FMU of the reference arm with motor drives on joints 1 and 3
/// (`REFERENCE_RRPR_MOTOR_TOML`): motor torque inputs and their derivatives,
/// the fixed gear ratio, refused values that store nothing, FMU states that
/// carry the motor torques and the rotors, and the variable lists of both
/// reference models.
mod motor {
    use super::super::description::{Causality, Type, Variability};
    use super::super::snapshot::Snapshot;
    use super::*;
    use crate::model::REFERENCE_RRPR_MOTOR_TOML;

    const WARNING: fmi2Status = fmi2Status_fmi2Warning;

    fn motor_instance() -> (fmi2Component, Log) {
        let (logger, log) = Logger::memory(true);
        let instance =
            Instance::new(&ModelSource::toml(REFERENCE_RRPR_MOTOR_TOML), logger).expect("motor reference model");
        (into_component(instance), log)
    }

    fn vr(name: &str) -> fmi2ValueReference {
        let model = Model::reference_rrpr_motor();
        variables(&model)
            .iter()
            .find(|v| v.name == name)
            .unwrap_or_else(|| panic!("no variable {name}"))
            .value_reference
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

    fn derivatives(c: fmi2Component, names: &[&str], orders: &[fmi2Integer], values: &[f64]) -> fmi2Status {
        let vrs: Vec<_> = names.iter().map(|n| vr(n)).collect();
        unsafe { fmi2SetRealInputDerivatives(c, vrs.as_ptr(), vrs.len(), orders.as_ptr(), values.as_ptr()) }
    }

    /// What the instance holds, through its own FMU state: the motor torques
    /// τ_m, τ̇_m, τ̈_m it will step with, per joint.
    fn stored_torques(c: fmi2Component) -> [Vec<f64>; 3] {
        let mut torques = None;
        let all = States::of(&[
            LifeCycle::Instantiated,
            LifeCycle::InitializationMode,
            LifeCycle::StepComplete,
            LifeCycle::StepFailed,
        ]);
        let status = unsafe {
            with_instance(c, "stored_torques", all, |instance| {
                let Snapshot { torques: t, .. } = instance.check_snapshot(&instance.snapshot())?;
                torques = Some(t);
                Ok(Status::Ok)
            })
        };
        assert_eq!(status, OK);
        torques.expect("the snapshot decodes")
    }

    /// Every Real and Boolean variable of the motor model, as raw bits.
    fn all_values(c: fmi2Component) -> Vec<u64> {
        let model = Model::reference_rrpr_motor();
        let vars = variables(&model);
        let reals: Vec<_> =
            vars.iter().filter(|v| matches!(v.ty, Type::Real { .. })).map(|v| v.value_reference).collect();
        let bools: Vec<_> =
            vars.iter().filter(|v| matches!(v.ty, Type::Boolean { .. })).map(|v| v.value_reference).collect();
        let mut r = vec![0.0; reals.len()];
        let mut b = vec![0; bools.len()];
        unsafe {
            assert_eq!(fmi2GetReal(c, reals.as_ptr(), reals.len(), r.as_mut_ptr()), OK);
            assert_eq!(fmi2GetBoolean(c, bools.as_ptr(), bools.len(), b.as_mut_ptr()), OK);
        }
        r.iter().map(|x| x.to_bits()).chain(b.iter().map(|x| *x as u64)).collect()
    }

    /// `n` steps of 1 ms from `t` with the torques the instance holds (none
    /// set here): every variable after every step, as raw bits.
    fn run(c: fmi2Component, t: f64, n: usize) -> Vec<u64> {
        let mut bits = Vec::new();
        for k in 0..n {
            assert_eq!(unsafe { fmi2DoStep(c, t + k as f64 * 1e-3, 1e-3, 0) }, OK);
            bits.extend(all_values(c));
        }
        bits
    }

    // τ_m on both motors moves their rotors forwards: after 20 steps of 1 ms
    // every Real output is finite, the rotor of joint 1 (0.5 N·m against
    // τ_c = 0.03 N·m) turns and slips, its kinetic energy and the motors'
    // work are positive; tau_m reads back what was set.
    #[test]
    fn tau_m_turns_the_rotors_and_every_output_stays_finite() {
        let (c, _) = motor_instance();
        initialize(c);
        assert_eq!(get(c, &["theta_m[1]", "omega_m[1]", "theta_m[3]"]), [0.0, 0.0, 0.0]);
        assert_eq!(set(c, &["tau_m[1]", "tau_m[3]"], &[0.5, 0.3]), OK);
        assert_eq!(get(c, &["tau_m[1]", "tau_m[3]"]), [0.5, 0.3]);
        for k in 0..20 {
            assert_eq!(unsafe { fmi2DoStep(c, k as f64 * 1e-3, 1e-3, 0) }, OK);
        }
        let model = Model::reference_rrpr_motor();
        for v in
            variables(&model).iter().filter(|v| v.causality == Causality::Output && matches!(v.ty, Type::Real { .. }))
        {
            let x = get(c, &[v.name.as_str()])[0];
            assert!(x.is_finite(), "{} = {x}", v.name);
        }
        let [theta, omega, e_rotor, w_drive] = get(c, &["theta_m[1]", "omega_m[1]", "E_rotor", "W_drive"])[..] else {
            unreachable!()
        };
        assert!(theta > 0.0 && omega > 0.0, "theta_m[1] = {theta}, omega_m[1] = {omega}");
        assert!(e_rotor > 0.0 && w_drive > 0.0, "E_rotor = {e_rotor}, W_drive = {w_drive}");
        let mut stuck = [9];
        unsafe { assert_eq!(fmi2GetBoolean(c, [vr("stick_m[1]")].as_ptr(), 1, stuck.as_mut_ptr()), OK) };
        assert_eq!(stuck, [0], "the rotor of joint 1 slips under 0.5 N·m");
        unsafe { fmi2FreeInstance(c) };
    }

    // gear_ratio[i] is a fixed parameter: set before fmi2ExitInitializationMode
    // it is used; after it, fmi2SetReal refuses it (naming it, `fixed
    // parameter`) and nothing changes, while J_m, b_m, tau_c stay tunable
    // (within their ranges).
    #[test]
    fn gear_ratio_is_fixed_after_initialization_and_the_rotor_parameters_are_tunable() {
        let (c, log) = motor_instance();
        assert_eq!(set(c, &["gear_ratio[1]"], &[50.0]), OK, "settable once instantiated");
        unsafe {
            assert_eq!(fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0), OK);
            assert_eq!(fmi2EnterInitializationMode(c), OK);
        }
        assert_eq!(get(c, &["gear_ratio[1]", "gear_ratio[3]"]), [50.0, 628.3185307179587]);
        assert_eq!(set(c, &["gear_ratio[3]"], &[500.0]), OK, "settable in initialization mode");
        unsafe { assert_eq!(fmi2ExitInitializationMode(c), OK) };
        assert_eq!(get(c, &["gear_ratio[1]", "gear_ratio[3]"]), [50.0, 500.0]);

        assert_eq!(set(c, &["gear_ratio[1]"], &[80.0]), ERROR);
        let (status, _, message) = last_message(&log);
        assert_eq!(status, Status::Error);
        assert!(message.contains("`gear_ratio[1]` is a fixed parameter"), "{message}");
        // With a tunable one in the same call: refused as a whole.
        assert_eq!(set(c, &["J_m[1]", "gear_ratio[3]"], &[1e-3, 600.0]), ERROR);
        assert_eq!(get(c, &["gear_ratio[1]", "gear_ratio[3]", "J_m[1]"]), [50.0, 500.0, 3e-4]);

        assert_eq!(set(c, &["J_m[1]", "b_m[3]", "tau_c[1]"], &[1e-3, 0.0, 0.05]), OK);
        assert_eq!(get(c, &["J_m[1]", "b_m[3]", "tau_c[1]"]), [1e-3, 0.0, 0.05]);
        assert_eq!(set(c, &["J_m[1]"], &[0.0]), ERROR);
        assert!(last_message(&log).2.contains("J_m[1]"), "{:?}", last_message(&log));
        assert_eq!(set(c, &["tau_c[3]"], &[-1.0]), ERROR);
        assert_eq!(get(c, &["J_m[1]", "tau_c[3]"]), [1e-3, 0.02]);
        assert_eq!(unsafe { fmi2DoStep(c, 0.0, 1e-3, 0) }, OK);
        unsafe { fmi2FreeInstance(c) };
    }

    // fmi2SetRealInputDerivatives on tau_m: order 1 sets τ̇_m, order 2 τ̈_m
    // (read from the instance's own FMU state), and the step uses them; a
    // non-zero order 3 is ignored with fmi2Warning (a zero one is fine); a
    // derivative outside its range (|τ̇_m| ≤ 1e9, |τ̈_m| ≤ 1e12) or NaN is
    // refused and nothing of the call is stored.
    #[test]
    fn tau_m_derivatives_of_order_1_and_2_are_taken_and_order_3_warns() {
        let (c, log) = motor_instance();
        initialize(c);
        let (a, _) = motor_instance();
        initialize(a);
        assert_eq!(derivatives(c, &["tau_m[1]", "tau_m[1]", "tau_m[3]"], &[1, 2, 1], &[200.0, 1e4, -1.0]), OK);
        let [tau, rate, accel] = stored_torques(c);
        assert_eq!((tau[0], rate[0], accel[0]), (0.0, 200.0, 1e4));
        assert_eq!((tau[2], rate[2], accel[2]), (0.0, -1.0, 0.0));
        assert_eq!(stored_torques(a), [vec![0.0; 4], vec![0.0; 4], vec![0.0; 4]]);

        // Order 3: a zero is accepted silently, a non-zero one warns and changes nothing.
        assert_eq!(derivatives(c, &["tau_m[3]"], &[3], &[0.0]), OK);
        assert_eq!(derivatives(c, &["tau_m[1]"], &[3], &[5.0]), WARNING);
        let (status, category, message) = last_message(&log);
        assert_eq!((status, category), (Status::Warning, "logStatusWarning"));
        assert!(message.contains("order 3 of `tau_m[1]`"), "{message}");
        assert_eq!(stored_torques(c)[1..], [vec![200.0, 0.0, -1.0, 0.0], vec![1e4, 0.0, 0.0, 0.0]]);

        // Out of range, NaN: refused, the valid entries of the call not stored either.
        assert_eq!(derivatives(c, &["tau_m[3]", "tau_m[1]"], &[1, 2], &[7.0, 2e12]), ERROR);
        let message = last_message(&log).2;
        assert!(
            message.contains("`tau_m[1]`") && message.contains("tau_m''") && message.contains("[-1e12, 1e12]"),
            "{message}"
        );
        assert_eq!(derivatives(c, &["tau_m[3]", "tau_m[1]"], &[1, 1], &[7.0, -2e9]), ERROR);
        assert!(last_message(&log).2.contains("[-1e9, 1e9]"), "{:?}", last_message(&log));
        assert_eq!(derivatives(c, &["tau_m[3]", "tau_m[3]"], &[1, 2], &[7.0, f64::NAN]), ERROR);
        assert!(last_message(&log).2.contains("not a finite number"), "{:?}", last_message(&log));
        assert_eq!(stored_torques(c)[1..], [vec![200.0, 0.0, -1.0, 0.0], vec![1e4, 0.0, 0.0, 0.0]]);
        // The bounds themselves are admissible.
        assert_eq!(derivatives(c, &["tau_m[3]", "tau_m[3]"], &[1, 2], &[-1e9, 1e12]), OK);
        assert_eq!(derivatives(c, &["tau_m[3]", "tau_m[3]"], &[1, 2], &[-1.0, 0.0]), OK);

        // The step runs with the derivatives: τ_m of joint 1 passes τ_c =
        // 0.03 N·m at about 0.14 ms, and its rotor turns, where the instance
        // without them stays at rest.
        unsafe {
            assert_eq!(fmi2DoStep(c, 0.0, 1e-3, 0), OK);
            assert_eq!(fmi2DoStep(a, 0.0, 1e-3, 0), OK);
        }
        assert!(get(c, &["omega_m[1]"])[0] > 0.0);
        assert_eq!(get(a, &["theta_m[1]", "omega_m[1]"]), [0.0, 0.0]);
        unsafe {
            fmi2FreeInstance(c);
            fmi2FreeInstance(a);
        }
    }

    // fmi2SetReal of tau_m outside [-1e6, 1e6] N·m, or NaN or infinite, is
    // refused naming the variable, and nothing of the call is stored (the
    // valid value before it neither); the bounds are admissible.
    #[test]
    fn out_of_range_or_non_finite_tau_m_is_refused_and_nothing_is_stored() {
        let (c, log) = motor_instance();
        initialize(c);
        assert_eq!(set(c, &["tau_m[1]"], &[0.25]), OK);
        let above = f64::from_bits(1e6f64.to_bits() + 1);
        for (value, says) in [
            (above, "outside its range [-1e6, 1e6]"),
            (-2e6, "outside its range"),
            (f64::NAN, "not a finite number"),
            (f64::INFINITY, "not a finite number"),
        ] {
            assert_eq!(set(c, &["tau_m[1]", "tau_m[3]"], &[0.5, value]), ERROR, "{value}");
            let message = last_message(&log).2;
            assert!(message.contains("`tau_m[3]`") && message.contains(says), "{message}");
            assert_eq!(get(c, &["tau_m[1]", "tau_m[3]"]), [0.25, 0.0]);
            assert_eq!(stored_torques(c)[0], [0.25, 0.0, 0.0, 0.0]);
        }
        assert_eq!(set(c, &["tau_m[1]", "tau_m[3]"], &[1e6, -1e6]), OK);
        assert_eq!(get(c, &["tau_m[1]", "tau_m[3]"]), [1e6, -1e6]);
        unsafe { fmi2FreeInstance(c) };
    }

    // An FMU state of the motor arm, taken mid-motion, continues bit for bit
    // (every variable, every step) in the same instance and, serialized, in
    // a fresh one, with the motor torques and their derivatives it holds
    // (set once before the state is taken, changed after it).
    #[test]
    fn an_fmu_state_of_the_motor_arm_continues_bit_for_bit_with_its_torques() {
        let (a, _) = motor_instance();
        initialize(a);
        assert_eq!(set(a, &["tau_m[1]", "tau_m[3]"], &[0.4, -0.05]), OK);
        assert_eq!(derivatives(a, &["tau_m[1]", "tau_m[3]"], &[1, 2], &[-20.0, 3.0]), OK);
        run(a, 0.0, 30);
        let mut state: fmi2FMUstate = std::ptr::null_mut();
        unsafe { assert_eq!(fmi2GetFMUstate(a, &mut state), OK) };
        let reference = run(a, 0.03, 30);
        // The rotor of joint 1 moved: there is something to restore.
        assert_ne!(get(a, &["theta_m[1]"])[0], 0.0);

        // Other torques, then the state back: the saved torques again.
        assert_eq!(set(a, &["tau_m[1]", "tau_m[3]"], &[0.9, 0.9]), OK);
        unsafe { assert_eq!(fmi2SetFMUstate(a, state), OK) };
        assert_eq!(get(a, &["tau_m[1]", "tau_m[3]"]), [0.4, -0.05]);
        assert_eq!(run(a, 0.03, 30), reference);

        let mut size = 0;
        let mut bytes;
        unsafe {
            assert_eq!(fmi2SerializedFMUstateSize(a, state, &mut size), OK);
            bytes = vec![0 as fmi2Byte; size];
            assert_eq!(fmi2SerializeFMUstate(a, state, bytes.as_mut_ptr(), size), OK);
            assert_eq!(fmi2FreeFMUstate(a, &mut state), OK);
        }
        let (b, _) = motor_instance();
        let mut copy: fmi2FMUstate = std::ptr::null_mut();
        unsafe {
            assert_eq!(fmi2DeSerializeFMUstate(b, bytes.as_ptr(), size, &mut copy), OK);
            assert_eq!(fmi2SetFMUstate(b, copy), OK);
            assert_eq!(fmi2FreeFMUstate(b, &mut copy), OK);
        }
        assert_eq!(stored_torques(b)[1], [-20.0, 0.0, 0.0, 0.0]);
        assert_eq!(run(b, 0.03, 30), reference);

        // The reference arm's instance refuses the motor arm's state.
        let (other, log) = super::instance();
        unsafe {
            assert_eq!(fmi2DeSerializeFMUstate(other, bytes.as_ptr(), size, &mut copy), ERROR);
            fmi2FreeInstance(a);
            fmi2FreeInstance(b);
            fmi2FreeInstance(other);
        }
        assert!(last_message(&log).2.contains("rejected FMU state"), "{:?}", last_message(&log));
    }

    // With use_start_values, a rotor left at theta_m_start = 0 behind a link
    // started at q_start[3] = 0.8 m winds its gear spring up by 0.8 m: the
    // start works as declared, and the log says what it means and how to
    // start unloaded (theta_m_start[3] = N·q_start[3]), which then logs nothing.
    #[test]
    fn a_rotor_start_that_loads_the_gear_spring_is_reported() {
        let n3 = 628.3185307179587;
        let warnings = |theta_m_start_3: Option<f64>| {
            let (c, log) = motor_instance();
            unsafe {
                assert_eq!(fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0), OK);
                assert_eq!(fmi2EnterInitializationMode(c), OK);
                assert_eq!(set(c, &["q_star[3]", "q_start[3]"], &[0.8, 0.8]), OK);
                if let Some(x) = theta_m_start_3 {
                    assert_eq!(set(c, &["theta_m_start[3]"], &[x]), OK);
                }
                let on = [vr("use_start_values")];
                assert_eq!(fmi2SetBoolean(c, on.as_ptr(), 1, [fmi2True as fmi2Boolean].as_ptr()), OK);
                // Outputs read in initialization mode start the engine; the
                // warning comes once, with fmi2ExitInitializationMode.
                get(c, &["q[3]"]);
                let exit = fmi2ExitInitializationMode(c);
                let theta = get(c, &["theta_m[3]", "q[3]"]);
                fmi2FreeInstance(c);
                let found: Vec<String> = log
                    .borrow()
                    .iter()
                    .filter(|m| m.2.contains("gear spring deflected"))
                    .map(|m| m.2.clone())
                    .collect();
                (exit, theta, found)
            }
        };
        let (exit, theta, found) = warnings(None);
        assert_eq!(exit, WARNING);
        assert_eq!(theta, [0.0, 0.8], "the start is the one declared");
        assert_eq!(found.len(), 1, "one warning of the loaded gear spring: {found:?}");
        let m = &found[0];
        for part in
            ["joint 3", "theta_m_start[3] = 0 rad", "deflected by 8.000000e-1 m", "8.000000e5 N", "static_start = true"]
        {
            assert!(m.contains(part), "`{part}` not in: {m}");
        }
        assert!(m.contains(&format!("= {}", n3 * 0.8)), "{m}");
        let (exit, theta, found) = warnings(Some(n3 * 0.8));
        assert_eq!(exit, OK);
        assert_eq!(theta, [n3 * 0.8, 0.8]);
        assert!(found.is_empty(), "{found:?}");
    }

    // fmi2SetReal of tau_m + fmi2DoStep of the motor arm allocate nothing.
    #[test]
    fn do_step_of_the_motor_arm_allocates_nothing() {
        let (logger, _log) = Logger::memory(false);
        let c =
            into_component(Instance::new(&ModelSource::toml(REFERENCE_RRPR_MOTOR_TOML), logger).expect("motor model"));
        initialize(c);
        let vrs = [vr("tau_m[1]"), vr("tau_m[3]")];
        let step = |k: usize| {
            let t = k as f64 * 1e-3;
            let values = [0.3 + 0.1 * t, 0.05];
            unsafe {
                assert_eq!(fmi2SetReal(c, vrs.as_ptr(), 2, values.as_ptr()), OK);
                assert_eq!(fmi2DoStep(c, t, 1e-3, 0), OK);
            }
        };
        step(0);
        let start = super::counting::ALLOCATIONS.with(|a| a.get());
        for k in 1..100 {
            step(k);
        }
        let allocations = super::counting::ALLOCATIONS.with(|a| a.get()) - start;
        assert_eq!(allocations, 0, "fmi2SetReal + fmi2DoStep allocated {allocations} times in 99 steps");
        unsafe { fmi2FreeInstance(c) };
    }

    /// The motor-only variables of the motor arm, with their causality,
    /// variability and type (R: Real, B: Boolean).
    const MOTOR_VARIABLES: [(&str, Causality, Variability, char); 27] = [
        ("tau_m[1]", Causality::Input, Variability::Continuous, 'R'),
        ("tau_m[3]", Causality::Input, Variability::Continuous, 'R'),
        ("theta_m[1]", Causality::Output, Variability::Continuous, 'R'),
        ("theta_m[3]", Causality::Output, Variability::Continuous, 'R'),
        ("omega_m[1]", Causality::Output, Variability::Continuous, 'R'),
        ("omega_m[3]", Causality::Output, Variability::Continuous, 'R'),
        ("stick_m[1]", Causality::Output, Variability::Discrete, 'B'),
        ("stick_m[3]", Causality::Output, Variability::Discrete, 'B'),
        ("n_stick_m[1]", Causality::Output, Variability::Continuous, 'R'),
        ("n_stick_m[3]", Causality::Output, Variability::Continuous, 'R'),
        ("tau_load[1]", Causality::Output, Variability::Continuous, 'R'),
        ("tau_load[3]", Causality::Output, Variability::Continuous, 'R'),
        ("tau_f_m[1]", Causality::Output, Variability::Continuous, 'R'),
        ("tau_f_m[3]", Causality::Output, Variability::Continuous, 'R'),
        ("E_rotor", Causality::Output, Variability::Continuous, 'R'),
        ("Q_motor", Causality::Output, Variability::Continuous, 'R'),
        ("gear_ratio[1]", Causality::Parameter, Variability::Fixed, 'R'),
        ("gear_ratio[3]", Causality::Parameter, Variability::Fixed, 'R'),
        ("J_m[1]", Causality::Parameter, Variability::Tunable, 'R'),
        ("J_m[3]", Causality::Parameter, Variability::Tunable, 'R'),
        ("b_m[1]", Causality::Parameter, Variability::Tunable, 'R'),
        ("b_m[3]", Causality::Parameter, Variability::Tunable, 'R'),
        ("tau_c[1]", Causality::Parameter, Variability::Tunable, 'R'),
        ("tau_c[3]", Causality::Parameter, Variability::Tunable, 'R'),
        ("theta_m_start[1]", Causality::Parameter, Variability::Fixed, 'R'),
        ("omega_m_start[3]", Causality::Parameter, Variability::Fixed, 'R'),
        ("static_start", Causality::Parameter, Variability::Fixed, 'B'),
    ];

    /// True for the name of a variable only a model with motor drives has.
    fn is_motor_variable(name: &str) -> bool {
        let base = name.split('[').next().unwrap();
        [
            "tau_m",
            "theta_m",
            "omega_m",
            "stick_m",
            "n_stick_m",
            "tau_load",
            "tau_f_m",
            "E_rotor",
            "Q_motor",
            "gear_ratio",
            "J_m",
            "b_m",
            "tau_c",
            "theta_m_start",
            "omega_m_start",
            "static_start",
        ]
        .contains(&base)
    }

    fn type_letter(t: &Type) -> char {
        match t {
            Type::Real { .. } => 'R',
            Type::Boolean { .. } => 'B',
        }
    }

    // The motor arm lists, for its motor joints 1 and 3 only, the input tau_m,
    // the outputs theta_m, omega_m, stick_m, n_stick_m, tau_load, tau_f_m and
    // E_rotor, Q_motor, the tunable J_m, b_m, tau_c, the fixed gear_ratio and
    // start values, with these causalities and variabilities in the
    // modelDescription.xml as well; the outputs are in ModelStructure.
    #[test]
    fn the_motor_model_description_lists_the_motor_variables() {
        let model = Model::reference_rrpr_motor();
        let vars = variables(&model);
        for (i, v) in vars.iter().enumerate() {
            assert_eq!(v.value_reference as usize, i, "{}", v.name);
        }
        let xml = model_description_xml(&model, REFERENCE_RRPR_MOTOR_TOML);
        for (name, causality, variability, ty) in MOTOR_VARIABLES {
            let v = vars.iter().find(|v| v.name == name).unwrap_or_else(|| panic!("no variable {name}"));
            assert_eq!((v.causality, v.variability, type_letter(&v.ty)), (causality, variability, ty), "{name}");
            let element = xml
                .split("<ScalarVariable ")
                .find(|e| e.starts_with(&format!("name=\"{name}\"")))
                .unwrap_or_else(|| panic!("{name} is not in the XML"));
            let (c, va) = (format!("{causality:?}").to_lowercase(), format!("{variability:?}").to_lowercase());
            assert!(
                element.contains(&format!("causality=\"{c}\"")) && element.contains(&format!("variability=\"{va}\"")),
                "{name}: {element}"
            );
            if causality == Causality::Output {
                assert!(
                    xml.contains(&format!("<Unknown index=\"{}\" dependencies=\"\"/>", v.value_reference + 1)),
                    "{name} not in Outputs"
                );
            }
        }
        // tau_m: N.m, its range, start 0; the ball screw's ratio in rad/m.
        let tau = vars.iter().find(|v| v.name == "tau_m[1]").unwrap();
        assert_eq!(tau.ty, Type::Real { unit: Some("N.m"), min: Some(-1e6), max: Some(1e6), start: Some(0.0) });
        let ratio = |name: &str| vars.iter().find(|v| v.name == name).unwrap().ty;
        assert!(matches!(ratio("gear_ratio[1]"), Type::Real { unit: None, start: Some(s), .. } if s == 100.0));
        assert!(matches!(ratio("gear_ratio[3]"), Type::Real { unit: Some("rad/m"), .. }));
        // Nothing for the rigid joints 2 and 4.
        for j in [2, 4] {
            for base in ["tau_m", "theta_m", "omega_m", "stick_m", "tau_load", "gear_ratio", "J_m", "theta_m_start"] {
                let name = format!("{base}[{j}]");
                assert!(!vars.iter().any(|v| v.name == name), "{name} exists");
            }
        }
        // Inputs first: the drive inputs of every joint, then tau_m.
        let inputs: Vec<&str> =
            vars.iter().filter(|v| v.causality == Causality::Input).map(|v| v.name.as_str()).collect();
        assert_eq!(inputs.len(), 14);
        assert_eq!(inputs[12..], ["tau_m[1]", "tau_m[3]"]);
        assert_eq!(
            vars.iter().filter(|v| is_motor_variable(&v.name)).count(),
            2 * 13 + 3,
            "13 per motor joint, E_rotor, Q_motor, static_start"
        );
    }

    // The reference arm (no motor) lists no motor variable, and its list is
    // the one it had before motor drives (124 variables, at 9a851d5^) with
    // the viscous friction coefficients b_v[1], b_v[3] added since (126): the
    // motor arm's list without its motor variables, name for name, with the
    // same causality, variability and type.
    #[test]
    fn the_reference_model_description_has_no_motor_variables_and_is_unchanged() {
        let reference = variables(&Model::reference_rrpr());
        assert_eq!(reference.len(), 124 + 2);
        let motor_names: Vec<&str> =
            reference.iter().map(|v| v.name.as_str()).filter(|n| is_motor_variable(n)).collect();
        assert!(motor_names.is_empty(), "{motor_names:?}");
        let xml = model_description_xml(&Model::reference_rrpr(), REFERENCE_RRPR_TOML);
        for name in ["tau_m[", "theta_m[", "E_rotor", "gear_ratio[", "static_start"] {
            assert!(!xml.contains(&format!("name=\"{name}")), "{name} in the reference XML");
        }
        let summary =
            |v: &super::super::description::Variable| (v.name.clone(), v.causality, v.variability, type_letter(&v.ty));
        let without_motors: Vec<_> = variables(&Model::reference_rrpr_motor())
            .iter()
            .filter(|v| !is_motor_variable(&v.name))
            .map(summary)
            .collect();
        let reference: Vec<_> = reference.iter().map(summary).collect();
        assert_eq!(reference, without_motors);
    }
}

// ---- stickslip_run_experiment ------------------------------------------------------

/// The inputs of the experiments below: q*, q̇*, q̈* of joints 1 and 3
/// (joint 1 accelerated, reversed at 0.15 s; joint 3 pushed out and back),
/// at `n` points 1 ms apart from 0.
fn experiment_inputs(n: usize) -> (Vec<f64>, Vec<fmi2ValueReference>, Vec<f64>) {
    let names = ["q_star[1]", "qd_star[1]", "qdd_star[1]", "q_star[3]", "qd_star[3]", "qdd_star[3]"];
    let vrs = names.iter().map(|n| vr(n)).collect();
    let time: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
    let drive = time
        .iter()
        .flat_map(|&t| {
            let (a, w) = (4.0, 2.0 * std::f64::consts::PI / 0.3);
            [a * (1.0 - (w * t).cos()) / (w * w), a * (w * t).sin() / w, a * (w * t).cos(), 0.02 * t, 0.02, 0.0]
        })
        .collect();
    (time, vrs, drive)
}

const EXPERIMENT_OUTPUTS: [&str; 4] = ["q[1]", "q[3]", "qd[1]", "F_friction[1]"];

/// stickslip_run_experiment without motor torques, on slices: (status,
/// points reached).
#[allow(clippy::too_many_arguments)]
fn call_run_experiment(
    c: fmi2Component,
    time: &[f64],
    drive_vrs: &[fmi2ValueReference],
    drive: &[f64],
    outputs: &[fmi2ValueReference],
    values: &mut [f64],
    wrt: &[fmi2ValueReference],
    steps: &[f64],
    central: bool,
    sens: &mut [f64],
    departures: &mut [u64],
) -> (fmi2Status, usize) {
    let mut reached = usize::MAX;
    let status = unsafe {
        stickslip_run_experiment(
            c,
            time.len(),
            time.as_ptr(),
            drive_vrs.len(),
            drive_vrs.as_ptr(),
            drive.as_ptr(),
            0,
            std::ptr::null(),
            std::ptr::null(),
            std::ptr::null(),
            std::ptr::null(),
            outputs.len(),
            outputs.as_ptr(),
            values.as_mut_ptr(),
            wrt.len(),
            wrt.as_ptr(),
            steps.as_ptr(),
            fmi2Boolean::from(central),
            2,
            sens.as_mut_ptr(),
            departures.as_mut_ptr(),
            &mut reached,
        )
    };
    (status, reached)
}

/// (status, outputs, sensitivities, departures, reached) of
/// stickslip_run_experiment on `c` for `n` points, with the sensitivities
/// to `wrt` (steps `steps`) when not empty.
fn run_experiment(
    c: fmi2Component,
    n: usize,
    wrt: &[&str],
    steps: &[f64],
    central: bool,
) -> (fmi2Status, Vec<f64>, Vec<f64>, Vec<u64>, usize) {
    let (time, drive_vrs, drive) = experiment_inputs(n);
    let outputs: Vec<_> = EXPERIMENT_OUTPUTS.iter().map(|n| vr(n)).collect();
    let wrt_vrs: Vec<_> = wrt.iter().map(|n| vr(n)).collect();
    let mut values = vec![f64::NAN; n * outputs.len()];
    let mut sens = vec![f64::NAN; n * outputs.len() * wrt.len()];
    let mut departures = vec![0u64; wrt.len()];
    let (status, reached) = call_run_experiment(
        c,
        &time,
        &drive_vrs,
        &drive,
        &outputs,
        &mut values,
        &wrt_vrs,
        steps,
        central,
        &mut sens,
        &mut departures,
    );
    (status, values, sens, departures, reached)
}

/// An instance with `values` set, set up at t = 0, not initialized.
fn configured(values: &[(&str, f64)]) -> (fmi2Component, Log) {
    let (c, log) = instance();
    unsafe { assert_eq!(fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0), OK) };
    for (name, x) in values {
        assert_eq!(set(c, &[name], &[*x]), OK, "{name} = {x}");
    }
    (c, log)
}

/// The same experiment through the per-point FMI calls.
fn per_point(c: fmi2Component, n: usize) -> Vec<f64> {
    let (time, drive_vrs, drive) = experiment_inputs(n);
    let outputs: Vec<_> = EXPERIMENT_OUTPUTS.iter().map(|n| vr(n)).collect();
    let m = drive_vrs.len();
    let mut values = vec![f64::NAN; n * outputs.len()];
    unsafe {
        assert_eq!(fmi2EnterInitializationMode(c), OK);
        assert_eq!(fmi2SetReal(c, drive_vrs.as_ptr(), m, drive[..m].as_ptr()), OK);
        assert_eq!(fmi2ExitInitializationMode(c), OK);
        assert_eq!(fmi2GetReal(c, outputs.as_ptr(), outputs.len(), values.as_mut_ptr()), OK);
        for k in 0..n - 1 {
            assert_eq!(fmi2SetReal(c, drive_vrs.as_ptr(), m, drive[k * m..(k + 1) * m].as_ptr()), OK);
            assert_eq!(fmi2DoStep(c, time[k], time[k + 1] - time[k], 0), OK);
            let row = &mut values[(k + 1) * outputs.len()..(k + 2) * outputs.len()];
            assert_eq!(fmi2GetReal(c, outputs.as_ptr(), outputs.len(), row.as_mut_ptr()), OK);
        }
    }
    values
}

fn bits(x: &[f64]) -> Vec<u64> {
    x.iter().map(|v| v.to_bits()).collect()
}

#[test]
fn a_whole_experiment_in_one_call_is_the_per_point_calls_bit_for_bit() {
    let n = 300;
    let values = [("mu_k[1]", 0.17), ("mu_s[1]", 0.22), ("k[3]", 8e5)];
    let (a, _) = configured(&values);
    let expected = per_point(a, n);
    let (b, _) = configured(&values);
    let (status, outputs, _, _, reached) = run_experiment(b, n, &[], &[], false);
    assert_eq!((status, reached), (OK, n));
    assert_eq!(bits(&outputs), bits(&expected));
    // Recording the schedule for the sensitivities changes nothing of the run.
    let (c, _) = configured(&values);
    let (status, outputs, _, departures, _) = run_experiment(c, n, &["mu_k[1]"], &[1e-7], false);
    assert_eq!(status, OK);
    assert_eq!(bits(&outputs), bits(&expected));
    assert_eq!(departures, [0]);
    // In parts: the second call goes on from the first's last point.
    let (d, _) = configured(&values);
    let (status, first, _, _, _) = run_experiment(d, 120, &[], &[], false);
    assert_eq!(status, OK);
    assert_eq!(bits(&first), bits(&expected[..120 * 4]));
    unsafe { fmi2FreeInstance(d) };
    for c in [a, b, c] {
        unsafe { fmi2FreeInstance(c) };
    }
}

#[test]
fn an_experiment_goes_on_from_step_mode_at_the_fmus_time() {
    let (time, drive_vrs, drive) = experiment_inputs(200);
    let outputs: Vec<_> = EXPERIMENT_OUTPUTS.iter().map(|n| vr(n)).collect();
    let call = |c, range: std::ops::Range<usize>, values: &mut [f64]| {
        let m = drive_vrs.len();
        let (time, drive) = (&time[range.clone()], &drive[range.start * m..range.end * m]);
        call_run_experiment(c, time, &drive_vrs, drive, &outputs, values, &[], &[], false, &mut [], &mut [])
    };
    let (whole, _) = configured(&[]);
    let mut all = vec![f64::NAN; 200 * 4];
    assert_eq!(call(whole, 0..200, &mut all), (OK, 200));
    let (parts, log) = configured(&[]);
    let mut a = vec![f64::NAN; 80 * 4];
    let mut b = vec![f64::NAN; 121 * 4];
    assert_eq!(call(parts, 0..80, &mut a), (OK, 80));
    // Not from the FMU's time: refused, nothing done.
    assert_eq!(call(parts, 80..200, &mut b[4..]), (ERROR, 0));
    assert!(last_message(&log).2.contains("is not the FMU's time"), "{:?}", last_message(&log));
    assert_eq!(call(parts, 79..200, &mut b), (OK, 121));
    assert_eq!(bits(&a), bits(&all[..80 * 4]));
    assert_eq!(bits(&b), bits(&all[79 * 4..]));
    for c in [whole, parts] {
        unsafe { fmi2FreeInstance(c) };
    }
}

#[test]
fn bad_experiments_are_errors_naming_the_problem() {
    let cases: [(&[&str], &[f64], &str); 3] = [
        (&["q[1]"], &[1e-6], "`q[1]` is neither a Real parameter nor a start value"),
        (&["mu_k[1]"], &[0.0], "the step of `mu_k[1]` is 0"),
        (&["mu_k[1]"], &[f64::NAN], "the step of `mu_k[1]` is NaN"),
    ];
    for (wrt, steps, message) in cases {
        let (c, log) = configured(&[]);
        let (status, ..) = run_experiment(c, 10, wrt, steps, false);
        assert_eq!(status, ERROR);
        assert!(last_message(&log).2.contains(message), "{:?}", last_message(&log));
        // Nothing happened: the instance is still instantiated.
        assert_eq!(run_experiment(c, 10, &[], &[], false).0, OK);
        unsafe { fmi2FreeInstance(c) };
    }
    // Sensitivities need the start.
    let (c, log) = configured(&[]);
    assert_eq!(run_experiment(c, 10, &[], &[], false).0, OK);
    let (status, ..) = run_experiment(c, 10, &["mu_k[1]"], &[1e-6], false);
    assert_eq!(status, ERROR);
    assert!(last_message(&log).2.contains("sensitivities are taken from the start"), "{:?}", last_message(&log));
    unsafe { fmi2FreeInstance(c) };
    // Points that do not increase.
    let (c, log) = configured(&[]);
    let time = [0.0, 1e-3, 1e-3];
    let mut out = [0.0; 3];
    let o = [vr("q[1]")];
    let (status, reached) = call_run_experiment(c, &time, &[], &[], &o, &mut out, &[], &[], false, &mut [], &mut []);
    assert_eq!((status, reached), (ERROR, 0));
    assert!(last_message(&log).2.contains("the points must increase"), "{:?}", last_message(&log));
    unsafe { fmi2FreeInstance(c) };
}

/// Central differences of free runs at fixed sub-steps with the Newmark
/// iteration at 1e-13 over a change of `relative` of the value x:
/// (points × outputs) derivatives.
fn free_differences(values: &[(&str, f64)], name: &str, x: f64, n: usize, relative: f64) -> Vec<f64> {
    let change = relative * x.abs();
    let run_at = |v: f64| {
        let mut all = values.to_vec();
        all.push((name, v));
        let (c, _) = configured(&all);
        let (status, out, ..) = run_experiment(c, n, &[], &[], false);
        assert_eq!(status, OK);
        unsafe { fmi2FreeInstance(c) };
        out
    };
    let (plus, minus) = (run_at(x + change), run_at(x - change));
    plus.iter().zip(&minus).map(|(p, m)| (p - m) / (2.0 * change)).collect()
}

#[test]
fn sensitivities_are_the_derivatives_of_the_scheme_across_stick_slip_events() {
    // Fixed sub-steps of 1e-4 s: free runs take the sub-steps a replay takes,
    // so central differences of free runs tend to the replays' derivative as
    // their change shrinks, until their own noise takes over (a free run
    // locates an event to 1e-7 of a sub-step, a replay to 1e-12); the best
    // of them is compared. Joint 1 sticks and slips in these 0.3 s, so every
    // column crosses events, each located afresh in every run (the
    // saltation). Measured, of the column's largest value: k[3] 4e-8 (it
    // hardly moves the events), k[1] 2.8e-6, mu_k[1] 4.3e-6, and mu_s[1],
    // which moves the breakaway instants themselves, 5e-5: where the free
    // differences stop, their located instants' noise over the change.
    let n = 300;
    let base = [("h_min", 1e-4), ("h_max", 1e-4), ("tolerance", 1e-13), ("mu_k[1]", 0.17), ("mu_s[1]", 0.22)];
    let wrt = [("mu_k[1]", 0.17, 1e-5), ("mu_s[1]", 0.22, 1e-4), ("k[1]", 1e6, 1e-5), ("k[3]", 1e6, 1e-6)];
    let names: Vec<&str> = wrt.iter().map(|w| w.0).collect();
    let steps: Vec<f64> = wrt.iter().map(|w| 1e-6 * w.1).collect();
    let (c, _) = configured(&base);
    let (status, _, sens, departures, _) = run_experiment(c, n, &names, &steps, true);
    unsafe { fmi2FreeInstance(c) };
    assert_eq!(status, OK);
    assert_eq!(departures, [0, 0, 0, 0]);
    let no = EXPERIMENT_OUTPUTS.len();
    let p = names.len();
    for (j, &(name, x, tolerance)) in wrt.iter().enumerate() {
        let others: Vec<(&str, f64)> = base.iter().copied().filter(|(b, _)| *b != name).collect();
        let free: Vec<Vec<f64>> =
            [3e-3, 1e-3, 1e-4, 1e-5, 1e-6].iter().map(|&r| free_differences(&others, name, x, n, r)).collect();
        for o in 0..no {
            let column: Vec<f64> = (0..n).map(|k| sens[(k * no + o) * p + j]).collect();
            let scale = column.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(scale > 0.0 && scale.is_finite(), "∂{}/∂{name} = {scale}", EXPERIMENT_OUTPUTS[o]);
            let best = free
                .iter()
                .map(|f| (0..n).map(|k| (f[k * no + o] - column[k]).abs()).fold(0.0f64, f64::max))
                .fold(f64::INFINITY, f64::min);
            assert!(
                best <= tolerance * scale,
                "∂{}/∂{name}: the best free difference is {:e} of the largest value off",
                EXPERIMENT_OUTPUTS[o],
                best / scale
            );
        }
    }
}
