//! The library of the FMI 3.0 FMU (`binaries/<platform>/StickSlipManipulator`
//! of `StickSlipManipulator-fmi3.fmu`): every FMI 3.0 function exported under
//! its name, and nothing else. Each is one call into
//! [`stick_slip_manipulator::fmi3::api`], where the work is done; the FMI 2.0
//! library (the crate `stick_slip_manipulator`) exports none of them.
//!
//! The engine's crate is linked as an rlib: its own `fmi2…` exports stay
//! out of this library's export table (`-Wl,--exclude-libs,ALL` in
//! build.rs on Linux; scripts/mingw-link.sh and scripts/darwin-link.sh cut
//! the export lists of the other platforms to this library's FMI version).

// FMI's names for functions and arguments.
#![allow(non_snake_case, clippy::missing_safety_doc, clippy::too_many_arguments)]

use fmi_sys::fmi3::*;
use std::ffi::c_char;
use stick_slip_manipulator::fmi3::api;

/// The names of the exported functions (the library's whole symbol table).
pub const EXPORTED_FUNCTIONS: [&str; 75] = [
    "fmi3GetVersion",
    "fmi3SetDebugLogging",
    "fmi3InstantiateModelExchange",
    "fmi3InstantiateCoSimulation",
    "fmi3InstantiateScheduledExecution",
    "fmi3FreeInstance",
    "fmi3EnterInitializationMode",
    "fmi3ExitInitializationMode",
    "fmi3EnterEventMode",
    "fmi3Terminate",
    "fmi3Reset",
    "fmi3GetFloat32",
    "fmi3GetFloat64",
    "fmi3GetInt8",
    "fmi3GetUInt8",
    "fmi3GetInt16",
    "fmi3GetUInt16",
    "fmi3GetInt32",
    "fmi3GetUInt32",
    "fmi3GetInt64",
    "fmi3GetUInt64",
    "fmi3GetBoolean",
    "fmi3GetString",
    "fmi3GetBinary",
    "fmi3GetClock",
    "fmi3SetFloat32",
    "fmi3SetFloat64",
    "fmi3SetInt8",
    "fmi3SetUInt8",
    "fmi3SetInt16",
    "fmi3SetUInt16",
    "fmi3SetInt32",
    "fmi3SetUInt32",
    "fmi3SetInt64",
    "fmi3SetUInt64",
    "fmi3SetBoolean",
    "fmi3SetString",
    "fmi3SetBinary",
    "fmi3SetClock",
    "fmi3GetNumberOfVariableDependencies",
    "fmi3GetVariableDependencies",
    "fmi3GetFMUState",
    "fmi3SetFMUState",
    "fmi3FreeFMUState",
    "fmi3SerializedFMUStateSize",
    "fmi3SerializeFMUState",
    "fmi3DeserializeFMUState",
    "fmi3GetDirectionalDerivative",
    "fmi3GetAdjointDerivative",
    "fmi3EnterConfigurationMode",
    "fmi3ExitConfigurationMode",
    "fmi3GetIntervalDecimal",
    "fmi3GetIntervalFraction",
    "fmi3GetShiftDecimal",
    "fmi3GetShiftFraction",
    "fmi3SetIntervalDecimal",
    "fmi3SetIntervalFraction",
    "fmi3SetShiftDecimal",
    "fmi3SetShiftFraction",
    "fmi3EvaluateDiscreteStates",
    "fmi3UpdateDiscreteStates",
    "fmi3EnterContinuousTimeMode",
    "fmi3CompletedIntegratorStep",
    "fmi3SetTime",
    "fmi3SetContinuousStates",
    "fmi3GetContinuousStateDerivatives",
    "fmi3GetEventIndicators",
    "fmi3GetContinuousStates",
    "fmi3GetNominalsOfContinuousStates",
    "fmi3GetNumberOfEventIndicators",
    "fmi3GetNumberOfContinuousStates",
    "fmi3EnterStepMode",
    "fmi3GetOutputDerivatives",
    "fmi3DoStep",
    "fmi3ActivateModelPartition",
];

// ---- compile-time check of every signature against fmi-sys -----------------

const _: fmi3GetVersionTYPE = Some(fmi3GetVersion);
const _: fmi3SetDebugLoggingTYPE = Some(fmi3SetDebugLogging);
const _: fmi3InstantiateModelExchangeTYPE = Some(fmi3InstantiateModelExchange);
const _: fmi3InstantiateCoSimulationTYPE = Some(fmi3InstantiateCoSimulation);
const _: fmi3InstantiateScheduledExecutionTYPE = Some(fmi3InstantiateScheduledExecution);
const _: fmi3FreeInstanceTYPE = Some(fmi3FreeInstance);
const _: fmi3EnterInitializationModeTYPE = Some(fmi3EnterInitializationMode);
const _: fmi3ExitInitializationModeTYPE = Some(fmi3ExitInitializationMode);
const _: fmi3EnterEventModeTYPE = Some(fmi3EnterEventMode);
const _: fmi3TerminateTYPE = Some(fmi3Terminate);
const _: fmi3ResetTYPE = Some(fmi3Reset);
const _: fmi3GetFloat32TYPE = Some(fmi3GetFloat32);
const _: fmi3GetFloat64TYPE = Some(fmi3GetFloat64);
const _: fmi3GetInt8TYPE = Some(fmi3GetInt8);
const _: fmi3GetUInt8TYPE = Some(fmi3GetUInt8);
const _: fmi3GetInt16TYPE = Some(fmi3GetInt16);
const _: fmi3GetUInt16TYPE = Some(fmi3GetUInt16);
const _: fmi3GetInt32TYPE = Some(fmi3GetInt32);
const _: fmi3GetUInt32TYPE = Some(fmi3GetUInt32);
const _: fmi3GetInt64TYPE = Some(fmi3GetInt64);
const _: fmi3GetUInt64TYPE = Some(fmi3GetUInt64);
const _: fmi3GetBooleanTYPE = Some(fmi3GetBoolean);
const _: fmi3GetStringTYPE = Some(fmi3GetString);
const _: fmi3GetBinaryTYPE = Some(fmi3GetBinary);
const _: fmi3GetClockTYPE = Some(fmi3GetClock);
const _: fmi3SetFloat32TYPE = Some(fmi3SetFloat32);
const _: fmi3SetFloat64TYPE = Some(fmi3SetFloat64);
const _: fmi3SetInt8TYPE = Some(fmi3SetInt8);
const _: fmi3SetUInt8TYPE = Some(fmi3SetUInt8);
const _: fmi3SetInt16TYPE = Some(fmi3SetInt16);
const _: fmi3SetUInt16TYPE = Some(fmi3SetUInt16);
const _: fmi3SetInt32TYPE = Some(fmi3SetInt32);
const _: fmi3SetUInt32TYPE = Some(fmi3SetUInt32);
const _: fmi3SetInt64TYPE = Some(fmi3SetInt64);
const _: fmi3SetUInt64TYPE = Some(fmi3SetUInt64);
const _: fmi3SetBooleanTYPE = Some(fmi3SetBoolean);
const _: fmi3SetStringTYPE = Some(fmi3SetString);
const _: fmi3SetBinaryTYPE = Some(fmi3SetBinary);
const _: fmi3SetClockTYPE = Some(fmi3SetClock);
const _: fmi3GetNumberOfVariableDependenciesTYPE = Some(fmi3GetNumberOfVariableDependencies);
const _: fmi3GetVariableDependenciesTYPE = Some(fmi3GetVariableDependencies);
const _: fmi3GetFMUStateTYPE = Some(fmi3GetFMUState);
const _: fmi3SetFMUStateTYPE = Some(fmi3SetFMUState);
const _: fmi3FreeFMUStateTYPE = Some(fmi3FreeFMUState);
const _: fmi3SerializedFMUStateSizeTYPE = Some(fmi3SerializedFMUStateSize);
const _: fmi3SerializeFMUStateTYPE = Some(fmi3SerializeFMUState);
const _: fmi3DeserializeFMUStateTYPE = Some(fmi3DeserializeFMUState);
const _: fmi3GetDirectionalDerivativeTYPE = Some(fmi3GetDirectionalDerivative);
const _: fmi3GetAdjointDerivativeTYPE = Some(fmi3GetAdjointDerivative);
const _: fmi3EnterConfigurationModeTYPE = Some(fmi3EnterConfigurationMode);
const _: fmi3ExitConfigurationModeTYPE = Some(fmi3ExitConfigurationMode);
const _: fmi3GetIntervalDecimalTYPE = Some(fmi3GetIntervalDecimal);
const _: fmi3GetIntervalFractionTYPE = Some(fmi3GetIntervalFraction);
const _: fmi3GetShiftDecimalTYPE = Some(fmi3GetShiftDecimal);
const _: fmi3GetShiftFractionTYPE = Some(fmi3GetShiftFraction);
const _: fmi3SetIntervalDecimalTYPE = Some(fmi3SetIntervalDecimal);
const _: fmi3SetIntervalFractionTYPE = Some(fmi3SetIntervalFraction);
const _: fmi3SetShiftDecimalTYPE = Some(fmi3SetShiftDecimal);
const _: fmi3SetShiftFractionTYPE = Some(fmi3SetShiftFraction);
const _: fmi3EvaluateDiscreteStatesTYPE = Some(fmi3EvaluateDiscreteStates);
const _: fmi3UpdateDiscreteStatesTYPE = Some(fmi3UpdateDiscreteStates);
const _: fmi3EnterContinuousTimeModeTYPE = Some(fmi3EnterContinuousTimeMode);
const _: fmi3CompletedIntegratorStepTYPE = Some(fmi3CompletedIntegratorStep);
const _: fmi3SetTimeTYPE = Some(fmi3SetTime);
const _: fmi3SetContinuousStatesTYPE = Some(fmi3SetContinuousStates);
const _: fmi3GetContinuousStateDerivativesTYPE = Some(fmi3GetContinuousStateDerivatives);
const _: fmi3GetEventIndicatorsTYPE = Some(fmi3GetEventIndicators);
const _: fmi3GetContinuousStatesTYPE = Some(fmi3GetContinuousStates);
const _: fmi3GetNominalsOfContinuousStatesTYPE = Some(fmi3GetNominalsOfContinuousStates);
const _: fmi3GetNumberOfEventIndicatorsTYPE = Some(fmi3GetNumberOfEventIndicators);
const _: fmi3GetNumberOfContinuousStatesTYPE = Some(fmi3GetNumberOfContinuousStates);
const _: fmi3EnterStepModeTYPE = Some(fmi3EnterStepMode);
const _: fmi3GetOutputDerivativesTYPE = Some(fmi3GetOutputDerivatives);
const _: fmi3DoStepTYPE = Some(fmi3DoStep);
const _: fmi3ActivateModelPartitionTYPE = Some(fmi3ActivateModelPartition);

// ---- the exports ---------------------------------------------------------------

#[no_mangle]
pub extern "C" fn fmi3GetVersion() -> *const c_char {
    api::fmi3GetVersion()
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetDebugLogging(
    instance: fmi3Instance,
    loggingOn: fmi3Boolean,
    nCategories: usize,
    categories: *const fmi3String,
) -> fmi3Status {
    unsafe { api::fmi3SetDebugLogging(instance, loggingOn, nCategories, categories) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateModelExchange(
    instanceName: fmi3String,
    instantiationToken: fmi3String,
    resourcePath: fmi3String,
    visible: fmi3Boolean,
    loggingOn: fmi3Boolean,
    instanceEnvironment: fmi3InstanceEnvironment,
    logMessage: fmi3LogMessageCallback,
) -> fmi3Instance {
    unsafe {
        api::fmi3InstantiateModelExchange(
            instanceName,
            instantiationToken,
            resourcePath,
            visible,
            loggingOn,
            instanceEnvironment,
            logMessage,
        )
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateCoSimulation(
    instanceName: fmi3String,
    instantiationToken: fmi3String,
    resourcePath: fmi3String,
    visible: fmi3Boolean,
    loggingOn: fmi3Boolean,
    eventModeUsed: fmi3Boolean,
    earlyReturnAllowed: fmi3Boolean,
    requiredIntermediateVariables: *const fmi3ValueReference,
    nRequiredIntermediateVariables: usize,
    instanceEnvironment: fmi3InstanceEnvironment,
    logMessage: fmi3LogMessageCallback,
    intermediateUpdate: fmi3IntermediateUpdateCallback,
) -> fmi3Instance {
    unsafe {
        api::fmi3InstantiateCoSimulation(
            instanceName,
            instantiationToken,
            resourcePath,
            visible,
            loggingOn,
            eventModeUsed,
            earlyReturnAllowed,
            requiredIntermediateVariables,
            nRequiredIntermediateVariables,
            instanceEnvironment,
            logMessage,
            intermediateUpdate,
        )
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateScheduledExecution(
    instanceName: fmi3String,
    instantiationToken: fmi3String,
    resourcePath: fmi3String,
    visible: fmi3Boolean,
    loggingOn: fmi3Boolean,
    instanceEnvironment: fmi3InstanceEnvironment,
    logMessage: fmi3LogMessageCallback,
    clockUpdate: fmi3ClockUpdateCallback,
    lockPreemption: fmi3LockPreemptionCallback,
    unlockPreemption: fmi3UnlockPreemptionCallback,
) -> fmi3Instance {
    unsafe {
        api::fmi3InstantiateScheduledExecution(
            instanceName,
            instantiationToken,
            resourcePath,
            visible,
            loggingOn,
            instanceEnvironment,
            logMessage,
            clockUpdate,
            lockPreemption,
            unlockPreemption,
        )
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3FreeInstance(instance: fmi3Instance) {
    unsafe { api::fmi3FreeInstance(instance) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3EnterInitializationMode(
    instance: fmi3Instance,
    toleranceDefined: fmi3Boolean,
    tolerance: fmi3Float64,
    startTime: fmi3Float64,
    stopTimeDefined: fmi3Boolean,
    stopTime: fmi3Float64,
) -> fmi3Status {
    unsafe {
        api::fmi3EnterInitializationMode(instance, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime)
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3ExitInitializationMode(instance: fmi3Instance) -> fmi3Status {
    unsafe { api::fmi3ExitInitializationMode(instance) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3EnterEventMode(instance: fmi3Instance) -> fmi3Status {
    unsafe { api::fmi3EnterEventMode(instance) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3Terminate(instance: fmi3Instance) -> fmi3Status {
    unsafe { api::fmi3Terminate(instance) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3Reset(instance: fmi3Instance) -> fmi3Status {
    unsafe { api::fmi3Reset(instance) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetFloat32(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *mut fmi3Float32,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3GetFloat32(instance, valueReferences, nValueReferences, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetFloat64(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *mut fmi3Float64,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3GetFloat64(instance, valueReferences, nValueReferences, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetInt8(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *mut fmi3Int8,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3GetInt8(instance, valueReferences, nValueReferences, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetUInt8(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *mut fmi3UInt8,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3GetUInt8(instance, valueReferences, nValueReferences, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetInt16(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *mut fmi3Int16,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3GetInt16(instance, valueReferences, nValueReferences, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetUInt16(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *mut fmi3UInt16,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3GetUInt16(instance, valueReferences, nValueReferences, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetInt32(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *mut fmi3Int32,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3GetInt32(instance, valueReferences, nValueReferences, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetUInt32(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *mut fmi3UInt32,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3GetUInt32(instance, valueReferences, nValueReferences, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetInt64(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *mut fmi3Int64,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3GetInt64(instance, valueReferences, nValueReferences, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetUInt64(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *mut fmi3UInt64,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3GetUInt64(instance, valueReferences, nValueReferences, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetBoolean(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *mut fmi3Boolean,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3GetBoolean(instance, valueReferences, nValueReferences, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetString(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *mut fmi3String,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3GetString(instance, valueReferences, nValueReferences, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetBinary(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    valueSizes: *mut usize,
    values: *mut fmi3Binary,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3GetBinary(instance, valueReferences, nValueReferences, valueSizes, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetClock(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *mut fmi3Clock,
) -> fmi3Status {
    unsafe { api::fmi3GetClock(instance, valueReferences, nValueReferences, values) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetFloat32(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *const fmi3Float32,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3SetFloat32(instance, valueReferences, nValueReferences, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetFloat64(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *const fmi3Float64,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3SetFloat64(instance, valueReferences, nValueReferences, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetInt8(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *const fmi3Int8,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3SetInt8(instance, valueReferences, nValueReferences, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetUInt8(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *const fmi3UInt8,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3SetUInt8(instance, valueReferences, nValueReferences, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetInt16(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *const fmi3Int16,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3SetInt16(instance, valueReferences, nValueReferences, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetUInt16(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *const fmi3UInt16,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3SetUInt16(instance, valueReferences, nValueReferences, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetInt32(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *const fmi3Int32,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3SetInt32(instance, valueReferences, nValueReferences, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetUInt32(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *const fmi3UInt32,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3SetUInt32(instance, valueReferences, nValueReferences, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetInt64(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *const fmi3Int64,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3SetInt64(instance, valueReferences, nValueReferences, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetUInt64(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *const fmi3UInt64,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3SetUInt64(instance, valueReferences, nValueReferences, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetBoolean(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *const fmi3Boolean,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3SetBoolean(instance, valueReferences, nValueReferences, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetString(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *const fmi3String,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3SetString(instance, valueReferences, nValueReferences, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetBinary(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    valueSizes: *const usize,
    values: *const fmi3Binary,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3SetBinary(instance, valueReferences, nValueReferences, valueSizes, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetClock(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *const fmi3Clock,
) -> fmi3Status {
    unsafe { api::fmi3SetClock(instance, valueReferences, nValueReferences, values) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetNumberOfVariableDependencies(
    instance: fmi3Instance,
    valueReference: fmi3ValueReference,
    nDependencies: *mut usize,
) -> fmi3Status {
    unsafe { api::fmi3GetNumberOfVariableDependencies(instance, valueReference, nDependencies) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetVariableDependencies(
    instance: fmi3Instance,
    dependent: fmi3ValueReference,
    elementIndicesOfDependent: *mut usize,
    independents: *mut fmi3ValueReference,
    elementIndicesOfIndependents: *mut usize,
    dependencyKinds: *mut fmi3DependencyKind,
    nDependencies: usize,
) -> fmi3Status {
    unsafe {
        api::fmi3GetVariableDependencies(
            instance,
            dependent,
            elementIndicesOfDependent,
            independents,
            elementIndicesOfIndependents,
            dependencyKinds,
            nDependencies,
        )
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetFMUState(instance: fmi3Instance, FMUState: *mut fmi3FMUState) -> fmi3Status {
    unsafe { api::fmi3GetFMUState(instance, FMUState) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetFMUState(instance: fmi3Instance, FMUState: fmi3FMUState) -> fmi3Status {
    unsafe { api::fmi3SetFMUState(instance, FMUState) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3FreeFMUState(instance: fmi3Instance, FMUState: *mut fmi3FMUState) -> fmi3Status {
    unsafe { api::fmi3FreeFMUState(instance, FMUState) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SerializedFMUStateSize(
    instance: fmi3Instance,
    FMUState: fmi3FMUState,
    size: *mut usize,
) -> fmi3Status {
    unsafe { api::fmi3SerializedFMUStateSize(instance, FMUState, size) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SerializeFMUState(
    instance: fmi3Instance,
    FMUState: fmi3FMUState,
    serializedState: *mut fmi3Byte,
    size: usize,
) -> fmi3Status {
    unsafe { api::fmi3SerializeFMUState(instance, FMUState, serializedState, size) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3DeserializeFMUState(
    instance: fmi3Instance,
    serializedState: *const fmi3Byte,
    size: usize,
    FMUState: *mut fmi3FMUState,
) -> fmi3Status {
    unsafe { api::fmi3DeserializeFMUState(instance, serializedState, size, FMUState) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetDirectionalDerivative(
    instance: fmi3Instance,
    unknowns: *const fmi3ValueReference,
    nUnknowns: usize,
    knowns: *const fmi3ValueReference,
    nKnowns: usize,
    seed: *const fmi3Float64,
    nSeed: usize,
    sensitivity: *mut fmi3Float64,
    nSensitivity: usize,
) -> fmi3Status {
    unsafe {
        api::fmi3GetDirectionalDerivative(
            instance,
            unknowns,
            nUnknowns,
            knowns,
            nKnowns,
            seed,
            nSeed,
            sensitivity,
            nSensitivity,
        )
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetAdjointDerivative(
    instance: fmi3Instance,
    unknowns: *const fmi3ValueReference,
    nUnknowns: usize,
    knowns: *const fmi3ValueReference,
    nKnowns: usize,
    seed: *const fmi3Float64,
    nSeed: usize,
    sensitivity: *mut fmi3Float64,
    nSensitivity: usize,
) -> fmi3Status {
    unsafe {
        api::fmi3GetAdjointDerivative(
            instance,
            unknowns,
            nUnknowns,
            knowns,
            nKnowns,
            seed,
            nSeed,
            sensitivity,
            nSensitivity,
        )
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3EnterConfigurationMode(instance: fmi3Instance) -> fmi3Status {
    unsafe { api::fmi3EnterConfigurationMode(instance) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3ExitConfigurationMode(instance: fmi3Instance) -> fmi3Status {
    unsafe { api::fmi3ExitConfigurationMode(instance) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetIntervalDecimal(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    intervals: *mut fmi3Float64,
    qualifiers: *mut fmi3IntervalQualifier,
) -> fmi3Status {
    unsafe { api::fmi3GetIntervalDecimal(instance, valueReferences, nValueReferences, intervals, qualifiers) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetIntervalFraction(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    counters: *mut fmi3UInt64,
    resolutions: *mut fmi3UInt64,
    qualifiers: *mut fmi3IntervalQualifier,
) -> fmi3Status {
    unsafe {
        api::fmi3GetIntervalFraction(instance, valueReferences, nValueReferences, counters, resolutions, qualifiers)
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetShiftDecimal(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    shifts: *mut fmi3Float64,
) -> fmi3Status {
    unsafe { api::fmi3GetShiftDecimal(instance, valueReferences, nValueReferences, shifts) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetShiftFraction(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    counters: *mut fmi3UInt64,
    resolutions: *mut fmi3UInt64,
) -> fmi3Status {
    unsafe { api::fmi3GetShiftFraction(instance, valueReferences, nValueReferences, counters, resolutions) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetIntervalDecimal(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    intervals: *const fmi3Float64,
) -> fmi3Status {
    unsafe { api::fmi3SetIntervalDecimal(instance, valueReferences, nValueReferences, intervals) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetIntervalFraction(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    counters: *const fmi3UInt64,
    resolutions: *const fmi3UInt64,
) -> fmi3Status {
    unsafe { api::fmi3SetIntervalFraction(instance, valueReferences, nValueReferences, counters, resolutions) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetShiftDecimal(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    shifts: *const fmi3Float64,
) -> fmi3Status {
    unsafe { api::fmi3SetShiftDecimal(instance, valueReferences, nValueReferences, shifts) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetShiftFraction(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    counters: *const fmi3UInt64,
    resolutions: *const fmi3UInt64,
) -> fmi3Status {
    unsafe { api::fmi3SetShiftFraction(instance, valueReferences, nValueReferences, counters, resolutions) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3EvaluateDiscreteStates(instance: fmi3Instance) -> fmi3Status {
    unsafe { api::fmi3EvaluateDiscreteStates(instance) }
}

#[no_mangle]
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
        api::fmi3UpdateDiscreteStates(
            instance,
            discreteStatesNeedUpdate,
            terminateSimulation,
            nominalsOfContinuousStatesChanged,
            valuesOfContinuousStatesChanged,
            nextEventTimeDefined,
            nextEventTime,
        )
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3EnterContinuousTimeMode(instance: fmi3Instance) -> fmi3Status {
    unsafe { api::fmi3EnterContinuousTimeMode(instance) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3CompletedIntegratorStep(
    instance: fmi3Instance,
    noSetFMUStatePriorToCurrentPoint: fmi3Boolean,
    enterEventMode: *mut fmi3Boolean,
    terminateSimulation: *mut fmi3Boolean,
) -> fmi3Status {
    unsafe {
        api::fmi3CompletedIntegratorStep(
            instance,
            noSetFMUStatePriorToCurrentPoint,
            enterEventMode,
            terminateSimulation,
        )
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetTime(instance: fmi3Instance, time: fmi3Float64) -> fmi3Status {
    unsafe { api::fmi3SetTime(instance, time) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetContinuousStates(
    instance: fmi3Instance,
    continuousStates: *const fmi3Float64,
    nContinuousStates: usize,
) -> fmi3Status {
    unsafe { api::fmi3SetContinuousStates(instance, continuousStates, nContinuousStates) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetContinuousStateDerivatives(
    instance: fmi3Instance,
    derivatives: *mut fmi3Float64,
    nContinuousStates: usize,
) -> fmi3Status {
    unsafe { api::fmi3GetContinuousStateDerivatives(instance, derivatives, nContinuousStates) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetEventIndicators(
    instance: fmi3Instance,
    eventIndicators: *mut fmi3Float64,
    nEventIndicators: usize,
) -> fmi3Status {
    unsafe { api::fmi3GetEventIndicators(instance, eventIndicators, nEventIndicators) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetContinuousStates(
    instance: fmi3Instance,
    continuousStates: *mut fmi3Float64,
    nContinuousStates: usize,
) -> fmi3Status {
    unsafe { api::fmi3GetContinuousStates(instance, continuousStates, nContinuousStates) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetNominalsOfContinuousStates(
    instance: fmi3Instance,
    nominals: *mut fmi3Float64,
    nContinuousStates: usize,
) -> fmi3Status {
    unsafe { api::fmi3GetNominalsOfContinuousStates(instance, nominals, nContinuousStates) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetNumberOfEventIndicators(
    instance: fmi3Instance,
    nEventIndicators: *mut usize,
) -> fmi3Status {
    unsafe { api::fmi3GetNumberOfEventIndicators(instance, nEventIndicators) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetNumberOfContinuousStates(
    instance: fmi3Instance,
    nContinuousStates: *mut usize,
) -> fmi3Status {
    unsafe { api::fmi3GetNumberOfContinuousStates(instance, nContinuousStates) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3EnterStepMode(instance: fmi3Instance) -> fmi3Status {
    unsafe { api::fmi3EnterStepMode(instance) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetOutputDerivatives(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    orders: *const fmi3Int32,
    values: *mut fmi3Float64,
    nValues: usize,
) -> fmi3Status {
    unsafe { api::fmi3GetOutputDerivatives(instance, valueReferences, nValueReferences, orders, values, nValues) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3DoStep(
    instance: fmi3Instance,
    currentCommunicationPoint: fmi3Float64,
    communicationStepSize: fmi3Float64,
    noSetFMUStatePriorToCurrentPoint: fmi3Boolean,
    eventHandlingNeeded: *mut fmi3Boolean,
    terminateSimulation: *mut fmi3Boolean,
    earlyReturn: *mut fmi3Boolean,
    lastSuccessfulTime: *mut fmi3Float64,
) -> fmi3Status {
    unsafe {
        api::fmi3DoStep(
            instance,
            currentCommunicationPoint,
            communicationStepSize,
            noSetFMUStatePriorToCurrentPoint,
            eventHandlingNeeded,
            terminateSimulation,
            earlyReturn,
            lastSuccessfulTime,
        )
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3ActivateModelPartition(
    instance: fmi3Instance,
    clockReference: fmi3ValueReference,
    activationTime: fmi3Float64,
) -> fmi3Status {
    unsafe { api::fmi3ActivateModelPartition(instance, clockReference, activationTime) }
}
