//! Named models built in code.

use super::{
    ContactGeometry, DhJoint, DhRow, Drive, FrictionCoefficients, IntegratorSettings, JointFriction, JointKind, Link,
    Model,
};
use crate::math::{Mat3, Vec3};

impl Model {
    /// A synthetic spatial chain of `n` links (1 ≤ n ≤ 64) for scaling studies
    /// and benchmarks: every third joint prismatic, the others revolute with
    /// twists alternating ±π/2; odd-numbered joints (1, 3, …) have flexible
    /// drives (k = 10⁶, h = 10) with dry friction (μ_s = 0.12, μ_k = 0.1), the
    /// even-numbered ones are rigid. Links get lighter towards the tip, and
    /// bearings and sliders are long, so that friction does not wedge the
    /// joints (a slider of length a wedges when the load it guides acts
    /// further than about a/(2μ) from it; the slipping equations then have no
    /// consistent solution and the step reports `NotConverged`).
    pub fn synthetic_chain(n: usize) -> Model {
        use std::f64::consts::FRAC_PI_2;
        let mut joints = Vec::with_capacity(n);
        let mut links = Vec::with_capacity(n);
        for i in 0..n {
            let kind = if i % 3 == 2 { JointKind::Prismatic } else { JointKind::Revolute };
            let flexible = i % 2 == 0;
            let geometry = match kind {
                JointKind::Revolute => ContactGeometry::Bearings {
                    reaction_point: Vec3::new(0.0, 0.0, 0.02),
                    l_a: 0.1,
                    l_b: 0.1,
                    d_a: 0.05,
                    d_b: 0.05,
                    d_c: 0.05,
                },
                JointKind::Prismatic => {
                    ContactGeometry::Slider { centre: Vec3::new(0.0, 0.0, -0.1), a: 0.4, b: 0.1, c: 0.1 }
                }
            };
            joints.push(DhJoint {
                kind,
                dh: DhRow {
                    theta: 0.3 * i as f64,
                    d: if kind == JointKind::Prismatic { 0.3 } else { 0.05 },
                    a: 0.1,
                    alpha: if i % 2 == 0 { FRAC_PI_2 } else { -FRAC_PI_2 },
                },
                drive: if flexible {
                    Drive::Flexible { stiffness: 1e6, damping: 10.0, clearance: 0.0 }
                } else {
                    Drive::Rigid
                },
                friction: flexible.then_some(JointFriction {
                    coefficients: FrictionCoefficients {
                        mu_kinetic: 0.1,
                        mu_static: 0.12,
                        stribeck_velocity: 0.0,
                        viscous: 0.0,
                    },
                    geometry,
                }),
            });
            let mass = 10.0 / (1.0 + 0.5 * i as f64);
            links.push(Link {
                mass,
                com: Vec3::new(0.05, 0.01, -0.02),
                inertia: Mat3::from_diagonal(&Vec3::new(0.02, 0.025, 0.03)) * mass,
            });
        }
        Model::from_dh(
            format!("synthetic_chain_{n}"),
            &joints,
            &links,
            Vec3::new(0.0, 0.0, -9.81),
            Vec3::new(0.1, 0.0, 0.0),
            IntegratorSettings::default(),
        )
        .expect("the synthetic chain is valid")
    }
}

#[cfg(test)]
mod tests {
    use super::Model;

    #[test]
    fn synthetic_chains_are_valid() {
        for n in [1, 2, 4, 8, 16, 24, 64] {
            Model::synthetic_chain(n).validate().unwrap();
        }
    }
}
