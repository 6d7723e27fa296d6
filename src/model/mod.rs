//! The manipulator model: chain, drives, friction, and its model file.

mod dh;
mod file;
mod joint;
mod link;
mod manipulator;
mod parameter;
mod presets;
mod range;
pub mod urdf;
mod urdf_model;
mod writer;

pub use dh::trailing_placement;
pub use file::{with_urdf_file_name, ModelSource, REFERENCE_RRPR_MOTOR_TOML, REFERENCE_RRPR_TOML};
pub use joint::{
    ContactGeometry, DhJoint, DhRow, Drive, DriveSpring, FrictionCoefficients, Joint, JointFriction, JointKind,
    Placement, Rotor,
};
pub use link::Link;
pub use manipulator::{IntegratorSettings, Model, MAX_JOINTS};
pub use parameter::Parameter;
pub use range::{Range, INPUT_RANGES, MOTOR_TORQUE_RANGES};
pub use urdf_model::{axis_alignment, JointExtras, UrdfModelSpec};
pub use writer::{model_file, WrittenModel};
