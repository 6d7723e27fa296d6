//! The algorithms of the engine, one per file; each has the shape
//! `algorithm(&model, &mut data, …)` and says where its result lands.

pub mod crba;
pub mod energy;
pub mod inverse_dynamics;
pub mod kinematics;
pub mod lagrange;
pub mod lu;
pub mod regressor;
pub mod rnea;
