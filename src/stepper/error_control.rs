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
//! **The velocity.** The estimate above vanishes where q⃛ does: at the
//! turning points of a drive's vibration, where the joint comes to rest and
//! may stick. The velocity update q̇₁ = q̇₀ + h·((1 − γ)·q̈₀ + γ·q̈₁) has the
//! local error (γ − ½)·h²·q⃛ + (γ/2 − ⅙)·h³·q⁗, h³·q⁗/12 for γ = ½, largest
//! exactly there; q⁗ comes from the second difference of q̈ over this and
//! the previous sub-step. In the energy norm of the drive's vibration a
//! velocity error counts as a position error times 1/ω, ω² = k_i/M_ii, so
//! the error of joint i is the larger of the two. It decides where a joint
//! slows to rest, and so whether and when it sticks: on variants with
//! small clearances and the decreasing characteristic it cuts the deviation
//! from the converged answer by 2.7 to 3.5 times for 1.25 times the
//! sub-steps, where the tolerance would need 1.6 to 1.9 times.
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
//! The tolerance is per second of motion (error per unit step), so that the
//! global error of ε, a sum of local errors over the run, is about
//! tol·w·(run time) whatever the number of sub-steps: a sub-step of length h
//! is accepted when r = max_i |e_i| / (tol·w_i·h / 1 s) ≤ 1.
//!
//! **Control.** The local error grows with h³, the ratio r with h², so the
//! next length is h·0.9·r^(−1/2), limited to [0.2, 2]·h so that the stepper
//! neither oscillates nor collapses, and to [h_min, h_max].

use super::newmark::PreviousSubStep;
use super::state::{Phase, State};
use crate::forces::drive::clearance_margin;
use crate::model::Model;

/// Safety factor on the optimal length.
const SAFETY: f64 = 0.9;
/// Largest growth of the sub-step from one to the next.
pub(crate) const GROWTH_MAX: f64 = 2.0;
/// Largest reduction of the sub-step from one to the next.
pub(crate) const SHRINK_MIN: f64 = 0.2;

/// The local error of the sub-step of length `h` from `start` to `state`,
/// relative to the tolerance: accepted when ≤ 1 (see the module doc).
/// `previous` is the sub-step before, for the velocity error (`None` right
/// after a restart of the solver: then only the position error counts).
#[inline(always)]
pub(crate) fn error_ratio(
    model: &Model,
    start: &State,
    state: &State,
    h: f64,
    previous: Option<PreviousSubStep>,
) -> f64 {
    let s = model.integrator;
    let n = model.nq();
    let coefficient = (s.beta - 1.0 / 6.0).abs() * h * h;
    let (q, q_star, friction) = (&state.q, &state.q_star[..n], &state.friction_force);
    let mut worst: f64 = 0.0;
    let nc = state.n_coordinates();
    let mut rotor = 0;
    for c in 0..nc {
        // A rotor's error is measured on the link side, θ_m/N, against its
        // joint's weight; its "stiffness" is the gear's seen from the rotor.
        let (i, ratio) = if c < n {
            (c, 1.0)
        } else {
            let j = rotor_joint(model, &mut rotor);
            (j, model.joints[j].drive.rotor().map_or(1.0, |r| r.gear_ratio))
        };
        let (Some(spring), Phase::Slipping(_)) = (model.joints[i].drive.spring(), state.phase[c]) else { continue };
        let stiffness = spring.stiffness / (ratio * ratio);
        let change = state.qdd[c] - start.qdd[c];
        let mut error = coefficient * change.abs();
        if let Some(PreviousSubStep { qdd: qdd_before, h: h_before, mass_diagonal }) = previous {
            // q⁗ from the second difference of q̈ over this and the last sub-step.
            let fourth = 2.0 * (change / h - (start.qdd[c] - qdd_before[c]) / h_before) / (h + h_before);
            let velocity_error = (s.gamma - 0.5) * h * change + (0.5 * s.gamma - 1.0 / 6.0) * h * h * h * fourth;
            // In the energy norm of the drive's vibration, a velocity error
            // counts as a position error times 1/ω, ω² = k/M_ii. A motor
            // drive's link and rotor vibrate against each other on the gear
            // (the wind-up θ_m/N − q), at ω² = k·(1/M_jj + 1/(N²·J_m)): both
            // coordinates' velocity errors count at that frequency.
            let period = match model.joints[i].drive.rotor() {
                None => (mass_diagonal[c] / stiffness).sqrt(),
                Some(rotor) => {
                    let link = mass_diagonal[i];
                    let reflected = rotor.gear_ratio * rotor.gear_ratio * mass_diagonal[rotor_coordinate_of(model, i)];
                    (1.0 / (spring.stiffness / link + spring.stiffness / reflected)).sqrt()
                }
            };
            error = error.max(velocity_error.abs() * period);
        }
        let stretch = clearance_margin(spring.clearance, q_star[i] - q[i]).max(0.0);
        // A rotor's friction causes a stretch of N·τ_f/k.
        let weight = stretch + ratio * friction[c].abs() / spring.stiffness + 1e-15 * (1.0 + q[c].abs() / ratio);
        worst = worst.max(error / ratio / (s.error_tolerance * weight * h));
    }
    worst
}

/// The coordinate of the rotor of motor joint `i`: n + the motor joints before it.
#[inline(always)]
fn rotor_coordinate_of(model: &Model, i: usize) -> usize {
    model.nq() + model.joints[..i].iter().filter(|j| j.drive.is_motor()).count()
}

/// The joint of the next rotor coordinate: the `*rotor`-th motor drive,
/// counting on.
#[inline(always)]
fn rotor_joint(model: &Model, rotor: &mut usize) -> usize {
    let j = model.joints.iter().enumerate().filter(|(_, j)| j.drive.is_motor()).nth(*rotor).map_or(0, |(i, _)| i);
    *rotor += 1;
    j
}

/// The factor by which the sub-step that gave error ratio `ratio` should be
/// scaled to meet the tolerance with a safety margin, unlimited above (∞
/// for a zero error) and at least [`SHRINK_MIN`].
#[inline(always)]
pub(crate) fn optimal_factor(ratio: f64) -> f64 {
    (SAFETY / ratio.sqrt()).max(SHRINK_MIN)
}

#[cfg(test)]
mod tests {
    use super::error_ratio;
    use crate::math::{Mat3, Vec3};
    use crate::model::{DhJoint, DhRow, Drive, IntegratorSettings, JointKind, Link, Model};
    use crate::stepper::{DriveInputs, InitialState, Simulator};

    /// A block of mass `mass` on a drive spring `stiffness` along z0, without
    /// friction and gravity: q(t) = A·cos(ωt + φ) about q* = 0, ω² = k/m.
    fn oscillator(mass: f64, stiffness: f64, h: f64) -> Model {
        let model = Model::from_dh(
            "oscillator",
            &[DhJoint {
                kind: JointKind::Prismatic,
                dh: DhRow { theta: 0.0, d: 0.0, a: 0.0, alpha: 0.0 },
                drive: Drive::Flexible { stiffness, damping: 0.0, clearance: 0.0 },
                friction: None,
            }],
            &[Link { mass, com: Vec3::zeros(), inertia: Mat3::from_diagonal(&Vec3::new(0.01, 0.01, 0.01)) }],
            Vec3::zeros(),
            Vec3::zeros(),
            IntegratorSettings { h_min: h, h_max: h, tolerance: 1e-13, ..IntegratorSettings::default() },
        )
        .expect("the model is valid");
        model.validate().expect("oscillator is valid");
        model
    }

    /// The estimate (β − ⅙)·h²·(q̈₁ − q̈₀) behind `error_ratio` is the local
    /// error of one Newmark sub-step: started on the exact solution of the
    /// oscillator, the sub-step ends off the exact q(t₀ + h) by the estimate,
    /// up to the next order (relative 0.3·ωh measured, asserted below 0.5·ωh);
    /// and the ratio divides it by
    /// tol·w·h with w the spring stretch |q* − q|.
    #[test]
    fn estimate_is_the_local_error_of_a_sub_step() {
        let (mass, stiffness, amplitude, phase): (f64, f64, f64, f64) = (10.0, 1e6, 1e-3, 1.0);
        let omega = (stiffness / mass).sqrt();
        let zero = [0.0];
        let inputs = DriveInputs { q_star: &zero, qd_star: &zero, qdd_star: &zero };
        for omega_h in [3e-2, 1e-2, 3e-3, 1e-3] {
            let h = omega_h / omega;
            let model = oscillator(mass, stiffness, h);
            let mut sim = Simulator::new(model.clone()).unwrap();
            let q0 = [amplitude * f64::cos(phase)];
            let qd0 = [-amplitude * omega * f64::sin(phase)];
            sim.initialize(0.0, &inputs, Some(InitialState { q: &q0, qd: &qd0 })).unwrap();
            let start = sim.state().clone();
            sim.advance(&inputs, h).unwrap();
            let end = sim.state();
            assert_eq!(end.steps.accepted, 1);
            let exact = amplitude * f64::cos(phase + omega_h);
            let local_error = end.q[0] - exact;
            let estimate = (model.integrator.beta - 1.0 / 6.0) * h * h * (end.qdd[0] - start.qdd[0]);
            let relative = (estimate - local_error).abs() / local_error.abs();
            eprintln!("ωh = {omega_h:e}: local error {local_error:.6e}, estimate {estimate:.6e}, relative difference {relative:.2e}");
            assert!(relative < 0.5 * omega_h, "ωh = {omega_h}: estimate {estimate} vs local error {local_error}");
            let tol = model.integrator.error_tolerance;
            let weight = end.q[0].abs() + 1e-15 * (1.0 + end.q[0].abs());
            let ratio = error_ratio(&model, &start, end, h, None);
            assert!((ratio * tol * weight * h - estimate.abs()).abs() <= 1e-12 * estimate.abs(), "ratio {ratio}");
        }
    }
}
