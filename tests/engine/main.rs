//! The engine's integration tests, in one test binary: each file below was a test binary of
//! its own, and each linked the engine and its dependencies again (one binary: the rebuild
//! after an engine change 92 s instead of 105 s, measured). Run one file's tests with its
//! module's name as the filter, e.g. `cargo test --release --test engine parameter_space`.
//!
//! `tests/no_allocation.rs` stays a binary of its own: its counting global allocator would
//! count every other test's allocations.

mod common;

mod communication_steps;
mod contact_loads;
mod damped_contact;
mod dh_placements;
mod energy_conservation;
mod fmi3_crate;
mod fmi_crate;
mod formulations;
mod instruction_sets;
mod inverse_dynamics_friction;
mod joint_reactions;
mod joint_torque_regressor;
mod model_file;
mod model_file_properties;
mod model_writer;
mod motor_drive;
mod motor_inputs;
mod parameter_space;
mod reference_motion;
mod static_friction;
mod step_errors;
mod stick_slip_cycle;
mod urdf_fuzz;
mod urdf_model_file;
mod urdf_reader;
mod urdf_reference_arm;
mod viscous_friction;
