//! The FMI 2.0 co-simulation layer: a thin translation of FMI calls into
//! [`Simulator`](crate::Simulator) calls. It checks every call and owns no
//! physics. Three layers, as in the FMI Reference FMUs:
//!
//! * `exports` — the 34 exported `fmi2…` functions; each names the
//!   life-cycle states that allow it and runs inside `boundary`, which turns
//!   pointers into checked slices and panics into fmi2Error; and the three
//!   functions beyond FMI, [`stickslip_inverse_dynamics`] (the engine's
//!   inverse dynamics for the fit, from the FMU's own library),
//!   [`stickslip_joint_torque_regressor`] (its joint-torque regressor) and
//!   [`stickslip_write_model`] (the model with identified values as a model file),
//!   and [`stickslip_run_experiment`] (a whole experiment, and its
//!   sensitivities, in one call: `experiment`);
//! * `instance` — one instance's life cycle (`lifecycle`), inputs,
//!   parameters and simulator, in safe Rust; FMU states in the byte format of
//!   `snapshot`;
//! * [`description`] — the variables and value references of a model and
//!   the `modelDescription.xml` built from them (shared with `build.rs` and
//!   the `package_fmu` binary), and the FMU's `documentation/index.html`;
//! * [`icon`] — the FMU's `model.png`, a picture of the chain (used by the
//!   `package_fmu` binary).

pub(crate) mod boundary;
pub mod description;
mod experiment;
pub(crate) mod exports;
pub mod icon;
pub(crate) mod instance;
pub(crate) mod lifecycle;
pub(crate) mod logger;
mod snapshot;
pub(crate) mod status;
#[cfg(test)]
mod tests;
pub mod uri;

pub use exports::{
    stickslip_inverse_dynamics, stickslip_joint_torque_regressor, stickslip_run_experiment, stickslip_write_model,
    EXPORTED_FUNCTIONS,
};
