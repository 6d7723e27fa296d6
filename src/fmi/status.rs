//! Call results of the FMI layer, before they become `fmi2Status`.

use fmi_sys::fmi2::{
    fmi2Status, fmi2Status_fmi2Discard, fmi2Status_fmi2Error, fmi2Status_fmi2OK, fmi2Status_fmi2Warning,
};

/// The status of a call. fmi2Pending never happens (steps are synchronous),
/// nor does fmi2Fatal: after an internal failure an instance can still be
/// reset, restored or freed, so it reports fmi2Error.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Status {
    Ok,
    Warning,
    Discard,
    Error,
}

impl Status {
    pub(crate) fn to_fmi(self) -> fmi2Status {
        match self {
            Status::Ok => fmi2Status_fmi2OK,
            Status::Warning => fmi2Status_fmi2Warning,
            Status::Discard => fmi2Status_fmi2Discard,
            Status::Error => fmi2Status_fmi2Error,
        }
    }
}

/// A call that did not succeed: its status and the message for the logger
/// (the boundary prefixes the function name).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Fault {
    pub(crate) status: Status,
    pub(crate) message: String,
}

impl Fault {
    /// An fmi2Error.
    pub(crate) fn error(message: impl Into<String>) -> Fault {
        Fault { status: Status::Error, message: message.into() }
    }

    /// An fmi2Discard.
    pub(crate) fn discard(message: impl Into<String>) -> Fault {
        Fault { status: Status::Discard, message: message.into() }
    }
}

/// What the body of an exported function returns.
pub(crate) type Outcome = Result<Status, Fault>;
