//! Driving force of a flexible drive with clearance, eq. (2.1): the force,
//! its damping part, whether the clearance is taken up, and its derivative
//! with respect to the joint's acceleration through the Newmark relations.

/// The driving force F^d_i of eq. (2.1) at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriveForce {
    /// F^d = k·δ·(q* − q − σΔ) + h·δ·(q̇* − q̇), N or N·m.
    pub force: f64,
    /// Its damping part h·δ·(q̇* − q̇), N or N·m.
    pub damping: f64,
    /// δ = 1: |q* − q| ≥ Δ, the clearance is taken up and the spring and
    /// damper act; δ = 0 inside the clearance.
    pub engaged: bool,
}

/// F^d of eq. (2.1) for a drive of stiffness k, damping h and clearance Δ,
/// with δ = 1 when |q* − q| ≥ Δ (the clearance is taken up) and 0 inside it,
/// and σ = sgn(q* − q).
#[inline(always)]
pub fn drive_force(stiffness: f64, damping: f64, clearance: f64, q_star: f64, qd_star: f64, q: f64, qd: f64) -> DriveForce {
    let e = q_star - q;
    if !clearance_taken_up(clearance, e) {
        return DriveForce { force: 0.0, damping: 0.0, engaged: false };
    }
    // With Δ = 0 the sign of e is irrelevant: σΔ vanishes.
    let sigma_clearance = if clearance > 0.0 { clearance.copysign(e) } else { 0.0 };
    let damper = damping * (qd_star - qd);
    DriveForce { force: stiffness * (e - sigma_clearance) + damper, damping: damper, engaged: true }
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
