//! The model's inverse dynamics at given states and the loads its friction
//! law reads there: the one home of what the `inverse_dynamics` binary writes
//! and of what the FMU library's `stickslip_inverse_dynamics` export returns
//! to the fit's equation-error stage (python/stickslip/fit/idim.py).
//!
//! With a measured q, q̇, q̈ the loads are the engine's for that state whether
//! the joint slips or sticks: a slipping joint's friction is μ(q̇)·L·sgn q̇ +
//! b·q̇ and its drive force F^d = τ + F^f (3.9), (3.10); a stuck one can be
//! held while |F^d − F*| ≤ μ_s·L (3.16).

use super::kinematics::forward_kinematics;
use super::rnea::{joint_reactions, rnea};
use crate::forces::friction::{friction_loads, FrictionLoads};
use crate::{Data, Model, ModelError};

/// `model` with each of `settings` applied in order
/// ([`Model::apply_setting`], `NAME[i]=VALUE` by FMU name), then validated:
/// the relations between parameters (μ_s ≥ μ_k, …) are checked once all are
/// set, as the FMU checks them.
pub fn with_settings<S: AsRef<str>>(mut model: Model, settings: &[S]) -> Result<Model, ModelError> {
    for setting in settings {
        model.apply_setting(setting.as_ref())?;
    }
    model.validate()?;
    Ok(model)
}

/// Inverse dynamics with joint reactions at `q`, `qd`, `qdd` (each of length
/// n). Results in `data`: `tau` (τ = M(q)·q̈ + bias(q, q̇) including gravity,
/// N·m or N), `force[i]` and `moment[i]` (exerted by link i−1 on link i about
/// the joint's origin, link i's frame) and the reactions at the reaction
/// points, `reaction_force[i]` and `reaction_moment[i]`, which the friction
/// law reads ([`joint_friction_loads`]).
pub fn inverse_dynamics(model: &Model, data: &mut Data, q: &[f64], qd: &[f64], qdd: &[f64]) {
    forward_kinematics(model, data, q);
    rnea(model, data, q, qd, qdd);
    joint_reactions(model, data);
}

/// The loads the friction law of joint `i` (0-based) reads at the state of
/// the last [`inverse_dynamics`] in `data`: the lever load L (N or N·m, the
/// dry friction is μ·L, bearing radii included, (3.11)–(3.15)) and F*
/// (3.17); `None` for a joint without friction.
pub fn joint_friction_loads(model: &Model, data: &Data, i: usize) -> Option<FrictionLoads> {
    let friction = model.joints[i].friction.as_ref()?;
    Some(friction_loads(Some(friction), &data.reaction_force[i], &data.reaction_moment[i], data.tau[i]))
}

/// Row by row over `states`, row-major rows × [q(n), q̇(n), q̈(n)] (n =
/// `model.nq()`, SI units): τ of each joint into `tau` and the lever load L
/// into `lever_load`, both row-major rows × n, NaN in `lever_load` for a
/// joint without friction. `data` must have been built for `model`.
///
/// An error names the first row (1-based) and state that is not finite, or
/// the lengths that do not fit; the outputs are then partly written.
pub fn inverse_dynamics_rows(
    model: &Model,
    data: &mut Data,
    states: &[f64],
    tau: &mut [f64],
    lever_load: &mut [f64],
) -> Result<(), String> {
    let n = model.nq();
    let rows = state_rows(n, states)?;
    for (what, len) in [("tau", tau.len()), ("lever_load", lever_load.len())] {
        if len != rows * n {
            return Err(format!("`{what}` has {len} values, {rows} rows of {n} joints need {}", rows * n));
        }
    }
    for (r, state) in states.chunks_exact(3 * n).enumerate() {
        let (q, qd, qdd) = state_row(n, r, state)?;
        inverse_dynamics(model, data, q, qd, qdd);
        tau[r * n..(r + 1) * n].copy_from_slice(&data.tau);
        for (i, load) in lever_load[r * n..(r + 1) * n].iter_mut().enumerate() {
            *load = joint_friction_loads(model, data, i).map_or(f64::NAN, |l| l.lever_load);
        }
    }
    Ok(())
}

/// The number of rows of `states`, row-major rows × [q(n), q̇(n), q̈(n)], or
/// why its length is not a whole number of them.
pub fn state_rows(n: usize, states: &[f64]) -> Result<usize, String> {
    if states.len() % (3 * n) != 0 {
        return Err(format!("{} state values are not rows of 3n = {} (q, qd, qdd of {n} joints)", states.len(), 3 * n));
    }
    Ok(states.len() / (3 * n))
}

/// A state's q, q̇ and q̈, each of length n.
pub type StateRow<'a> = (&'a [f64], &'a [f64], &'a [f64]);

/// (q, q̇, q̈) of row `r` (0-based) of the states, `state` its 3n values, or
/// the first of them that is not finite, named with its row (1-based).
pub fn state_row(n: usize, r: usize, state: &[f64]) -> Result<StateRow<'_>, String> {
    if let Some(k) = state.iter().position(|x| !x.is_finite()) {
        let name = ["q", "qd", "qdd"][k / n];
        return Err(format!("row {}: {name}[{}] = {} is not finite", r + 1, k % n + 1, state[k]));
    }
    let (q, rates) = state.split_at(n);
    let (qd, qdd) = rates.split_at(n);
    Ok((q, qd, qdd))
}
