//! Dry friction of revolute and prismatic joints (study sections 3.1, 3.2):
//! the kinetic characteristic μ(v), the normal loads of bearings and sliders
//! (3.11), (3.13)–(3.15), the friction of each phase with its margin to the
//! next phase change (3.16)–(3.18), and the derivatives the Newton iteration
//! needs, next to the laws they differentiate.
//!
//! Beyond the study, a joint may add a viscous part b·q̇ while it moves
//! (lubricated bearings and slideways: friction that grows with speed,
//! independent of the normal load). The kinetic friction of a moving joint
//! is then F^f = μ(q̇)·L·sgn q̇ + b·q̇, (3.12) or (3.13)–(3.14) plus b·q̇;
//! at rest the viscous part is zero, so the static limit (3.16)–(3.18) is
//! the study's. With b = 0 every function here returns the study's value bit
//! for bit.

use crate::math::Vec3;
use crate::model::{ContactGeometry, FrictionCoefficients, JointFriction};

impl FrictionCoefficients {
    /// Kinetic coefficient at sliding velocity `v`:
    /// μ(v) = μ_k + (μ_s − μ_k)·exp(−|v|/v_s) (the decreasing characteristic of
    /// the study's Fig. 2), or μ_k when v_s = 0.
    #[inline]
    pub fn kinetic(&self, v: f64) -> f64 {
        if self.stribeck_velocity > 0.0 {
            self.mu_kinetic + (self.mu_static - self.mu_kinetic) * (-v.abs() / self.stribeck_velocity).exp()
        } else {
            self.mu_kinetic
        }
    }

    /// The dry part `coulomb` of a moving joint's friction plus its viscous
    /// part b·`v`; `coulomb` itself, bit for bit (the sign of a zero
    /// included), when b = 0.
    #[inline(always)]
    pub fn with_viscous(&self, coulomb: f64, v: f64) -> f64 {
        if self.viscous == 0.0 {
            coulomb
        } else {
            coulomb + self.viscous * v
        }
    }

    /// dμ/dv of [`FrictionCoefficients::kinetic`] at sliding velocity `v`.
    #[inline]
    pub fn kinetic_slope(&self, v: f64) -> f64 {
        if self.stribeck_velocity > 0.0 && v != 0.0 {
            -(self.mu_static - self.mu_kinetic) / self.stribeck_velocity
                * (-v.abs() / self.stribeck_velocity).exp()
                * v.signum()
        } else {
            0.0
        }
    }
}

/// True if the joint has static friction that can hold it (μ_s > 0): only
/// such a joint can enter a stiction phase.
#[inline(always)]
pub fn holds_statically(friction: Option<&JointFriction>) -> bool {
    friction.is_some_and(|f| f.coefficients.mu_static > 0.0)
}

/// Friction of a joint in its current phase, signed so that F^d − F^f is
/// its generalized force (3.10), and how far the joint is from its next
/// phase change: the phase holds while `margin` ≥ 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhaseFriction {
    /// F^f, N or N·m.
    pub force: f64,
    /// Distance to the next phase change (see the constructors).
    pub margin: f64,
}

/// A stuck joint (3.16)–(3.18): static friction holds it with
/// F^f = F^d − F*, where F* (3.17) is the axial reaction with the joint
/// held; the margin is the static reserve F̄^f − |F^d − F*|, with
/// F̄^f = μ_s·`lever_load` (3.12) or (3.14) with the static coefficient.
/// A viscous part b·q̇ is zero at rest and does not enter.
#[inline(always)]
pub fn stuck_friction(
    coefficients: Option<FrictionCoefficients>,
    lever_load: f64,
    drive_force: f64,
    axial_reaction: f64,
) -> PhaseFriction {
    let static_limit = coefficients.map_or(0.0, |c| c.mu_static) * lever_load;
    let held = drive_force - axial_reaction;
    PhaseFriction { force: held, margin: static_limit - held.abs() }
}

/// A joint slipping in direction `direction` (±1): kinetic friction
/// μ(q̇)·L·d opposes it, (3.12), (3.14), plus the viscous part b·q̇. The
/// margin is d·q̇ for a joint that static friction can hold (it may stick
/// where its velocity reaches zero), +∞ for one that cannot.
#[inline(always)]
pub fn slip_friction(friction: Option<&JointFriction>, lever_load: f64, qd: f64, direction: i8) -> PhaseFriction {
    let d = direction as f64;
    // (3.12), (3.14): μ(q̇)·L·d.
    let coulomb = friction.map_or(0.0, |f| f.coefficients.kinetic(qd)) * lever_load * d;
    let force = friction.map_or(coulomb, |f| f.coefficients.with_viscous(coulomb, qd));
    let margin = if holds_statically(friction) { d * qd } else { f64::INFINITY };
    PhaseFriction { force, margin }
}

/// Friction a rigid drive overcomes while its joint moves:
/// μ(q̇)·L·sgn q̇ + b·q̇.
#[inline(always)]
pub fn prescribed_friction(coefficients: Option<FrictionCoefficients>, lever_load: f64, qd: f64) -> f64 {
    coefficients.map_or(0.0, |c| c.with_viscous(c.kinetic(qd) * lever_load * sign(qd), qd))
}

/// ∂F^f/∂q̇ of [`slip_friction`] at a fixed lever load: d·L·μ'(q̇) + b. In a
/// Newmark sub-step q̇ moves by γh per unit of q̈.
#[inline(always)]
pub fn slip_friction_velocity_slope(
    coefficients: FrictionCoefficients,
    lever_load: f64,
    qd: f64,
    direction: i8,
) -> f64 {
    let dry = direction as f64 * lever_load * coefficients.kinetic_slope(qd);
    // ∂(b·q̇)/∂q̇ = b: the viscous part at unit velocity.
    coefficients.with_viscous(dry, 1.0)
}

/// Derivative of the kinetic friction μ(q̇)·L·d of a slipping joint
/// (`direction` d) through its lever load L (friction per unit coefficient,
/// here `lever_load` under the joint force `f` and moment `n`) along the
/// change (`df`, `dn`) of that reaction, at fixed q̇ (the viscous part b·q̇
/// does not depend on the load). A one-sided difference of
/// [`contact_load`] with a step of 1e-7 of the reaction's size: the loads are
/// sums of absolute values and norms, one-sided at their kinks.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn slip_friction_load_derivative(
    friction: &JointFriction,
    lever_load: f64,
    qd: f64,
    direction: i8,
    f: &Vec3,
    n: &Vec3,
    df: &Vec3,
    dn: &Vec3,
) -> f64 {
    let mu = friction.coefficients.kinetic(qd);
    if mu == 0.0 {
        return 0.0;
    }
    let size = f.norm() + n.norm();
    let step = 1e-7 * size.max(1e-9) / (df.norm() + dn.norm()).max(1e-300);
    let shifted = contact_load(&friction.geometry, &(f + df * step), &(n + dn * step)).lever_load;
    direction as f64 * mu * (shifted - lever_load) / step
}

#[inline(always)]
fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// What the friction law of a joint reads from the joint's reaction: its
/// contact loads and the axial reaction F*. The stepper takes them from
/// here, and so does `inverse_dynamics` for measured states.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FrictionLoads {
    /// Total normal load, N: [`ContactLoad::normal`]; 0 without friction.
    pub normal: f64,
    /// Lever load L, N or N·m: the dry friction is μ·L
    /// ([`ContactLoad::lever_load`]); 0 without friction.
    pub lever_load: f64,
    /// F* of (3.17), N or N·m: the reaction's component along the joint axis,
    /// f'_z of a slider, n_z of a pin. It is the generalized force τ the
    /// joint transmits (the inverse dynamics resolves the reaction in the
    /// joint frame, z along the axis), and a stuck joint's friction is
    /// F^d − F* (3.16).
    pub axial: f64,
}

/// [`FrictionLoads`] of a joint with `friction` under the joint force `f`
/// and moment `n` (reaction reference point, joint frame: z along the axis)
/// whose generalized force is `tau`, all from one inverse-dynamics pass at
/// the joint's q, q̇, q̈.
#[inline(always)]
pub fn friction_loads(friction: Option<&JointFriction>, f: &Vec3, n: &Vec3, tau: f64) -> FrictionLoads {
    let (normal, lever_load) = match friction {
        Some(friction) => {
            let load = contact_load(&friction.geometry, f, n);
            (load.normal, load.lever_load)
        }
        None => (0.0, 0.0),
    };
    // (3.17): F* = f'_z or n_z, which the inverse dynamics gives as τ.
    FrictionLoads { normal, lever_load, axial: tau }
}

/// Contact loads of a joint computed from its reaction.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ContactLoad {
    /// Total normal load: N_s of eq. (3.11) for a slider; R_A + R_B + |f_z|
    /// for bearings, N.
    pub normal: f64,
    /// Friction force or moment per unit friction coefficient: N_s for a
    /// slider (3.12); R_A·d_A/2 + R_B·d_B/2 + ⅔·|f_z|·d_C/2 for bearings
    /// (3.13), (3.14). Friction = μ·`lever_load`, N or N·m.
    pub lever_load: f64,
}

/// Normal loads of the contact `geometry` under the joint force `f` and
/// moment `n` (reaction reference point, joint frame: z along the axis).
#[inline(always)]
pub fn contact_load(geometry: &ContactGeometry, f: &Vec3, n: &Vec3) -> ContactLoad {
    match *geometry {
        ContactGeometry::Bearings { l_a, l_b, d_a, d_b, d_c, .. } => {
            let (r_a, r_b) = bearing_loads(l_a, l_b, f, n);
            let thrust = f.z.abs();
            ContactLoad {
                normal: r_a + r_b + thrust,
                lever_load: r_a * 0.5 * d_a + r_b * 0.5 * d_b + 2.0 / 3.0 * thrust * 0.5 * d_c,
            }
        }
        ContactGeometry::Slider { a, b, c, .. } => {
            let n_s = slider_normal_load(a, b, c, f, n);
            ContactLoad { normal: n_s, lever_load: n_s }
        }
    }
}

/// Radial loads R_A (bearing A, l_A below the reference point) and R_B
/// (bearing B, l_B above it) of eq. (3.15).
#[inline(always)]
pub fn bearing_loads(l_a: f64, l_b: f64, f: &Vec3, n: &Vec3) -> (f64, f64) {
    let l = l_a + l_b;
    // Loads are far from overflow: a plain root is exact enough and cheaper than hypot.
    let norm = |x: f64, y: f64| (x * x + y * y).sqrt();
    let r_a = norm(l_b * f.x - n.y, l_b * f.y + n.x) / l;
    let r_b = norm(l_a * f.x + n.y, l_a * f.y - n.x) / l;
    (r_a, r_b)
}

/// Total normal load N_s on a slider of length `a` and cross-section
/// `b` × `c` touching its slideway at the eight corner points, eq. (3.11),
/// from the force f' and moment n' at the slider centre.
#[inline(always)]
pub fn slider_normal_load(a: f64, b: f64, c: f64, f: &Vec3, n: &Vec3) -> f64 {
    let n_fx = 0.25 * f.x;
    let n_fy = 0.25 * f.y;
    let n_nx = 0.5 * n.x / a;
    let n_ny = 0.5 * n.y / a;
    let bc = b * b + c * c;
    let n_nz_x = 0.5 * n.z * c / bc;
    let n_nz_y = 0.5 * n.z * b / bc;
    (n_fy + n_nx + n_nz_y).abs()
        + (n_fy + n_nx - n_nz_y).abs()
        + (n_fy - n_nx + n_nz_y).abs()
        + (n_fy - n_nx - n_nz_y).abs()
        + (n_fx - n_ny + n_nz_x).abs()
        + (n_fx - n_ny - n_nz_x).abs()
        + (n_fx + n_ny + n_nz_x).abs()
        + (n_fx + n_ny - n_nz_x).abs()
}
