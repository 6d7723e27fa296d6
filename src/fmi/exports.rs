//! The 34 exported functions of FMI 2.0 (common + co-simulation). Each one
//! names the life-cycle states that allow it and hands checked arguments to
//! [`Instance`]. Beside them four functions beyond FMI, which an FMI master
//! never calls: [`stickslip_inverse_dynamics`], the engine's inverse
//! dynamics for the fit's equation-error stage,
//! [`stickslip_joint_torque_regressor`], its joint-torque regressor and the
//! model's standard inertial parameters, [`stickslip_write_model`], the
//! model with identified values written as a model file, and
//! [`stickslip_run_experiment`], a whole experiment (and its parameter
//! sensitivities) in one call; nothing else is exported from the library.
//!
//! Beyond FMI 2.0, which leaves the slave's behaviour there open,
//! fmi2DoStep, fmi2SetReal, fmi2SetBoolean and fmi2SetRealInputDerivatives
//! are also allowed in the step-failed state: a discarded step leaves the
//! state at the last good communication point, so a master may retry with a
//! smaller step or other inputs.

// FMI's names for arguments and constants.
#![allow(non_snake_case, non_upper_case_globals)]

use super::boundary::{
    catch, free_component, free_state, guard, into_component, into_state, out, slice, slice_mut, state, text,
    with_instance, write_text,
};
use super::description::MODEL_IDENTIFIER;
use super::experiment::{Experiment, Sensitivities};
use super::instance::Instance;
use super::lifecycle::{LifeCycle::*, States};
use super::logger::{Category, Logger};
use super::status::{Fault, Status};
use super::uri::resource_path;
use crate::algorithms::inverse_dynamics::{inverse_dynamics_rows, with_settings};
use crate::algorithms::regressor::{
    joint_torque_regressor_rows, standard_parameters, with_standard_parameters, LINK_PARAMETERS,
};
use crate::model::{model_file, Model, ModelSource};
use crate::Data;
use fmi_sys::fmi2::*;
use std::ffi::{c_char, c_int, CString};

const ANY: States = States::of(&[Instantiated, InitializationMode, StepComplete, StepFailed, Terminated, Error]);
const SET: States = States::of(&[Instantiated, InitializationMode, StepComplete, StepFailed]);
const GET: States = States::of(&[InitializationMode, StepComplete, StepFailed, Terminated, Error]);
const STEPPING: States = States::of(&[StepComplete, StepFailed]);
const STATUS: States = States::of(&[StepComplete, StepFailed, Terminated]);

// ---- compile-time check of every signature against fmi-sys -----------------

const _: fmi2GetTypesPlatformTYPE = Some(fmi2GetTypesPlatform);
const _: fmi2GetVersionTYPE = Some(fmi2GetVersion);
const _: fmi2SetDebugLoggingTYPE = Some(fmi2SetDebugLogging);
const _: fmi2InstantiateTYPE = Some(fmi2Instantiate);
const _: fmi2FreeInstanceTYPE = Some(fmi2FreeInstance);
const _: fmi2SetupExperimentTYPE = Some(fmi2SetupExperiment);
const _: fmi2EnterInitializationModeTYPE = Some(fmi2EnterInitializationMode);
const _: fmi2ExitInitializationModeTYPE = Some(fmi2ExitInitializationMode);
const _: fmi2TerminateTYPE = Some(fmi2Terminate);
const _: fmi2ResetTYPE = Some(fmi2Reset);
const _: fmi2GetRealTYPE = Some(fmi2GetReal);
const _: fmi2GetIntegerTYPE = Some(fmi2GetInteger);
const _: fmi2GetBooleanTYPE = Some(fmi2GetBoolean);
const _: fmi2GetStringTYPE = Some(fmi2GetString);
const _: fmi2SetRealTYPE = Some(fmi2SetReal);
const _: fmi2SetIntegerTYPE = Some(fmi2SetInteger);
const _: fmi2SetBooleanTYPE = Some(fmi2SetBoolean);
const _: fmi2SetStringTYPE = Some(fmi2SetString);
const _: fmi2GetFMUstateTYPE = Some(fmi2GetFMUstate);
const _: fmi2SetFMUstateTYPE = Some(fmi2SetFMUstate);
const _: fmi2FreeFMUstateTYPE = Some(fmi2FreeFMUstate);
const _: fmi2SerializedFMUstateSizeTYPE = Some(fmi2SerializedFMUstateSize);
const _: fmi2SerializeFMUstateTYPE = Some(fmi2SerializeFMUstate);
const _: fmi2DeSerializeFMUstateTYPE = Some(fmi2DeSerializeFMUstate);
const _: fmi2GetDirectionalDerivativeTYPE = Some(fmi2GetDirectionalDerivative);
const _: fmi2SetRealInputDerivativesTYPE = Some(fmi2SetRealInputDerivatives);
const _: fmi2GetRealOutputDerivativesTYPE = Some(fmi2GetRealOutputDerivatives);
const _: fmi2DoStepTYPE = Some(fmi2DoStep);
const _: fmi2CancelStepTYPE = Some(fmi2CancelStep);
const _: fmi2GetStatusTYPE = Some(fmi2GetStatus);
const _: fmi2GetRealStatusTYPE = Some(fmi2GetRealStatus);
const _: fmi2GetIntegerStatusTYPE = Some(fmi2GetIntegerStatus);
const _: fmi2GetBooleanStatusTYPE = Some(fmi2GetBooleanStatus);
const _: fmi2GetStringStatusTYPE = Some(fmi2GetStringStatus);

/// The names of the exported functions (the library's whole symbol table):
/// the 34 of FMI 2.0, then the four beyond it.
pub const EXPORTED_FUNCTIONS: [&str; 38] = [
    "fmi2GetTypesPlatform",
    "fmi2GetVersion",
    "fmi2SetDebugLogging",
    "fmi2Instantiate",
    "fmi2FreeInstance",
    "fmi2SetupExperiment",
    "fmi2EnterInitializationMode",
    "fmi2ExitInitializationMode",
    "fmi2Terminate",
    "fmi2Reset",
    "fmi2GetReal",
    "fmi2GetInteger",
    "fmi2GetBoolean",
    "fmi2GetString",
    "fmi2SetReal",
    "fmi2SetInteger",
    "fmi2SetBoolean",
    "fmi2SetString",
    "fmi2GetFMUstate",
    "fmi2SetFMUstate",
    "fmi2FreeFMUstate",
    "fmi2SerializedFMUstateSize",
    "fmi2SerializeFMUstate",
    "fmi2DeSerializeFMUstate",
    "fmi2GetDirectionalDerivative",
    "fmi2SetRealInputDerivatives",
    "fmi2GetRealOutputDerivatives",
    "fmi2DoStep",
    "fmi2CancelStep",
    "fmi2GetStatus",
    "fmi2GetRealStatus",
    "fmi2GetIntegerStatus",
    "fmi2GetBooleanStatus",
    "fmi2GetStringStatus",
    "stickslip_inverse_dynamics",
    "stickslip_joint_torque_regressor",
    "stickslip_write_model",
    "stickslip_run_experiment",
];

// ---- functions without an instance ------------------------------------------------

/// "default": the standard platform types. Any state.
#[no_mangle]
pub extern "C" fn fmi2GetTypesPlatform() -> *const c_char {
    fmi2TypesPlatform.as_ptr().cast()
}

/// "2.0". Any state.
#[no_mangle]
pub extern "C" fn fmi2GetVersion() -> *const c_char {
    fmi2Version.as_ptr().cast()
}

/// Creates an instance from `resources/model.toml` under
/// `fmuResourceLocation`. Returns NULL, with the reason logged where a logger
/// exists, for: no callbacks or logger, no instance name, a model-exchange
/// request, a wrong GUID, or resources that cannot be read or parsed.
///
/// # Safety
/// Pointers are null or valid as FMI 2.0 specifies.
#[no_mangle]
pub unsafe extern "C" fn fmi2Instantiate(
    instanceName: fmi2String,
    fmuType: fmi2Type,
    fmuGUID: fmi2String,
    fmuResourceLocation: fmi2String,
    functions: *const fmi2CallbackFunctions,
    _visible: fmi2Boolean,
    loggingOn: fmi2Boolean,
) -> fmi2Component {
    // SAFETY: `functions` is null or valid by contract.
    let Some(functions) = (unsafe { functions.as_ref() }) else { return std::ptr::null_mut() };
    if functions.logger.is_none() {
        return std::ptr::null_mut();
    }
    guard(std::ptr::null_mut(), || {
        // SAFETY: the strings are null or valid by contract.
        let name = unsafe { text(instanceName, "instanceName") }.ok().filter(|n| !n.is_empty());
        let logger = Logger::new(
            functions.logger,
            functions.componentEnvironment,
            CString::new(name.unwrap_or("?")).unwrap_or_default(),
            loggingOn != 0,
        );
        let instantiate = || -> Result<Instance, String> {
            name.ok_or("instanceName is NULL or empty")?;
            if fmuType != fmi2Type_fmi2CoSimulation {
                return Err(format!("fmuType = {fmuType}: {MODEL_IDENTIFIER} is a co-simulation FMU only"));
            }
            // SAFETY: null or valid by contract.
            let guid = unsafe { text(fmuGUID, "fmuGUID") }.map_err(|f| f.message)?;
            let location = unsafe { text(fmuResourceLocation, "fmuResourceLocation") }.map_err(|f| f.message)?;
            let resources = resource_path(location)?;
            let file = resources.join("model.toml");
            let model_text = std::fs::read_to_string(&file)
                .map_err(|e| format!("cannot read the model file {}: {e}", file.display()))?;
            let source = ModelSource { urdf: model_urdf(&resources, &model_text)?, toml: model_text };
            let instance = Instance::new(&source, logger.clone()).map_err(|e| format!("{}: {e}", file.display()))?;
            if instance.guid() != guid {
                return Err(format!(
                    "fmuGUID {guid} does not match the FMU's resources (GUID {}): modelDescription.xml and resources/ (model.toml, or the URDF it names) are from different FMUs",
                    instance.guid()
                ));
            }
            Ok(instance)
        };
        match instantiate() {
            Ok(instance) => into_component(instance),
            Err(reason) => {
                logger.log(Status::Error, Category::StatusError, &format!("fmi2Instantiate: {reason}"));
                std::ptr::null_mut()
            }
        }
    })
}

/// The text of the URDF a packaged model file names: a plain file name in
/// `resources/`, as the packaging writes it.
pub(crate) fn model_urdf(resources: &std::path::Path, model_text: &str) -> Result<Option<String>, String> {
    let Some(name) = Model::urdf_reference(model_text) else { return Ok(None) };
    if name.is_empty() || name.contains(['/', '\\']) || name == ".." {
        return Err(format!(
            "resources/model.toml names the URDF `{name}`; a packaged model names a file in resources/"
        ));
    }
    let path = resources.join(&name);
    std::fs::read_to_string(&path).map(Some).map_err(|e| format!("cannot read the URDF {}: {e}", path.display()))
}

/// Frees the instance; NULL is accepted. Any state.
///
/// # Safety
/// `c` is null or from fmi2Instantiate and not used again.
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeInstance(c: fmi2Component) {
    // SAFETY: see the function's contract.
    guard((), || unsafe { free_component(c) })
}

// ---- life cycle ----------------------------------------------------------------

/// Log categories on or off. Any state.
///
/// # Safety
/// Pointers are null or valid as FMI 2.0 specifies (also for all functions below).
#[no_mangle]
pub unsafe extern "C" fn fmi2SetDebugLogging(
    c: fmi2Component,
    loggingOn: fmi2Boolean,
    nCategories: usize,
    categories: *const fmi2String,
) -> fmi2Status {
    unsafe {
        with_instance(c, "fmi2SetDebugLogging", ANY, |inst| {
            let names = slice(categories, nCategories, "categories[]")?
                .iter()
                .map(|p| text(*p, "categories[]"))
                .collect::<Result<Vec<_>, _>>()?;
            inst.set_debug_logging(loggingOn != 0, &names)
        })
    }
}

/// Start and stop time. Instantiated.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2SetupExperiment(
    c: fmi2Component,
    toleranceDefined: fmi2Boolean,
    tolerance: fmi2Real,
    startTime: fmi2Real,
    stopTimeDefined: fmi2Boolean,
    stopTime: fmi2Real,
) -> fmi2Status {
    let stop = (stopTimeDefined != 0).then_some(stopTime);
    let tolerance = (toleranceDefined != 0).then_some(tolerance);
    unsafe {
        with_instance(c, "fmi2SetupExperiment", States::of(&[Instantiated]), |inst| {
            inst.setup_experiment(tolerance, startTime, stop)
        })
    }
}

/// Instantiated.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2EnterInitializationMode(c: fmi2Component) -> fmi2Status {
    unsafe {
        with_instance(
            c,
            "fmi2EnterInitializationMode",
            States::of(&[Instantiated]),
            Instance::enter_initialization_mode,
        )
    }
}

/// Starts the engine. Initialization mode.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2ExitInitializationMode(c: fmi2Component) -> fmi2Status {
    unsafe {
        with_instance(
            c,
            "fmi2ExitInitializationMode",
            States::of(&[InitializationMode]),
            Instance::exit_initialization_mode,
        )
    }
}

/// Step complete, step failed, error.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2Terminate(c: fmi2Component) -> fmi2Status {
    unsafe { with_instance(c, "fmi2Terminate", States::of(&[StepComplete, StepFailed, Error]), Instance::terminate) }
}

/// Back to instantiated with the start values. Any state.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2Reset(c: fmi2Component) -> fmi2Status {
    unsafe { with_instance(c, "fmi2Reset", ANY, Instance::reset) }
}

// ---- getters and setters -------------------------------------------------------------

/// Initialization mode, step complete, step failed, terminated, error.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2GetReal(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2Real,
) -> fmi2Status {
    unsafe {
        with_instance(c, "fmi2GetReal", GET, |inst| {
            inst.get_real(slice(vr, nvr, "vr[]")?, slice_mut(value, nvr, "value[]")?)
        })
    }
}

/// No Integer variables: only nvr = 0 succeeds. States as fmi2GetReal.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2GetInteger(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    _value: *mut fmi2Integer,
) -> fmi2Status {
    unsafe { with_instance(c, "fmi2GetInteger", GET, |inst| inst.no_variables_of("Integer", slice(vr, nvr, "vr[]")?)) }
}

/// States as fmi2GetReal.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2GetBoolean(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2Boolean,
) -> fmi2Status {
    unsafe {
        with_instance(c, "fmi2GetBoolean", GET, |inst| {
            inst.get_boolean(slice(vr, nvr, "vr[]")?, slice_mut(value, nvr, "value[]")?)
        })
    }
}

/// No String variables: only nvr = 0 succeeds. States as fmi2GetReal.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2GetString(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    _value: *mut fmi2String,
) -> fmi2Status {
    unsafe { with_instance(c, "fmi2GetString", GET, |inst| inst.no_variables_of("String", slice(vr, nvr, "vr[]")?)) }
}

/// Inputs and tunable parameters: instantiated, initialization mode, step
/// complete, step failed; fixed parameters before step mode only.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2SetReal(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2Real,
) -> fmi2Status {
    unsafe {
        with_instance(c, "fmi2SetReal", SET, |inst| {
            inst.set_real(slice(vr, nvr, "vr[]")?, slice(value, nvr, "value[]")?)
        })
    }
}

/// No Integer variables: only nvr = 0 succeeds. States as fmi2SetReal.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2SetInteger(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    _value: *const fmi2Integer,
) -> fmi2Status {
    unsafe { with_instance(c, "fmi2SetInteger", SET, |inst| inst.no_variables_of("Integer", slice(vr, nvr, "vr[]")?)) }
}

/// `use_start_values`, before step mode. States as fmi2SetReal.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2SetBoolean(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2Boolean,
) -> fmi2Status {
    unsafe {
        with_instance(c, "fmi2SetBoolean", SET, |inst| {
            inst.set_boolean(slice(vr, nvr, "vr[]")?, slice(value, nvr, "value[]")?)
        })
    }
}

/// No String variables: only nvr = 0 succeeds. States as fmi2SetReal.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2SetString(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    _value: *const fmi2String,
) -> fmi2Status {
    unsafe { with_instance(c, "fmi2SetString", SET, |inst| inst.no_variables_of("String", slice(vr, nvr, "vr[]")?)) }
}

// ---- FMU states -------------------------------------------------------------------------

/// Copies the state; reuses `*FMUstate` if it is not NULL. Any state but error.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2GetFMUstate(c: fmi2Component, FMUstate: *mut fmi2FMUstate) -> fmi2Status {
    let allowed = States::of(&[Instantiated, InitializationMode, StepComplete, StepFailed, Terminated]);
    unsafe {
        with_instance(c, "fmi2GetFMUstate", allowed, |inst| {
            let slot = out(FMUstate, "FMUstate")?;
            let bytes = inst.snapshot();
            if slot.is_null() {
                *slot = into_state(bytes);
            } else {
                state(*slot)?.bytes = bytes;
            }
            Ok(Status::Ok)
        })
    }
}

/// Restores a state of an instance of the same model. Any state.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2SetFMUstate(c: fmi2Component, FMUstate: fmi2FMUstate) -> fmi2Status {
    unsafe { with_instance(c, "fmi2SetFMUstate", ANY, |inst| inst.restore(&state(FMUstate)?.bytes)) }
}

/// Frees a state and sets `*FMUstate` to NULL; NULL is accepted. Any state.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeFMUstate(c: fmi2Component, FMUstate: *mut fmi2FMUstate) -> fmi2Status {
    unsafe {
        with_instance(c, "fmi2FreeFMUstate", ANY, |_| {
            if !FMUstate.is_null() {
                free_state(out(FMUstate, "FMUstate")?)?;
            }
            Ok(Status::Ok)
        })
    }
}

/// Size of the serialized state. Any state.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2SerializedFMUstateSize(
    c: fmi2Component,
    FMUstate: fmi2FMUstate,
    size: *mut usize,
) -> fmi2Status {
    unsafe {
        with_instance(c, "fmi2SerializedFMUstateSize", ANY, |_| {
            *out(size, "size")? = state(FMUstate)?.bytes.len();
            Ok(Status::Ok)
        })
    }
}

/// Writes the serialized state; `size` must be fmi2SerializedFMUstateSize's.
/// Any state.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2SerializeFMUstate(
    c: fmi2Component,
    FMUstate: fmi2FMUstate,
    serializedState: *mut fmi2Byte,
    size: usize,
) -> fmi2Status {
    unsafe {
        with_instance(c, "fmi2SerializeFMUstate", ANY, |_| {
            let bytes = &state(FMUstate)?.bytes;
            if size != bytes.len() {
                return Err(Fault::error(format!("size = {size}, the serialized state has {} bytes", bytes.len())));
            }
            let target = slice_mut(serializedState.cast::<u8>(), size, "serializedState[]")?;
            target.copy_from_slice(bytes);
            Ok(Status::Ok)
        })
    }
}

/// Checks serialized bytes (corrupted, truncated and foreign ones are
/// rejected) and makes a state of them; reuses `*FMUstate` if not NULL.
/// Any state.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
    c: fmi2Component,
    serializedState: *const fmi2Byte,
    size: usize,
    FMUstate: *mut fmi2FMUstate,
) -> fmi2Status {
    unsafe {
        with_instance(c, "fmi2DeSerializeFMUstate", ANY, |inst| {
            let bytes = slice(serializedState.cast::<u8>(), size, "serializedState[]")?;
            let slot = out(FMUstate, "FMUstate")?;
            inst.check_snapshot(bytes)?;
            if slot.is_null() {
                *slot = into_state(bytes.to_vec());
            } else {
                state(*slot)?.bytes = bytes.to_vec();
            }
            Ok(Status::Ok)
        })
    }
}

/// Not provided (providesDirectionalDerivative = false): fmi2Error.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2GetDirectionalDerivative(
    c: fmi2Component,
    _vUnknown_ref: *const fmi2ValueReference,
    _nUnknown: usize,
    _vKnown_ref: *const fmi2ValueReference,
    _nKnown: usize,
    _dvKnown: *const fmi2Real,
    _dvUnknown: *mut fmi2Real,
) -> fmi2Status {
    unsafe {
        with_instance(c, "fmi2GetDirectionalDerivative", GET, |_| {
            Err(Fault::error("directional derivatives are not provided (providesDirectionalDerivative = false)"))
        })
    }
}

// ---- co-simulation ----------------------------------------------------------------------

/// Derivatives of the inputs (orders 1, 2 of `q_star[i]`, 1 of `qd_star[i]`).
/// Instantiated, initialization mode, step complete, step failed.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2SetRealInputDerivatives(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    order: *const fmi2Integer,
    value: *const fmi2Real,
) -> fmi2Status {
    unsafe {
        with_instance(c, "fmi2SetRealInputDerivatives", SET, |inst| {
            inst.set_real_input_derivatives(
                slice(vr, nvr, "vr[]")?,
                slice(order, nvr, "order[]")?,
                slice(value, nvr, "value[]")?,
            )
        })
    }
}

/// Not provided (maxOutputDerivativeOrder = 0): fmi2Error.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealOutputDerivatives(
    c: fmi2Component,
    _vr: *const fmi2ValueReference,
    _nvr: usize,
    _order: *const fmi2Integer,
    _value: *mut fmi2Real,
) -> fmi2Status {
    let allowed = States::of(&[StepComplete, StepFailed, Terminated, Error]);
    unsafe {
        with_instance(c, "fmi2GetRealOutputDerivatives", allowed, |_| {
            Err(Fault::error("output derivatives are not provided (maxOutputDerivativeOrder = 0)"))
        })
    }
}

/// One communication step from `currentCommunicationPoint` (must be the
/// FMU's time) over `communicationStepSize` > 0. Step complete, step failed.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2DoStep(
    c: fmi2Component,
    currentCommunicationPoint: fmi2Real,
    communicationStepSize: fmi2Real,
    _noSetFMUStatePriorToCurrentPoint: fmi2Boolean,
) -> fmi2Status {
    unsafe {
        with_instance(c, "fmi2DoStep", STEPPING, |inst| inst.do_step(currentCommunicationPoint, communicationStepSize))
    }
}

/// Steps are synchronous, so there is nothing to cancel: fmi2Error.
/// Step complete, step failed, terminated.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2CancelStep(c: fmi2Component) -> fmi2Status {
    unsafe {
        with_instance(c, "fmi2CancelStep", STATUS, |_| {
            Err(Fault::error("there is no step to cancel: fmi2DoStep never returns fmi2Pending"))
        })
    }
}

/// A status kind that this FMU has no value for: fmi2Discard, as FMI 2.0
/// prescribes, with the reason.
fn no_status(kind: fmi2StatusKind) -> Fault {
    let what = match kind {
        fmi2StatusKind_fmi2DoStepStatus | fmi2StatusKind_fmi2PendingStatus => {
            "only after fmi2DoStep returned fmi2Pending, which it never does"
        }
        fmi2StatusKind_fmi2LastSuccessfulTime => "with fmi2GetRealStatus",
        fmi2StatusKind_fmi2Terminated => "with fmi2GetBooleanStatus",
        _ => "(unknown status kind)",
    };
    Fault::discard(format!("status kind {kind} is available {what}"))
}

/// Step complete, step failed, terminated.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2GetStatus(c: fmi2Component, s: fmi2StatusKind, _value: *mut fmi2Status) -> fmi2Status {
    unsafe { with_instance(c, "fmi2GetStatus", STATUS, |_| Err(no_status(s))) }
}

/// fmi2LastSuccessfulTime: the time of the last good communication point.
/// Step complete, step failed, terminated.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealStatus(c: fmi2Component, s: fmi2StatusKind, value: *mut fmi2Real) -> fmi2Status {
    unsafe {
        with_instance(c, "fmi2GetRealStatus", STATUS, |inst| {
            if s != fmi2StatusKind_fmi2LastSuccessfulTime {
                return Err(no_status(s));
            }
            *out(value, "value")? = inst.last_successful_time();
            Ok(Status::Ok)
        })
    }
}

/// No integer status kinds. Step complete, step failed, terminated.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2GetIntegerStatus(
    c: fmi2Component,
    s: fmi2StatusKind,
    _value: *mut fmi2Integer,
) -> fmi2Status {
    unsafe { with_instance(c, "fmi2GetIntegerStatus", STATUS, |_| Err(no_status(s))) }
}

/// fmi2Terminated: false, the FMU never asks to end the simulation (a
/// discarded step can be retried). Step complete, step failed, terminated.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2GetBooleanStatus(
    c: fmi2Component,
    s: fmi2StatusKind,
    value: *mut fmi2Boolean,
) -> fmi2Status {
    unsafe {
        with_instance(c, "fmi2GetBooleanStatus", STATUS, |_| {
            if s != fmi2StatusKind_fmi2Terminated {
                return Err(no_status(s));
            }
            *out(value, "value")? = fmi2False as fmi2Boolean;
            Ok(Status::Ok)
        })
    }
}

/// No string status kinds (fmi2PendingStatus needs fmi2Pending). Step
/// complete, step failed, terminated.
///
/// # Safety
/// See [`fmi2SetDebugLogging`].
#[no_mangle]
pub unsafe extern "C" fn fmi2GetStringStatus(
    c: fmi2Component,
    s: fmi2StatusKind,
    _value: *mut fmi2String,
) -> fmi2Status {
    unsafe { with_instance(c, "fmi2GetStringStatus", STATUS, |_| Err(no_status(s))) }
}

// ---- beyond FMI 2.0 ---------------------------------------------------------------------

/// The engine's inverse dynamics and friction loads at given states, from
/// the FMU alone (the fit's equation-error stage, python/stickslip/fit/idim.py,
/// calls it with ctypes; no instance, no FMI state):
///
/// ```c
/// int stickslip_inverse_dynamics(
///     const char *model, const char *urdf,                 /* resources/model.toml, its URDF or NULL */
///     const char *const *settings, size_t n_settings,      /* "m[3]=8.0", ... */
///     const double *states, size_t rows, size_t columns,   /* rows x [q(n), qd(n), qdd(n)], columns = 3n */
///     double *tau, double *lever_load, size_t size,        /* rows x n each, size = rows * n */
///     char *message, size_t message_size);                 /* the reason of an error */
/// ```
///
/// The model is `model`'s text (with `urdf`, the text of the URDF it names)
/// with `settings`, tunable parameters by FMU name as `--set` of the
/// `inverse_dynamics` binary takes them, applied and then validated. Per row
/// of `states` (SI units) and joint it writes the generalized force
/// τ = M(q)·q̈ + bias(q, q̇), gravity included, into `tau` and the lever load L
/// of the joint's friction (the dry friction is μ·L, (3.11)–(3.15)) into
/// `lever_load`, NaN for a joint without friction: the numbers of the binary
/// (both run [`inverse_dynamics_rows`]).
///
/// Returns 0, or 1 with the reason, NUL-terminated and cut to
/// `message_size` bytes, in `message` (an empty string on success): a model
/// that does not parse, an unknown or refused setting, `columns` ≠ 3n,
/// `size` ≠ rows·n, a NULL array that should have values, overlapping
/// outputs, a state that is not finite (its row and name), an internal error.
/// The outputs are then unspecified. With `rows` = 0 the arrays are not
/// looked at.
///
/// # Safety
/// Each pointer is NULL or valid for the length its arguments give: `model`
/// and `urdf` NUL-terminated, `settings[0..n_settings]` NUL-terminated strings,
/// `states[0..rows·columns]`, `tau` and `lever_load` `[0..size]` each, `message[0..message_size]`.
#[no_mangle]
pub unsafe extern "C" fn stickslip_inverse_dynamics(
    model: *const c_char,
    urdf: *const c_char,
    settings: *const *const c_char,
    n_settings: usize,
    states: *const f64,
    rows: usize,
    columns: usize,
    tau: *mut f64,
    lever_load: *mut f64,
    size: usize,
    message: *mut c_char,
    message_size: usize,
) -> c_int {
    let run = || -> Result<(), Fault> {
        // SAFETY: the pointers are null or valid by the function's contract.
        let model = unsafe { model_with_settings(model, urdf, settings, n_settings) }?;
        let n = model.nq();
        let values = state_values(rows, columns, n)?;
        if size != rows * n {
            return Err(Fault::error(format!("size = {size}: {rows} rows of {n} joints need {}", rows * n)));
        }
        let overlap = size > 0 && (tau as usize).abs_diff(lever_load as usize) < size.saturating_mul(size_of::<f64>());
        if overlap {
            return Err(Fault::error("`tau` and `lever_load` overlap"));
        }
        let states = unsafe { slice(states, values, "states[]") }?;
        let tau = unsafe { slice_mut(tau, size, "tau[]") }?;
        let lever_load = unsafe { slice_mut(lever_load, size, "lever_load[]") }?;
        inverse_dynamics_rows(&model, &mut Data::new(&model), states, tau, lever_load).map_err(Fault::error)
    };
    // SAFETY: `message` is null or valid by contract.
    unsafe { finish(run, message, message_size) }
}

/// The engine's joint-torque regressor at given states and the model's
/// standard inertial parameters, from the FMU alone (the fit's
/// python/stickslip/fit/regressor.py calls it with ctypes; no instance, no
/// FMI state):
///
/// ```c
/// int stickslip_joint_torque_regressor(
///     const char *model, const char *urdf,                 /* resources/model.toml, its URDF or NULL */
///     const char *const *settings, size_t n_settings,      /* "m[3]=8.0", ... */
///     const double *states, size_t rows, size_t columns,   /* rows x [q(n), qd(n), qdd(n)], columns = 3n */
///     double *regressor, size_t size,                      /* rows x n x 10n, size = rows * n * 10n */
///     double *parameters, size_t n_parameters,             /* the standard parameters, n_parameters = 10n */
///     char *message, size_t message_size);                 /* the reason of an error */
/// ```
///
/// The model and `settings` as for [`stickslip_inverse_dynamics`]. Per row
/// of `states` (SI units) it writes Y(q, q̇, q̈), row-major n × 10n, such that
/// Y·π is [`stickslip_inverse_dynamics`]'s τ to rounding, and into
/// `parameters` the model's standard parameters π, per link
/// [m, m·c_x, m·c_y, m·c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz] in its link
/// frame, the inertia about the frame's origin
/// ([`crate::algorithms::regressor`] says which frame that is).
///
/// Returns 0, or 1 with the reason, NUL-terminated and cut to
/// `message_size` bytes, in `message` (an empty string on success): a model
/// that does not parse, an unknown or refused setting, `columns` ≠ 3n,
/// `size` ≠ rows·n·10n, `n_parameters` ≠ 10n, a NULL array that should have
/// values, overlapping outputs, a state that is not finite (its row and
/// name), an internal error. The outputs are then unspecified. With `rows` =
/// 0, `states` and `regressor` are not looked at (π alone).
///
/// # Safety
/// Each pointer is NULL or valid for the length its arguments give: `model`
/// and `urdf` NUL-terminated, `settings[0..n_settings]` NUL-terminated strings,
/// `states[0..rows·columns]`, `regressor[0..size]`, `parameters[0..n_parameters]`,
/// `message[0..message_size]`.
#[no_mangle]
pub unsafe extern "C" fn stickslip_joint_torque_regressor(
    model: *const c_char,
    urdf: *const c_char,
    settings: *const *const c_char,
    n_settings: usize,
    states: *const f64,
    rows: usize,
    columns: usize,
    regressor: *mut f64,
    size: usize,
    parameters: *mut f64,
    n_parameters: usize,
    message: *mut c_char,
    message_size: usize,
) -> c_int {
    let run = || -> Result<(), Fault> {
        // SAFETY: the pointers are null or valid by the function's contract.
        let model = unsafe { model_with_settings(model, urdf, settings, n_settings) }?;
        let n = model.nq();
        let values = state_values(rows, columns, n)?;
        let per_row = n * LINK_PARAMETERS * n;
        let need = rows.checked_mul(per_row).ok_or_else(|| Fault::error(format!("{rows} rows are too many")))?;
        if size != need {
            return Err(Fault::error(format!(
                "size = {size}: {rows} rows of {n} x {} need {need}",
                LINK_PARAMETERS * n
            )));
        }
        if n_parameters != LINK_PARAMETERS * n {
            return Err(Fault::error(format!(
                "n_parameters = {n_parameters}: {n} links of {LINK_PARAMETERS} parameters need {}",
                LINK_PARAMETERS * n
            )));
        }
        let (a, b) = (regressor as usize, parameters as usize);
        let f64s = size_of::<f64>();
        let overlap = size > 0 && a < b.saturating_add(n_parameters * f64s) && b < a.saturating_add(size * f64s);
        if overlap {
            return Err(Fault::error("`regressor` and `parameters` overlap"));
        }
        let states = unsafe { slice(states, values, "states[]") }?;
        let regressor = unsafe { slice_mut(regressor, size, "regressor[]") }?;
        let parameters = unsafe { slice_mut(parameters, n_parameters, "parameters[]") }?;
        standard_parameters(&model, parameters);
        joint_torque_regressor_rows(&model, &mut Data::new(&model), states, regressor).map_err(Fault::error)
    };
    // SAFETY: `message` is null or valid by contract.
    unsafe { finish(run, message, message_size) }
}

/// The model with identified values written as a model file, and for a URDF
/// model the URDF it names, from the FMU alone (python/stickslip/identify/model_file.py
/// calls it with ctypes; no instance, no FMI state):
///
/// ```c
/// int stickslip_write_model(
///     const char *model, const char *urdf,                 /* resources/model.toml, its URDF or NULL */
///     const char *const *settings, size_t n_settings,      /* "mu_k[1]=0.03", ... */
///     const double *parameters, size_t n_parameters,       /* the standard parameters (10n), or 0: keep the links */
///     const char *urdf_file_name,                          /* the `urdf = "..."` of the written model file */
///     char *toml, size_t toml_size,                        /* the written model file */
///     char *urdf_out, size_t urdf_size,                    /* the written URDF */
///     size_t *toml_needed, size_t *urdf_needed,            /* the sizes they need, NUL included */
///     char *message, size_t message_size);                 /* the reason of an error */
/// ```
///
/// The model and `settings` as for [`stickslip_inverse_dynamics`]; then,
/// with `n_parameters` = 10n, the links from the standard parameters
/// `parameters` (per link [m, m·c_x, m·c_y, m·c_z, I_xx, I_xy, I_yy, I_xz,
/// I_yz, I_zz] in its link frame, the order and frames of
/// [`stickslip_joint_torque_regressor`]'s π), refused where a link is not
/// physically consistent (with_standard_parameters; the message names the
/// link). It writes the model file [`model_file`] writes from the result,
/// naming its URDF `urdf_file_name` (a URDF model; ignored and may be NULL
/// without a URDF), each NUL-terminated.
///
/// Returns 0 with both texts written and `*toml_needed`, `*urdf_needed` their
/// sizes (NUL included; `*urdf_needed` = 0 and `urdf_out` not looked at
/// without a URDF); 2 when a buffer is too small: nothing written but the
/// two sizes and the message, so that the caller can allocate and call again
/// (a first call with sizes 0 asks for them); or 1 with the reason in
/// `message` (as [`stickslip_inverse_dynamics`]): the model does not parse,
/// a setting is unknown or refused, `n_parameters` is neither 0 nor 10n, a
/// link's parameters are physically impossible, a NULL pointer that should
/// be one, `toml` and `urdf_out` overlap, an internal error.
///
/// # Safety
/// Each pointer is NULL or valid for the length its arguments give: `model`,
/// `urdf` and `urdf_file_name` NUL-terminated, `settings[0..n_settings]`
/// NUL-terminated strings, `parameters[0..n_parameters]`, `toml[0..toml_size]`,
/// `urdf_out[0..urdf_size]`, `toml_needed` and `urdf_needed` one each,
/// `message[0..message_size]`.
#[no_mangle]
pub unsafe extern "C" fn stickslip_write_model(
    model: *const c_char,
    urdf: *const c_char,
    settings: *const *const c_char,
    n_settings: usize,
    parameters: *const f64,
    n_parameters: usize,
    urdf_file_name: *const c_char,
    toml: *mut c_char,
    toml_size: usize,
    urdf_out: *mut c_char,
    urdf_size: usize,
    toml_needed: *mut usize,
    urdf_needed: *mut usize,
    message: *mut c_char,
    message_size: usize,
) -> c_int {
    let mut too_small = false;
    let run = || -> Result<(), Fault> {
        // SAFETY: the pointers are null or valid by the function's contract.
        let source_model = unsafe { model_with_settings(model, urdf, settings, n_settings) }?;
        let toml_needed = unsafe { out(toml_needed, "toml_needed") }?;
        let urdf_needed = unsafe { out(urdf_needed, "urdf_needed") }?;
        let n = source_model.nq();
        let identified = match n_parameters {
            0 => source_model,
            k if k == LINK_PARAMETERS * n => {
                let pi = unsafe { slice(parameters, n_parameters, "parameters[]") }?;
                with_standard_parameters(source_model, pi).map_err(|e| Fault::error(format!("parameters: {e}")))?
            }
            k => {
                return Err(Fault::error(format!(
                    "n_parameters = {k}: 0 (keep the links) or {n} links of {LINK_PARAMETERS} parameters, {}",
                    LINK_PARAMETERS * n
                )))
            }
        };
        // SAFETY: as above.
        let source = ModelSource {
            toml: unsafe { text(model, "model") }?.to_string(),
            urdf: if urdf.is_null() { None } else { Some(unsafe { text(urdf, "urdf") }?.to_string()) },
        };
        let file_name = match &source.urdf {
            Some(_) => unsafe { text(urdf_file_name, "urdf_file_name") }?,
            None => "",
        };
        let written = model_file(&identified, &source, file_name).map_err(|e| Fault::error(format!("{e}")))?;
        *toml_needed = written.toml.len() + 1;
        *urdf_needed = written.urdf.as_ref().map_or(0, |u| u.len() + 1);
        if toml_size < *toml_needed || urdf_size < *urdf_needed {
            too_small = true;
            return Err(Fault::error(format!(
                "toml_size = {toml_size}, urdf_size = {urdf_size}: the model file needs {} bytes and the URDF {} \
                 (NUL included)",
                *toml_needed, *urdf_needed
            )));
        }
        let (a, b) = (toml as usize, urdf_out as usize);
        if *urdf_needed > 0 && a < b.saturating_add(*urdf_needed) && b < a.saturating_add(*toml_needed) {
            return Err(Fault::error("`toml` and `urdf_out` overlap"));
        }
        unsafe { write_text(toml, *toml_needed, &written.toml, "toml") }?;
        if let Some(text) = &written.urdf {
            unsafe { write_text(urdf_out, *urdf_needed, text, "urdf_out") }?;
        }
        Ok(())
    };
    // SAFETY: `message` is null or valid by contract.
    let status = unsafe { finish(run, message, message_size) };
    if too_small {
        2
    } else {
        status
    }
}

/// The model of the exports beyond FMI: `model`'s text (with `urdf`, the
/// text of the URDF it names) with `settings` applied, then validated.
///
/// # Safety
/// As the exports' contract says of these pointers.
unsafe fn model_with_settings(
    model: *const c_char,
    urdf: *const c_char,
    settings: *const *const c_char,
    n_settings: usize,
) -> Result<Model, Fault> {
    // SAFETY: the pointers are null or valid by the caller's contract.
    let toml = unsafe { text(model, "model") }?.to_string();
    let urdf = if urdf.is_null() { None } else { Some(unsafe { text(urdf, "urdf") }?.to_string()) };
    let settings = unsafe { slice(settings, n_settings, "settings[]") }?
        .iter()
        .map(|&s| unsafe { text(s, "settings[]") })
        .collect::<Result<Vec<_>, _>>()?;
    let model = ModelSource { toml, urdf }.model().map_err(|e| Fault::error(format!("the model: {e}")))?;
    with_settings(model, &settings).map_err(|e| Fault::error(format!("settings: {e}")))
}

/// The number of state values of `rows` rows of `columns`, which must be 3n.
fn state_values(rows: usize, columns: usize, n: usize) -> Result<usize, Fault> {
    if columns != 3 * n {
        return Err(Fault::error(format!(
            "a state row has {columns} values, the model's has 3n = {} (q, qd, qdd of {n} joints)",
            3 * n
        )));
    }
    rows.checked_mul(columns).ok_or_else(|| Fault::error(format!("{rows} rows are too many")))
}

/// Runs an export's body, a panic caught; its status (0 or 1), and its
/// reason (empty on success) into `message`.
///
/// # Safety
/// `message` is null or valid for `message_size` bytes.
unsafe fn finish(run: impl FnOnce() -> Result<(), Fault>, message: *mut c_char, message_size: usize) -> c_int {
    let (status, reason) = match catch(run) {
        Ok(()) => (0, String::new()),
        Err(fault) => (1, fault.message),
    };
    // A buffer it cannot use is not written.
    guard((), || {
        let _ = unsafe { write_text(message, message_size, &reason, "message") };
    });
    status
}

/// A whole experiment in one call (`super::experiment`): the FMI sequence a
/// master would make from fmi2EnterInitializationMode on, with the inputs of
/// every communication point given at once and the outputs of every point
/// returned, bit for bit those of the per-point calls; and, with
/// `n_sensitivities` > 0, their sensitivities to Real parameters or start
/// values by internal numerical differentiation.
///
/// ```c
/// fmi2Status stickslip_run_experiment(
///     fmi2Component c,                                  /* instantiated, values set, not initialized */
///     size_t n_points, const double *time,              /* communication points, increasing */
///     size_t n_drive, const fmi2ValueReference *drive_vr, const double *drive,  /* points x n_drive */
///     size_t n_torques, const fmi2ValueReference *torque_vr,
///     const double *torque, const double *torque_rate, const double *torque_accel, /* points x n_torques */
///     size_t n_outputs, const fmi2ValueReference *output_vr, double *outputs,    /* points x n_outputs */
///     size_t n_sensitivities, const fmi2ValueReference *sensitivity_vr,
///     const double *sensitivity_step, fmi2Boolean central, size_t threads,
///     double *sensitivities,                            /* points x n_outputs x n_sensitivities */
///     uint64_t *departures,                             /* per value: 0 where its column is exact */
///     size_t *reached);                                 /* points whose outputs were written */
/// ```
///
/// Allowed in the instantiated state (after fmi2SetupExperiment and the
/// values: the experiment starts with initialization) and in step complete
/// (it goes on from the FMU's time, which must be `time[0]`; no
/// sensitivities then). It leaves the instance where the last step left it
/// (step complete, step failed, or initialization mode when initialization
/// failed), for more steps, fmi2Terminate, fmi2Reset or fmi2FreeInstance. A failure
/// returns the status of the FMI call that failed, with its message logged,
/// and the points before it written. Boolean outputs come as 0 or 1.
///
/// # Safety
/// Pointers are null (with a zero count) or point to the counts of values
/// given; `c` as for every FMI function.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn stickslip_run_experiment(
    c: fmi2Component,
    n_points: usize,
    time: *const f64,
    n_drive: usize,
    drive_vr: *const fmi2ValueReference,
    drive: *const f64,
    n_torques: usize,
    torque_vr: *const fmi2ValueReference,
    torque: *const f64,
    torque_rate: *const f64,
    torque_accel: *const f64,
    n_outputs: usize,
    output_vr: *const fmi2ValueReference,
    outputs: *mut f64,
    n_sensitivities: usize,
    sensitivity_vr: *const fmi2ValueReference,
    sensitivity_step: *const f64,
    central: fmi2Boolean,
    threads: usize,
    sensitivities: *mut f64,
    departures: *mut u64,
    reached: *mut usize,
) -> fmi2Status {
    const STARTS_OR_GOES_ON: States = States::of(&[Instantiated, StepComplete]);
    unsafe {
        with_instance(c, "stickslip_run_experiment", STARTS_OR_GOES_ON, |inst| {
            let count = |a: usize, b: usize, what: &str| {
                a.checked_mul(b).ok_or_else(|| Fault::error(format!("{what}: {a} x {b} values overflow")))
            };
            let torques = count(n_points, n_torques, "torque")?;
            let e = Experiment {
                time: slice(time, n_points, "time[]")?,
                drive_vrs: slice(drive_vr, n_drive, "drive_vr[]")?,
                drive: slice(drive, count(n_points, n_drive, "drive")?, "drive[]")?,
                torque_vrs: slice(torque_vr, n_torques, "torque_vr[]")?,
                torques: [
                    slice(torque, torques, "torque[]")?,
                    slice(torque_rate, torques, "torque_rate[]")?,
                    slice(torque_accel, torques, "torque_accel[]")?,
                ],
                output_vrs: slice(output_vr, n_outputs, "output_vr[]")?,
            };
            let size = count(n_points, n_outputs, "outputs")?;
            let values = slice_mut(outputs, size, "outputs[]")?;
            let reached = out(reached, "reached")?;
            let s = if n_sensitivities == 0 {
                None
            } else {
                Some(Sensitivities {
                    vrs: slice(sensitivity_vr, n_sensitivities, "sensitivity_vr[]")?,
                    steps: slice(sensitivity_step, n_sensitivities, "sensitivity_step[]")?,
                    central: central != 0,
                    threads,
                    out: slice_mut(sensitivities, count(size, n_sensitivities, "sensitivities")?, "sensitivities[]")?,
                    departures: slice_mut(departures, n_sensitivities, "departures[]")?,
                })
            };
            inst.run_experiment(&e, values, reached, s)
        })
    }
}
