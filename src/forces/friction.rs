//! Normal loads and dry friction of revolute and prismatic joints
//! (study sections 3.1, 3.2).

use crate::math::Vec3;
use crate::model::ContactGeometry;

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
