//! What the FMU declares: its variables with their value references, units,
//! log categories, GUID, and the `modelDescription.xml` built from them (and
//! the FMU's `documentation/index.html`, from the same variables).
//!
//! This is the one place that lays out the value references. It is pure data
//! derived from a [`Model`](crate::model::Model): the runtime (`fmi2GetReal` …),
//! the packager (`src/bin/package_fmu.rs`) and `build.rs` all call it. `build.rs`
//! compiles this folder into itself together with `src/model`, `src/error.rs`,
//! `src/math.rs` and `src/stepper/state.rs`, so code here may use only
//! `crate::model`, `crate::error`, `crate::math`, `crate::stepper::State`,
//! `super::…` and the `quick_xml` crate. The FMI 3.0 parts (`arrays`,
//! `writer3`, `fmi3_terms`) are compiled with the feature `fmi3` only.

#[cfg(feature = "fmi3")]
mod arrays;
mod documentation;
#[cfg(feature = "fmi3")]
mod fmi3_terms;
mod hash;
mod joints;
mod outputs;
mod units;
mod variables;
mod writer;
#[cfg(feature = "fmi3")]
mod writer3;

#[cfg(feature = "fmi3")]
pub use arrays::{variables3, Type3, Variable3};
pub use documentation::{documentation_html, drive_colour_index, escape_html, DRIVE_COLOURS};
#[cfg(feature = "fmi3")]
pub use fmi3_terms::in_fmi3_terms;
pub use hash::{fnv1a_64, Fnv1a128};
pub(crate) use joints::joint_units;
pub use outputs::{Arity, Output, OutputKind, OutputUnit, OUTPUTS};
pub use units::{Unit, UNITS};
pub use variables::{
    guid, model_hash, variables, Causality, Initial, InputField, Quantity, Setting, Type, Variability, Variable,
};
pub use writer::model_description_xml;
#[cfg(feature = "fmi3")]
pub use writer3::model_description_fmi3_xml;

/// The modelIdentifier: file name of the shared library in the FMU and of the
/// FMU itself.
pub const MODEL_IDENTIFIER: &str = "StickSlipManipulator";

/// Log categories: (name, description). Messages of the status categories are
/// on by default; `logEvents` follows the `loggingOn` flag; `logAll` (last)
/// names all of them in fmi2SetDebugLogging.
pub const LOG_CATEGORIES: [(&str, &str); 5] = [
    ("logEvents", "Stick-slip transitions of the joints and discarded steps (debug logging)"),
    ("logStatusWarning", "Calls that returned fmi2Warning"),
    ("logStatusDiscard", "Steps that returned fmi2Discard (the state stays at the last good time)"),
    ("logStatusError", "Calls that returned fmi2Error: illegal call sequence, bad arguments, invalid parameters"),
    ("logAll", "All of the above"),
];

/// Default experiment: start, stop and communication step size, s.
pub const DEFAULT_EXPERIMENT: (f64, f64, f64) = (0.0, 2.0, 1e-3);
