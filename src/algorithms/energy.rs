//! Kinetic and potential energy of the links from the recursive kinematics.

use crate::data::Data;
use crate::model::Model;

/// Kinetic energy T = Σ ½·m_i·|v_ci|² + ½·ω_iᵀ·I_i·ω_i of the links, from the
/// velocities of the last [`rnea`](super::rnea::rnea) call, J.
pub fn kinetic_energy(model: &Model, data: &Data) -> f64 {
    model
        .links
        .iter()
        .enumerate()
        .map(|(i, link)| {
            let w = data.omega[i + 1];
            0.5 * link.mass * data.com_velocity[i].norm_squared() + 0.5 * w.dot(&(data.inertia[i] * w))
        })
        .sum()
}

/// Potential energy of gravity V = −Σ m_i·gᵀ·x_ci, zero at the origin of
/// frame 0, from the last forward kinematics, J.
pub fn potential_energy(model: &Model, data: &Data) -> f64 {
    model
        .links
        .iter()
        .enumerate()
        .map(|(i, link)| -link.mass * model.gravity.dot(&data.com[i]))
        .sum()
}
