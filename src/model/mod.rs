//! The manipulator model: chain, drives, friction, and its model file.

mod file;
mod joint;
mod link;
mod manipulator;
mod parameter;
mod presets;
pub mod urdf;

pub use file::REFERENCE_RRPR_TOML;
pub use joint::{ContactGeometry, DhRow, Drive, FrictionCoefficients, Joint, JointFriction, JointKind};
pub use link::Link;
pub use manipulator::{IntegratorSettings, Model, Range, INPUT_RANGES, MAX_JOINTS};
pub(crate) use manipulator::number;
pub use parameter::Parameter;
