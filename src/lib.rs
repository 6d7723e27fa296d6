#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

pub mod algorithms;
pub mod data;
pub mod error;
pub mod fmi;
#[cfg(feature = "fmi3")]
#[doc(hidden)]
pub mod fmi3;
pub mod forces;
pub mod math;
pub mod model;
pub mod motion;
pub mod servo;
pub mod stepper;

pub use data::Data;
pub use error::{ModelError, NonConvergence, StepError};
pub use model::Model;
pub use stepper::{
    DriveInputs, Energy, InitialState, MotorTorques, Phase, PlannedSubStep, RotorStart, Simulator, State,
    StepStatistics,
};
