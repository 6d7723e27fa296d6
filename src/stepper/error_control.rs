//! Error control of the Newmark sub-steps: the local error estimate of a
//! solved sub-step and the length proposed for the next one.
//!
//! **Estimate.** Newmark's displacement update
//! q₁ = q₀ + h·q̇₀ + h²·((½ − β)·q̈₀ + β·q̈₁) matches the Taylor series
//! q(t₀ + h) = q₀ + h·q̇₀ + ½h²·q̈₀ + ⅙h³·q⃛₀ + O(h⁴) up to the h³ term: with
//! q̈₁ − q̈₀ = h·q⃛₀ + O(h²) it reproduces β·h³·q⃛₀ in place of ⅙h³·q⃛₀, so
//! the local error of q is (β − ⅙)·h²·(q̈₁ − q̈₀) + O(h⁴) (Zienkiewicz and
//! Xie, 1991): h²·Δq̈/12 for the average-acceleration rule β = ¼. Only the
//! slipping joints have it; stuck and prescribed ones follow their inputs.
//!
//! **Weights.** The quantities users read are small differences: the end
//! point error ε is 10⁻⁴ of the coordinates and comes from the drive
//! deflections q* − q. The error of joint i is therefore measured against
//! the stretch of its drive spring, floored by the stretch its friction
//! causes: w_i = max(|q*_i − q_i| − Δ_i, 0) + |F^f_i|/k_i. The clearance Δ_i
//! does not count: a joint sliding freely inside it must still end where
//! friction stops it to the accuracy of an engaged drive's stretch. The
//! friction term keeps the weight from vanishing where the stretch passes
//! through zero during a vibration or inside the clearance.
//! A sub-step is accepted when max_i |e_i| / (tol·w_i) ≤ 1.
//!
//! **Control.** The error grows with h³, so the next length is
//! h·0.9·r^(−1/3) for the ratio r above, limited to [0.2, 2]·h so that the
//! stepper neither oscillates nor collapses, and to [h_min, h_max].

use super::state::{Phase, State};
use crate::forces::drive::clearance_margin;
use crate::model::{Drive, Model};

/// Safety factor on the optimal length.
const SAFETY: f64 = 0.9;
/// Largest growth of the sub-step from one to the next.
pub(crate) const GROWTH_MAX: f64 = 2.0;
/// Largest reduction of the sub-step from one to the next.
pub(crate) const SHRINK_MIN: f64 = 0.2;

/// The local error of the sub-step of length `h` from `start` to `state`,
/// relative to the tolerance: accepted when ≤ 1 (see the module doc).
#[inline(always)]
pub(crate) fn error_ratio(model: &Model, start: &State, state: &State, h: f64) -> f64 {
    let s = model.integrator;
    let n = model.nq();
    let coefficient = (s.beta - 1.0 / 6.0).abs() * h * h;
    let (qdd0, qdd1, q, q_star, friction, phase) =
        (&start.qdd[..n], &state.qdd[..n], &state.q[..n], &state.q_star[..n], &state.friction_force[..n], &state.phase[..n]);
    let mut worst: f64 = 0.0;
    for (i, joint) in model.joints.iter().enumerate().take(n) {
        let (Drive::Flexible { stiffness, clearance, .. }, Phase::Slipping(_)) = (joint.drive, phase[i]) else { continue };
        let error = coefficient * (qdd1[i] - qdd0[i]).abs();
        let stretch = clearance_margin(clearance, q_star[i] - q[i]).max(0.0);
        let weight = stretch + friction[i].abs() / stiffness + 1e-15 * (1.0 + q[i].abs());
        worst = worst.max(error / (s.error_tolerance * weight * h));
    }
    worst
}

/// The factor by which the sub-step that gave error ratio `ratio` should be
/// scaled to meet the tolerance with a safety margin, unlimited above (∞
/// for a zero error) and at least [`SHRINK_MIN`].
#[inline(always)]
pub(crate) fn optimal_factor(ratio: f64) -> f64 {
    (SAFETY / ratio.sqrt()).max(SHRINK_MIN)
}
