//! The iterative Newmark stepper with stick–slip switching.

mod inputs;
mod error_control;
mod isa;
mod newmark;
mod simulator;
mod state;
mod switching;

pub use inputs::{DriveInputs, InputPolynomial, MotorTorques, INPUT_RANGES, MOTOR_TORQUE_RANGES};
pub use isa::InstructionSet;
pub use simulator::{InitialState, RotorStart, Simulator, Transition, TRANSITION_LOG_CAPACITY};
pub use state::{Energy, Phase, State, StepStatistics};
