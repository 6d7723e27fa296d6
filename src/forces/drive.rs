//! Driving force of a flexible drive with clearance, eq. (2.1), made
//! unilateral where the clearance is open: the force, its damping part,
//! whether the drive transmits force, and its derivative with respect to the
//! joint's acceleration through the Newmark relations.
//!
//! **Where it differs from the study.** With a clearance Δ > 0 the force of
//! (2.1) is carried by one tooth flank, and a flank can only push. (2.1)
//! switches its damper on with a jump h·δ̇ when the clearance closes and lets
//! it pull while the flanks separate: k·(|e| − Δ) + h·d|e|/dt < 0 with
//! e = q* − q. A tensile contact force has no physical meaning, and worse, it
//! leaves no consistent state: the pull reopens the clearance, where the
//! force vanishes (the Newmark iteration then fails to converge). The
//! contact mechanics of impacts treats the linear spring–damper contact
//! (Kelvin–Voigt) the same way: the force is max(0, k·δ + h·δ̇) in the
//! penetration δ = |e| − Δ, and the bodies separate where it reaches zero,
//! before δ does (Hunt and Crossley 1975, who point out the tensile force of
//! the linear model; Gilardi and Sharf 2002, sec. 3; for gear backlash
//! the dead-zone model of Nordin and Gutman 2002). So here
//!
//! F^d = σ·max(0, k·(|e| − Δ) + h·σ·ė)  for |e| ≥ Δ > 0,  0 for |e| < Δ,
//!
//! which is (2.1) wherever (2.1) pushes. The flank force σ·F of (2.1)
//! ([`DriveForce::flank`]) is continuous in the state, so the release is a
//! kink of F^d, located inside the sub-step like the edges of the clearance
//! (`src/stepper/switching.rs`). Without damping (h = 0) the flank force
//! k·(|e| − Δ) is never negative, and without clearance (Δ = 0) the drive is
//! bilateral (both flanks engaged, or no gear play at all) and may pull: in
//! both cases, every case of the study, the force is (2.1) bit for bit.
//!
//! **The closing of the clearance.** The damper acts from the instant the
//! clearance is taken up, so a damped drive's force jumps by h·δ̇ there. An
//! implicit sub-step that ends just past that instant then has no solution:
//! with the force the end falls back inside the clearance, without it outside
//! (the iteration flips between the two). So over a sub-step that starts
//! with the clearance open the force stays 0 ([`drive_force_over_substep`]);
//! the closing is located as an event and the sub-step after it starts with
//! the drive engaged, the way an event-driven integrator keeps a
//! discontinuous law's mode fixed between events. Without damping the force
//! is continuous there (k·δ from 0) and is evaluated as it is.
//!
//! **Energy.** The spring keeps the energy ½k·(|e| − Δ)² while the flank is
//! released, and the damper is taken to hold it at zero force: its part of
//! F^d is −k·(e − σΔ), so the heat booked for the damper over a sub-step is
//! what the spring loses, and the energy account closes as before.

/// The driving force F^d_i of eq. (2.1) at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriveForce {
    /// F^d = k·δ·(q* − q − σΔ) + h·δ·(q̇* − q̇) while the drive transmits
    /// force, 0 otherwise, N or N·m.
    pub force: f64,
    /// Its damping part h·δ·(q̇* − q̇), N or N·m; while a flank is released,
    /// the part −k·(q* − q − σΔ) that holds the spring at zero force.
    pub damping: f64,
    /// The drive transmits force: δ = 1 (|q* − q| ≥ Δ, the clearance is
    /// taken up) and, with a clearance, the flank pushes.
    pub engaged: bool,
    /// σ·F of (2.1), the force the loaded flank would carry: positive while
    /// it pushes, negative where (2.1) would pull and the flank is released.
    /// +∞ where no release can happen: no clearance or no damping, or the
    /// clearance not taken up.
    pub flank: f64,
}

/// F^d of eq. (2.1) for a drive of stiffness k, damping h and clearance Δ,
/// with δ = 1 when |q* − q| ≥ Δ (the clearance is taken up) and 0 inside it,
/// and σ = sgn(q* − q); with Δ > 0 and h > 0 a flank that (2.1) would make
/// pull is released and the force is 0 (see the module doc).
#[inline(always)]
pub fn drive_force(
    stiffness: f64,
    damping: f64,
    clearance: f64,
    q_star: f64,
    qd_star: f64,
    q: f64,
    qd: f64,
) -> DriveForce {
    let e = q_star - q;
    if !clearance_taken_up(clearance, e) {
        return DriveForce { force: 0.0, damping: 0.0, engaged: false, flank: f64::INFINITY };
    }
    // With Δ = 0 the sign of e is irrelevant: σΔ vanishes.
    let sigma_clearance = if clearance > 0.0 { clearance.copysign(e) } else { 0.0 };
    let spring = stiffness * (e - sigma_clearance);
    let damper = damping * (qd_star - qd);
    let force = spring + damper;
    if clearance > 0.0 && damping != 0.0 {
        // σ·F: e is not zero here, |e| ≥ Δ > 0.
        let flank = if e > 0.0 { force } else { -force };
        if flank < 0.0 {
            return DriveForce { force: 0.0, damping: -spring, engaged: false, flank };
        }
        return DriveForce { force, damping: damper, engaged: true, flank };
    }
    DriveForce { force, damping: damper, engaged: true, flank: f64::INFINITY }
}

/// F^d over a Newmark sub-step that starts with the drive's clearance open
/// (`open_at_start`, a negative clearance margin at its start): 0 for a
/// damped drive until the closing, located as an event, ends the sub-step
/// (see the module doc); [`drive_force`] otherwise.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn drive_force_over_substep(
    stiffness: f64,
    damping: f64,
    clearance: f64,
    open_at_start: bool,
    q_star: f64,
    qd_star: f64,
    q: f64,
    qd: f64,
) -> DriveForce {
    if open_at_start && damping != 0.0 {
        return DriveForce { force: 0.0, damping: 0.0, engaged: false, flank: f64::INFINITY };
    }
    drive_force(stiffness, damping, clearance, q_star, qd_star, q, qd)
}

/// δ of eq. (2.1): true when the drive's deflection `e` = q* − q has taken up
/// the clearance Δ, |e| ≥ Δ.
#[inline(always)]
#[allow(clippy::neg_cmp_op_on_partial_ord)] // "not inside": a NaN deflection must propagate into F^d
pub fn clearance_taken_up(clearance: f64, e: f64) -> bool {
    !(e.abs() < clearance)
}

/// Distance of the deflection e = q* − q from the edges ±Δ of the clearance,
/// |e| − Δ: it changes sign where δ of eq. (2.1) switches. Positive while the
/// clearance is taken up.
#[inline(always)]
pub fn clearance_margin(clearance: f64, e: f64) -> f64 {
    e.abs() - clearance
}

/// −∂F^d/∂q̈ of an engaged drive in a Newmark sub-step of length `h`:
/// q moves by βh²·Δq̈ and q̇ by γh·Δq̈, so the spring and damper of (2.1)
/// resist an increase of q̈ with γh·h_d + βh²·k (0 inside the clearance).
#[inline(always)]
pub fn acceleration_stiffness(stiffness: f64, damping: f64, engaged: bool, h: f64, beta: f64, gamma: f64) -> f64 {
    if engaged {
        gamma * h * damping + beta * h * h * stiffness
    } else {
        0.0
    }
}

/// Elastic energy stored in the drive spring, ½·k·(|q* − q| − Δ)² outside the
/// clearance and 0 inside it.
#[inline]
pub fn spring_energy(stiffness: f64, clearance: f64, q_star: f64, q: f64) -> f64 {
    let stretch = clearance_margin(clearance, q_star - q).max(0.0);
    0.5 * stiffness * stretch * stretch
}
