//! The iterative Newmark stepper with stick–slip switching.

mod error_control;
mod inputs;
mod integrator;
mod isa;
mod newmark;
mod reported;
mod schedule;
mod simulator;
mod state;
#[cfg(feature = "fmi3")]
mod substep;

pub use inputs::{DriveInputs, InputPolynomial, MotorTorques, INPUT_RANGES, MOTOR_TORQUE_RANGES};
pub use integrator::{Flow, Transition, TRANSITION_LOG_CAPACITY};
pub use isa::InstructionSet;
pub use schedule::PlannedSubStep;
pub use simulator::{InitialState, RotorStart, Simulator};
pub use state::{Energy, Phase, State, StepStatistics};
#[cfg(feature = "fmi3")]
pub(crate) use substep::SubStep;
