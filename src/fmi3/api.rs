//! Every FMI 3.0 function, with FMI's names and C signatures. The crate
//! `fmi3/` exports each under its name (the FMI 3.0 FMU's library); here
//! they are plain functions, so that the FMI 2.0 library exports none of
//! them. Each names the modes that allow it and hands checked arguments to
//! [`Instance3`]. Model Exchange, Scheduled Execution, clocks and
//! configuration mode are not provided: their functions return fmi3Error
//! with a log message (or NULL, for the instantiation functions).

// FMI's names for functions, arguments and constants.
#![allow(non_snake_case, clippy::missing_safety_doc, clippy::too_many_arguments)]

use super::boundary::{free_instance, into_instance, with_instance, with_values};
use super::instance::{Instance3, Mode::*, Modes};
use crate::fmi::boundary::{free_state, guard, into_state, out, slice, slice_mut, state, text};
use crate::fmi::description::{Type3, MODEL_IDENTIFIER};
use crate::fmi::exports::model_urdf;
use crate::fmi::instance::Instance;
use crate::fmi::logger::{Category, Logger};
use crate::fmi::status::{Fault, Status};
use crate::model::ModelSource;
use fmi_sys::fmi3::*;
use std::ffi::c_char;
use std::path::PathBuf;

const ANY: Modes = Modes::of(&[Instantiated, InitializationMode, EventMode, StepMode, Terminated, Error]);
const SET: Modes = Modes::of(&[Instantiated, InitializationMode, EventMode, StepMode]);
const GET: Modes = Modes::of(&[InitializationMode, EventMode, StepMode, Terminated, Error]);

/// "3.0". Any state.
pub extern "C" fn fmi3GetVersion() -> *const c_char {
    fmi3Version.as_ptr().cast()
}

pub unsafe extern "C" fn fmi3SetDebugLogging(
    instance: fmi3Instance,
    loggingOn: fmi3Boolean,
    nCategories: usize,
    categories: *const fmi3String,
) -> fmi3Status {
    unsafe {
        with_instance(instance, "fmi3SetDebugLogging", ANY, |inst, _| {
            let names = slice(categories, nCategories, "categories[]")?
                .iter()
                .map(|p| text(*p, "categories[]"))
                .collect::<Result<Vec<_>, _>>()?;
            inst.inner.set_debug_logging(loggingOn, &names)
        })
    }
}

/// Not provided: this is a co-simulation FMU. Returns NULL, with the reason logged.
pub unsafe extern "C" fn fmi3InstantiateModelExchange(
    _instanceName: fmi3String,
    _instantiationToken: fmi3String,
    _resourcePath: fmi3String,
    _visible: fmi3Boolean,
    _loggingOn: fmi3Boolean,
    instanceEnvironment: fmi3InstanceEnvironment,
    logMessage: fmi3LogMessageCallback,
) -> fmi3Instance {
    refuse_instantiation(instanceEnvironment, logMessage, "fmi3InstantiateModelExchange")
}

/// Not provided: this is a co-simulation FMU. Returns NULL, with the reason logged.
pub unsafe extern "C" fn fmi3InstantiateScheduledExecution(
    _instanceName: fmi3String,
    _instantiationToken: fmi3String,
    _resourcePath: fmi3String,
    _visible: fmi3Boolean,
    _loggingOn: fmi3Boolean,
    instanceEnvironment: fmi3InstanceEnvironment,
    logMessage: fmi3LogMessageCallback,
    _clockUpdate: fmi3ClockUpdateCallback,
    _lockPreemption: fmi3LockPreemptionCallback,
    _unlockPreemption: fmi3UnlockPreemptionCallback,
) -> fmi3Instance {
    refuse_instantiation(instanceEnvironment, logMessage, "fmi3InstantiateScheduledExecution")
}

fn refuse_instantiation(
    environment: fmi3InstanceEnvironment,
    log: fmi3LogMessageCallback,
    function: &str,
) -> fmi3Instance {
    guard(std::ptr::null_mut(), || {
        Logger::fmi3(log, environment, false).log(
            Status::Error,
            Category::StatusError,
            &format!("{function}: {MODEL_IDENTIFIER} is a co-simulation FMU only (fmi3InstantiateCoSimulation)"),
        );
        std::ptr::null_mut()
    })
}

/// Creates an instance from `model.toml` in `resourcePath` (a directory
/// path, FMI 3.0). Returns NULL, with the reason logged, for: no instance
/// name, no or a wrong instantiation token, no resources, or resources that
/// cannot be read or parsed. `requiredIntermediateVariables` may name any
/// outputs and drive inputs: all of them are available in the callback.
pub unsafe extern "C" fn fmi3InstantiateCoSimulation(
    instanceName: fmi3String,
    instantiationToken: fmi3String,
    resourcePath: fmi3String,
    _visible: fmi3Boolean,
    loggingOn: fmi3Boolean,
    eventModeUsed: fmi3Boolean,
    earlyReturnAllowed: fmi3Boolean,
    _requiredIntermediateVariables: *const fmi3ValueReference,
    _nRequiredIntermediateVariables: usize,
    instanceEnvironment: fmi3InstanceEnvironment,
    logMessage: fmi3LogMessageCallback,
    intermediateUpdate: fmi3IntermediateUpdateCallback,
) -> fmi3Instance {
    guard(std::ptr::null_mut(), || {
        let logger = Logger::fmi3(logMessage, instanceEnvironment, loggingOn);
        let instantiate = || -> Result<Instance3, String> {
            unsafe { text(instanceName, "instanceName") }
                .ok()
                .filter(|n| !n.is_empty())
                .ok_or("instanceName is NULL or empty")?;
            let token = unsafe { text(instantiationToken, "instantiationToken") }.map_err(|f| f.message)?;
            let location = unsafe { text(resourcePath, "resourcePath") }
                .map_err(|f| format!("{}: the FMU needs its resources (model.toml)", f.message))?;
            let resources = PathBuf::from(location);
            let file = resources.join("model.toml");
            let model_text = std::fs::read_to_string(&file)
                .map_err(|e| format!("cannot read the model file {}: {e}", file.display()))?;
            let source = ModelSource { urdf: model_urdf(&resources, &model_text)?, toml: model_text };
            let inner = Instance::new(&source, logger.clone()).map_err(|e| format!("{}: {e}", file.display()))?;
            if inner.guid() != token {
                return Err(format!(
                    "instantiationToken {token} does not match the FMU's resources (token {}): modelDescription.xml \
                     and resources/ (model.toml, or the URDF it names) are from different FMUs",
                    inner.guid()
                ));
            }
            Ok(Instance3::new(inner, eventModeUsed, earlyReturnAllowed, intermediateUpdate, instanceEnvironment))
        };
        match instantiate() {
            Ok(instance) => into_instance(instance),
            Err(reason) => {
                logger.log(Status::Error, Category::StatusError, &format!("fmi3InstantiateCoSimulation: {reason}"));
                std::ptr::null_mut()
            }
        }
    })
}

pub unsafe extern "C" fn fmi3FreeInstance(instance: fmi3Instance) {
    guard((), || unsafe { free_instance(instance) })
}

pub unsafe extern "C" fn fmi3EnterInitializationMode(
    instance: fmi3Instance,
    toleranceDefined: fmi3Boolean,
    tolerance: fmi3Float64,
    startTime: fmi3Float64,
    stopTimeDefined: fmi3Boolean,
    stopTime: fmi3Float64,
) -> fmi3Status {
    let tolerance = toleranceDefined.then_some(tolerance);
    let stop = stopTimeDefined.then_some(stopTime);
    unsafe {
        with_instance(instance, "fmi3EnterInitializationMode", Modes::of(&[Instantiated]), |inst, _| {
            inst.enter_initialization_mode(tolerance, startTime, stop)
        })
    }
}

pub unsafe extern "C" fn fmi3ExitInitializationMode(instance: fmi3Instance) -> fmi3Status {
    unsafe {
        with_instance(instance, "fmi3ExitInitializationMode", Modes::of(&[InitializationMode]), |inst, _| {
            inst.exit_initialization_mode()
        })
    }
}

pub unsafe extern "C" fn fmi3EnterEventMode(instance: fmi3Instance) -> fmi3Status {
    unsafe { with_instance(instance, "fmi3EnterEventMode", Modes::of(&[StepMode]), |inst, _| inst.enter_event_mode()) }
}

pub unsafe extern "C" fn fmi3EnterStepMode(instance: fmi3Instance) -> fmi3Status {
    unsafe { with_instance(instance, "fmi3EnterStepMode", Modes::of(&[EventMode]), |inst, _| inst.enter_step_mode()) }
}

/// Event Mode: nothing to update (the stick-slip phases were decided at the
/// event inside the engine); no next time event.
pub unsafe extern "C" fn fmi3UpdateDiscreteStates(
    instance: fmi3Instance,
    discreteStatesNeedUpdate: *mut fmi3Boolean,
    terminateSimulation: *mut fmi3Boolean,
    nominalsOfContinuousStatesChanged: *mut fmi3Boolean,
    valuesOfContinuousStatesChanged: *mut fmi3Boolean,
    nextEventTimeDefined: *mut fmi3Boolean,
    nextEventTime: *mut fmi3Float64,
) -> fmi3Status {
    unsafe {
        with_instance(instance, "fmi3UpdateDiscreteStates", Modes::of(&[EventMode]), |_, _| {
            for (p, what) in [
                (discreteStatesNeedUpdate, "discreteStatesNeedUpdate"),
                (terminateSimulation, "terminateSimulation"),
                (nominalsOfContinuousStatesChanged, "nominalsOfContinuousStatesChanged"),
                (valuesOfContinuousStatesChanged, "valuesOfContinuousStatesChanged"),
                (nextEventTimeDefined, "nextEventTimeDefined"),
            ] {
                *out(p, what)? = false;
            }
            if !nextEventTime.is_null() {
                *out(nextEventTime, "nextEventTime")? = 0.0;
            }
            Ok(Status::Ok)
        })
    }
}

pub unsafe extern "C" fn fmi3Terminate(instance: fmi3Instance) -> fmi3Status {
    unsafe {
        with_instance(instance, "fmi3Terminate", Modes::of(&[EventMode, StepMode, Error]), |inst, _| {
            inst.inner.terminate()
        })
    }
}

pub unsafe extern "C" fn fmi3Reset(instance: fmi3Instance) -> fmi3Status {
    unsafe { with_instance(instance, "fmi3Reset", ANY, |inst, _| inst.reset()) }
}

// ---- getters and setters ---------------------------------------------------------

pub unsafe extern "C" fn fmi3GetFloat64(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *mut fmi3Float64,
    nValues: usize,
) -> fmi3Status {
    unsafe {
        let vrs = || slice(valueReferences, nValueReferences, "valueReferences[]");
        let values = || slice_mut(values, nValues, "values[]");
        with_values(
            instance,
            "fmi3GetFloat64",
            GET,
            |inst, _| inst.get_float64(vrs()?, values()?),
            |frame| frame.get(vrs()?, Type3::Float64, values()?),
        )
    }
}

pub unsafe extern "C" fn fmi3GetInt32(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *mut fmi3Int32,
    nValues: usize,
) -> fmi3Status {
    unsafe {
        let vrs = || slice(valueReferences, nValueReferences, "valueReferences[]");
        let values = || slice_mut(values, nValues, "values[]");
        with_values(
            instance,
            "fmi3GetInt32",
            GET,
            |inst, _| inst.get_int32(vrs()?, values()?),
            |frame| {
                let values = values()?;
                let mut reals = vec![0.0; values.len()];
                let status = frame.get(vrs()?, Type3::Int32, &mut reals)?;
                for (o, x) in values.iter_mut().zip(reals) {
                    *o = x as i32;
                }
                Ok(status)
            },
        )
    }
}

pub unsafe extern "C" fn fmi3GetBoolean(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *mut fmi3Boolean,
    nValues: usize,
) -> fmi3Status {
    unsafe {
        let vrs = || slice(valueReferences, nValueReferences, "valueReferences[]");
        let values = || slice_mut(values, nValues, "values[]");
        with_values(
            instance,
            "fmi3GetBoolean",
            GET,
            |inst, _| inst.get_boolean(vrs()?, values()?),
            |frame| {
                let values = values()?;
                let mut reals = vec![0.0; values.len()];
                let status = frame.get(vrs()?, Type3::Boolean, &mut reals)?;
                for (o, x) in values.iter_mut().zip(reals) {
                    *o = x != 0.0;
                }
                Ok(status)
            },
        )
    }
}

pub unsafe extern "C" fn fmi3SetFloat64(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *const fmi3Float64,
    nValues: usize,
) -> fmi3Status {
    unsafe {
        let vrs = || slice(valueReferences, nValueReferences, "valueReferences[]");
        let values = || slice(values, nValues, "values[]");
        with_values(
            instance,
            "fmi3SetFloat64",
            SET,
            |inst, _| inst.set_float64(vrs()?, values()?),
            |frame| {
                let scalars = frame_scalars(frame);
                frame.set(&scalars, vrs()?, values()?)
            },
        )
    }
}

fn frame_scalars(frame: &super::frame::Frame) -> std::sync::Arc<[crate::fmi::description::Variable]> {
    frame.scalars()
}

pub unsafe extern "C" fn fmi3SetInt32(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *const fmi3Int32,
    nValues: usize,
) -> fmi3Status {
    unsafe {
        let vrs = || slice(valueReferences, nValueReferences, "valueReferences[]");
        let values = || slice(values, nValues, "values[]");
        with_values(
            instance,
            "fmi3SetInt32",
            SET,
            |inst, _| inst.set_int32(vrs()?, values()?),
            |_| Err(Fault::error("only the drive inputs (Float64) can be set in Intermediate Update Mode")),
        )
    }
}

pub unsafe extern "C" fn fmi3SetBoolean(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *const fmi3Boolean,
    nValues: usize,
) -> fmi3Status {
    unsafe {
        let vrs = || slice(valueReferences, nValueReferences, "valueReferences[]");
        let values = || slice(values, nValues, "values[]");
        with_values(
            instance,
            "fmi3SetBoolean",
            SET,
            |inst, _| inst.set_boolean(vrs()?, values()?),
            |_| Err(Fault::error("only the drive inputs (Float64) can be set in Intermediate Update Mode")),
        )
    }
}

/// The getters and setters of the types the FMU has no variables of: fine
/// for no value references, fmi3Error naming the variable's type otherwise.
macro_rules! no_variables {
    ($($name:ident ( $values:ident : $ty:ty ) $kind:literal $allowed:ident;)*) => {$(
        pub unsafe extern "C" fn $name(
            instance: fmi3Instance,
            valueReferences: *const fmi3ValueReference,
            nValueReferences: usize,
            _values: $ty,
            _nValues: usize,
        ) -> fmi3Status {
            unsafe {
                let vrs = || slice(valueReferences, nValueReferences, "valueReferences[]");
                with_values(
                    instance,
                    stringify!($name),
                    $allowed,
                    |inst, _| inst.no_variables_of($kind, vrs()?),
                    |frame| frame.no_variables_of($kind, vrs()?),
                )
            }
        }
    )*};
}

no_variables! {
    fmi3GetFloat32(values: *mut fmi3Float32) "Float32" GET;
    fmi3GetInt8(values: *mut fmi3Int8) "Int8" GET;
    fmi3GetUInt8(values: *mut fmi3UInt8) "UInt8" GET;
    fmi3GetInt16(values: *mut fmi3Int16) "Int16" GET;
    fmi3GetUInt16(values: *mut fmi3UInt16) "UInt16" GET;
    fmi3GetUInt32(values: *mut fmi3UInt32) "UInt32" GET;
    fmi3GetInt64(values: *mut fmi3Int64) "Int64" GET;
    fmi3GetUInt64(values: *mut fmi3UInt64) "UInt64" GET;
    fmi3GetString(values: *mut fmi3String) "String" GET;
    fmi3SetFloat32(values: *const fmi3Float32) "Float32" SET;
    fmi3SetInt8(values: *const fmi3Int8) "Int8" SET;
    fmi3SetUInt8(values: *const fmi3UInt8) "UInt8" SET;
    fmi3SetInt16(values: *const fmi3Int16) "Int16" SET;
    fmi3SetUInt16(values: *const fmi3UInt16) "UInt16" SET;
    fmi3SetUInt32(values: *const fmi3UInt32) "UInt32" SET;
    fmi3SetInt64(values: *const fmi3Int64) "Int64" SET;
    fmi3SetUInt64(values: *const fmi3UInt64) "UInt64" SET;
    fmi3SetString(values: *const fmi3String) "String" SET;
}

pub unsafe extern "C" fn fmi3GetBinary(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    _valueSizes: *mut usize,
    _values: *mut fmi3Binary,
    _nValues: usize,
) -> fmi3Status {
    unsafe {
        let vrs = || slice(valueReferences, nValueReferences, "valueReferences[]");
        with_values(
            instance,
            "fmi3GetBinary",
            GET,
            |inst, _| inst.no_variables_of("Binary", vrs()?),
            |frame| frame.no_variables_of("Binary", vrs()?),
        )
    }
}

pub unsafe extern "C" fn fmi3SetBinary(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    _valueSizes: *const usize,
    _values: *const fmi3Binary,
    _nValues: usize,
) -> fmi3Status {
    unsafe {
        let vrs = || slice(valueReferences, nValueReferences, "valueReferences[]");
        with_values(
            instance,
            "fmi3SetBinary",
            SET,
            |inst, _| inst.no_variables_of("Binary", vrs()?),
            |frame| frame.no_variables_of("Binary", vrs()?),
        )
    }
}

pub unsafe extern "C" fn fmi3GetOutputDerivatives(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    orders: *const fmi3Int32,
    values: *mut fmi3Float64,
    nValues: usize,
) -> fmi3Status {
    unsafe {
        with_instance(instance, "fmi3GetOutputDerivatives", GET, |inst, _| {
            let vrs = slice(valueReferences, nValueReferences, "valueReferences[]")?;
            let orders = slice(orders, nValueReferences, "orders[]")?;
            inst.get_output_derivatives(vrs, orders, slice_mut(values, nValues, "values[]")?)
        })
    }
}

// ---- stepping ------------------------------------------------------------------------

/// One communication step, or less: with `earlyReturnAllowed` it ends at
/// the first stick→slip, slip→stick or clearance event inside the step
/// (`earlyReturn`, `lastSuccessfulTime` = the event's instant, and with
/// `eventModeUsed` `eventHandlingNeeded`), and where the master's
/// intermediate-update callback asks for it.
pub unsafe extern "C" fn fmi3DoStep(
    instance: fmi3Instance,
    currentCommunicationPoint: fmi3Float64,
    communicationStepSize: fmi3Float64,
    _noSetFMUStatePriorToCurrentPoint: fmi3Boolean,
    eventHandlingNeeded: *mut fmi3Boolean,
    terminateSimulation: *mut fmi3Boolean,
    earlyReturn: *mut fmi3Boolean,
    lastSuccessfulTime: *mut fmi3Float64,
) -> fmi3Status {
    unsafe {
        with_instance(instance, "fmi3DoStep", Modes::of(&[StepMode]), |inst, reentry| {
            let event = out(eventHandlingNeeded, "eventHandlingNeeded")?;
            let terminate = out(terminateSimulation, "terminateSimulation")?;
            let early = out(earlyReturn, "earlyReturn")?;
            let last = out(lastSuccessfulTime, "lastSuccessfulTime")?;
            (*event, *terminate, *early) = (false, false, false);
            *last = inst.inner.time();
            let result = inst.do_step(currentCommunicationPoint, communicationStepSize, reentry);
            *last = inst.inner.time();
            let (status, report) = result?;
            (*event, *early, *last) = (report.event_handling_needed, report.early_return, report.last_successful_time);
            Ok(status)
        })
    }
}

// ---- FMU states ------------------------------------------------------------------------

pub unsafe extern "C" fn fmi3GetFMUState(instance: fmi3Instance, FMUState: *mut fmi3FMUState) -> fmi3Status {
    let allowed = Modes::of(&[Instantiated, InitializationMode, EventMode, StepMode, Terminated]);
    unsafe {
        with_instance(instance, "fmi3GetFMUState", allowed, |inst, _| {
            let slot = out(FMUState, "FMUState")?;
            let bytes = inst.inner.snapshot();
            if slot.is_null() {
                *slot = into_state(bytes);
            } else {
                state(*slot)?.bytes = bytes;
            }
            Ok(Status::Ok)
        })
    }
}

pub unsafe extern "C" fn fmi3SetFMUState(instance: fmi3Instance, FMUState: fmi3FMUState) -> fmi3Status {
    unsafe { with_instance(instance, "fmi3SetFMUState", ANY, |inst, _| inst.restore(&state(FMUState)?.bytes)) }
}

pub unsafe extern "C" fn fmi3FreeFMUState(instance: fmi3Instance, FMUState: *mut fmi3FMUState) -> fmi3Status {
    unsafe {
        with_instance(instance, "fmi3FreeFMUState", ANY, |_, _| {
            if !FMUState.is_null() {
                free_state(out(FMUState, "FMUState")?)?;
            }
            Ok(Status::Ok)
        })
    }
}

pub unsafe extern "C" fn fmi3SerializedFMUStateSize(
    instance: fmi3Instance,
    FMUState: fmi3FMUState,
    size: *mut usize,
) -> fmi3Status {
    unsafe {
        with_instance(instance, "fmi3SerializedFMUStateSize", ANY, |_, _| {
            *out(size, "size")? = state(FMUState)?.bytes.len();
            Ok(Status::Ok)
        })
    }
}

pub unsafe extern "C" fn fmi3SerializeFMUState(
    instance: fmi3Instance,
    FMUState: fmi3FMUState,
    serializedState: *mut fmi3Byte,
    size: usize,
) -> fmi3Status {
    unsafe {
        with_instance(instance, "fmi3SerializeFMUState", ANY, |_, _| {
            let bytes = &state(FMUState)?.bytes;
            if size != bytes.len() {
                return Err(Fault::error(format!("size = {size}, the serialized state has {} bytes", bytes.len())));
            }
            slice_mut(serializedState, size, "serializedState[]")?.copy_from_slice(bytes);
            Ok(Status::Ok)
        })
    }
}

/// The bytes are checked (format, version, model, checksum) before a state
/// is made of them.
pub unsafe extern "C" fn fmi3DeserializeFMUState(
    instance: fmi3Instance,
    serializedState: *const fmi3Byte,
    size: usize,
    FMUState: *mut fmi3FMUState,
) -> fmi3Status {
    unsafe {
        with_instance(instance, "fmi3DeserializeFMUState", ANY, |inst, _| {
            let bytes = slice(serializedState, size, "serializedState[]")?;
            inst.inner.check_snapshot(bytes)?;
            let slot = out(FMUState, "FMUState")?;
            if slot.is_null() {
                *slot = into_state(bytes.to_vec());
            } else {
                state(*slot)?.bytes = bytes.to_vec();
            }
            Ok(Status::Ok)
        })
    }
}

// ---- not provided ------------------------------------------------------------------------

/// Functions of capabilities the modelDescription does not declare: each
/// logs why and returns fmi3Error (any mode; never from the callback).
macro_rules! not_provided {
    ($($name:ident ( $($arg:ident : $ty:ty),* ) $why:literal;)*) => {$(
        pub unsafe extern "C" fn $name(instance: fmi3Instance, $(_: $ty),*) -> fmi3Status {
            unsafe { with_instance(instance, stringify!($name), ANY, |_, _| Err(Fault::error($why))) }
        }
    )*};
}

not_provided! {
    fmi3GetNumberOfVariableDependencies(vr: fmi3ValueReference, n: *mut usize)
        "not provided: the modelDescription declares no dependencies (every output may depend on every input)";
    fmi3GetVariableDependencies(dependent: fmi3ValueReference, a: *mut usize, b: *mut fmi3ValueReference, c: *mut usize, d: *mut fmi3DependencyKind, n: usize)
        "not provided: the modelDescription declares no dependencies (every output may depend on every input)";
    fmi3GetDirectionalDerivative(a: *const fmi3ValueReference, b: usize, c: *const fmi3ValueReference, d: usize, e: *const fmi3Float64, f: usize, g: *mut fmi3Float64, h: usize)
        "not provided (providesDirectionalDerivatives is false)";
    fmi3GetAdjointDerivative(a: *const fmi3ValueReference, b: usize, c: *const fmi3ValueReference, d: usize, e: *const fmi3Float64, f: usize, g: *mut fmi3Float64, h: usize)
        "not provided (providesAdjointDerivatives is false)";
    fmi3EnterConfigurationMode() "not provided: the FMU has no structural parameters";
    fmi3ExitConfigurationMode() "not provided: the FMU has no structural parameters";
    fmi3GetClock(a: *const fmi3ValueReference, b: usize, c: *mut fmi3Clock) "not provided: the FMU has no clocks";
    fmi3SetClock(a: *const fmi3ValueReference, b: usize, c: *const fmi3Clock) "not provided: the FMU has no clocks";
    fmi3GetIntervalDecimal(a: *const fmi3ValueReference, b: usize, c: *mut fmi3Float64, d: *mut fmi3IntervalQualifier)
        "not provided: the FMU has no clocks";
    fmi3GetIntervalFraction(a: *const fmi3ValueReference, b: usize, c: *mut fmi3UInt64, d: *mut fmi3UInt64, e: *mut fmi3IntervalQualifier)
        "not provided: the FMU has no clocks";
    fmi3GetShiftDecimal(a: *const fmi3ValueReference, b: usize, c: *mut fmi3Float64) "not provided: the FMU has no clocks";
    fmi3GetShiftFraction(a: *const fmi3ValueReference, b: usize, c: *mut fmi3UInt64, d: *mut fmi3UInt64)
        "not provided: the FMU has no clocks";
    fmi3SetIntervalDecimal(a: *const fmi3ValueReference, b: usize, c: *const fmi3Float64) "not provided: the FMU has no clocks";
    fmi3SetIntervalFraction(a: *const fmi3ValueReference, b: usize, c: *const fmi3UInt64, d: *const fmi3UInt64)
        "not provided: the FMU has no clocks";
    fmi3SetShiftDecimal(a: *const fmi3ValueReference, b: usize, c: *const fmi3Float64) "not provided: the FMU has no clocks";
    fmi3SetShiftFraction(a: *const fmi3ValueReference, b: usize, c: *const fmi3UInt64, d: *const fmi3UInt64)
        "not provided: the FMU has no clocks";
    fmi3EvaluateDiscreteStates() "not provided: Model Exchange and Scheduled Execution only";
    fmi3EnterContinuousTimeMode() "not provided: Model Exchange only (this is a co-simulation FMU)";
    fmi3CompletedIntegratorStep(a: fmi3Boolean, b: *mut fmi3Boolean, c: *mut fmi3Boolean)
        "not provided: Model Exchange only (this is a co-simulation FMU)";
    fmi3SetTime(t: fmi3Float64) "not provided: Model Exchange only (this is a co-simulation FMU)";
    fmi3SetContinuousStates(a: *const fmi3Float64, b: usize) "not provided: Model Exchange only (this is a co-simulation FMU)";
    fmi3GetContinuousStateDerivatives(a: *mut fmi3Float64, b: usize) "not provided: Model Exchange only (this is a co-simulation FMU)";
    fmi3GetEventIndicators(a: *mut fmi3Float64, b: usize) "not provided: Model Exchange only (this is a co-simulation FMU)";
    fmi3GetContinuousStates(a: *mut fmi3Float64, b: usize) "not provided: Model Exchange only (this is a co-simulation FMU)";
    fmi3GetNominalsOfContinuousStates(a: *mut fmi3Float64, b: usize) "not provided: Model Exchange only (this is a co-simulation FMU)";
    fmi3GetNumberOfEventIndicators(a: *mut usize) "not provided: Model Exchange only (this is a co-simulation FMU)";
    fmi3GetNumberOfContinuousStates(a: *mut usize) "not provided: Model Exchange only (this is a co-simulation FMU)";
    fmi3ActivateModelPartition(a: fmi3ValueReference, b: fmi3Float64) "not provided: Scheduled Execution only";
}
