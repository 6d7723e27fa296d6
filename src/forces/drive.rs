//! Driving force of a flexible drive with clearance, eq. (2.1).

/// Driving force or moment F^d_i of eq. (2.1):
/// F^d = k·δ·(q* − q − σΔ) + h·δ·(q̇* − q̇), with δ = 1 when |q* − q| ≥ Δ
/// (the clearance is taken up) and 0 inside it, and σ = sgn(q* − q).
#[inline(always)]
pub fn drive_force(stiffness: f64, damping: f64, clearance: f64, q_star: f64, qd_star: f64, q: f64, qd: f64) -> f64 {
    let e = q_star - q;
    if e.abs() < clearance {
        return 0.0;
    }
    // With Δ = 0 the sign of e is irrelevant: σΔ vanishes.
    let sigma_clearance = if clearance > 0.0 { clearance.copysign(e) } else { 0.0 };
    stiffness * (e - sigma_clearance) + damping * (qd_star - qd)
}

/// Elastic energy stored in the drive spring, ½·k·(|q* − q| − Δ)² outside the
/// clearance and 0 inside it.
#[inline]
pub fn spring_energy(stiffness: f64, clearance: f64, q_star: f64, q: f64) -> f64 {
    let stretch = ((q_star - q).abs() - clearance).max(0.0);
    0.5 * stiffness * stretch * stretch
}
