//! The reported quantities of a state that stepping does not need: the
//! energies, the joint reactions in the frames the user described the links
//! in, and the end points (of the chain and of its rigid counterpart).

use super::integrator::Integrator;
use super::state::State;
use crate::algorithms::energy::{kinetic_energy, potential_energy};
use crate::algorithms::kinematics::{end_point, forget_joint_transforms, forward_kinematics};
use crate::algorithms::rnea::joint_reactions;
use crate::data::Data;
use crate::forces::drive::spring_energy;
use crate::model::Model;

/// Recomputes the reported quantities of `core`'s state (see
/// [`Simulator::update_reported`]); `scratch` is a joint vector.
pub(super) fn update_reported(core: &mut Integrator, scratch: &mut [f64]) {
    report(&core.model, &mut core.data, &mut core.state, core.solver.rotors(), scratch);
}

/// The reported quantities of `st` (energies, joint reactions, end points),
/// with `data` evaluated at `st`.
pub(super) fn report(model: &Model, data: &mut Data, st: &mut State, rotors: &[usize], scratch: &mut [f64]) {
    update_energies_of(model, data, st, rotors);
    joint_reactions(model, data);
    // Reported in the frame the user described each link in (URDF: the
    // child link frame); the identity for Denavit–Hartenberg joints.
    for (i, joint) in model.joints.iter().enumerate() {
        st.reaction_force[i] = joint.reported_axes * data.reaction_force[i];
        st.reaction_moment[i] = joint.reported_axes * data.reaction_moment[i];
    }
    st.end_point = end_point(model, data);
    // q̂: q* for flexible joints, the prescribed q for rigid ones (= q*).
    scratch.copy_from_slice(&st.q_star);
    forward_kinematics(model, data, scratch);
    // The next interval starts from the library's sines of its own q.
    forget_joint_transforms(data);
    st.end_point_rigid = end_point(model, data);
}

/// Kinetic, gravity and spring energy of `core`'s state; leaves the
/// frame-0 kinematics of the current coordinates in the workspace.
pub(super) fn update_energies(core: &mut Integrator) {
    update_energies_of(&core.model, &mut core.data, &mut core.state, core.solver.rotors());
}

pub(super) fn update_energies_of(model: &Model, data: &mut Data, st: &mut State, rotors: &[usize]) {
    let n = model.nq();
    forward_kinematics(model, data, &st.q[..n]);
    st.energy.kinetic = kinetic_energy(model, data, &st.qd[..n]);
    st.energy.potential = potential_energy(model, data);
    st.energy.spring = model
        .joints
        .iter()
        .enumerate()
        .map(|(i, j)| j.drive.spring().map_or(0.0, |s| spring_energy(s.stiffness, s.clearance, st.q_star[i], st.q[i])))
        .sum();
    st.energy.rotor_kinetic = rotors
        .iter()
        .enumerate()
        .filter_map(|(r, &j)| {
            model.joints[j].drive.rotor().map(|rotor| 0.5 * rotor.inertia * st.qd[n + r] * st.qd[n + r])
        })
        .sum();
}
