//! Shared helpers of the integration tests: a small deterministic random
//! generator, random chains and simple one-joint models.
#![allow(dead_code)]

pub mod motor_tables;

use stick_slip_manipulator::math::{Mat3, Vec3};
use stick_slip_manipulator::model::{
    ContactGeometry, DhJoint, DhRow, Drive, FrictionCoefficients, IntegratorSettings, JointFriction, JointKind, Link,
};
use stick_slip_manipulator::Model;

/// xorshift64*: deterministic, good enough for test configurations.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    pub fn next_f64(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.next_f64()
    }
    pub fn vec3(&mut self, s: f64) -> Vec3 {
        Vec3::new(self.range(-s, s), self.range(-s, s), self.range(-s, s))
    }
}

/// A rotation from a random unit quaternion.
pub fn random_rotation(rng: &mut Rng) -> Mat3 {
    let q = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
        rng.range(-1.0, 1.0),
        rng.range(-1.0, 1.0),
        rng.range(-1.0, 1.0),
        rng.range(-1.0, 1.0),
    ));
    *q.to_rotation_matrix().matrix()
}

/// Inertia of a solid box with random sides and orientation (positive
/// definite, satisfies the triangle inequality).
pub fn random_inertia(rng: &mut Rng, mass: f64) -> Mat3 {
    let (a, b, c) = (rng.range(0.05, 0.5), rng.range(0.05, 0.5), rng.range(0.05, 0.5));
    let d = Mat3::from_diagonal(&Vec3::new(b * b + c * c, a * a + c * c, a * a + b * b)) * (mass / 12.0);
    let r = random_rotation(rng);
    r * d * r.transpose()
}

/// A random chain of `n` links with mixed revolute and prismatic joints,
/// mixed drives, and friction geometry on every joint.
pub fn random_chain(n: usize, seed: u64) -> Model {
    let (joints, links) = random_dh_chain(n, seed);
    Model::from_dh(
        format!("random_{n}_{seed}"),
        &joints,
        &links,
        Vec3::new(0.3, -0.2, -9.81),
        Vec3::new(0.1, 0.0, 0.05),
        IntegratorSettings::default(),
    )
    .expect("random chain is valid")
}

/// The Denavit–Hartenberg joints and links (in the study's frames i) of
/// [`random_chain`].
pub fn random_dh_chain(n: usize, seed: u64) -> (Vec<DhJoint>, Vec<Link>) {
    let mut rng = Rng::new(seed);
    let mut joints = Vec::new();
    let mut links = Vec::new();
    for _ in 0..n {
        let kind = if rng.next_f64() < 0.35 { JointKind::Prismatic } else { JointKind::Revolute };
        let drive = if rng.next_f64() < 0.5 {
            Drive::Flexible { stiffness: rng.range(1e4, 1e6), damping: rng.range(0.0, 10.0), clearance: 0.0 }
        } else {
            Drive::Rigid
        };
        let geometry = match kind {
            JointKind::Revolute => ContactGeometry::Bearings {
                reaction_point: Vec3::new(0.0, 0.0, rng.range(-0.2, 0.2)),
                l_a: rng.range(0.01, 0.1),
                l_b: rng.range(0.01, 0.1),
                d_a: rng.range(0.02, 0.1),
                d_b: rng.range(0.02, 0.1),
                d_c: rng.range(0.02, 0.1),
            },
            JointKind::Prismatic => ContactGeometry::Slider {
                centre: rng.vec3(0.3),
                a: rng.range(0.1, 0.4),
                b: rng.range(0.03, 0.1),
                c: rng.range(0.03, 0.1),
            },
        };
        let mu = rng.range(0.05, 0.3);
        joints.push(DhJoint {
            kind,
            dh: DhRow {
                theta: rng.range(-3.0, 3.0),
                d: rng.range(-0.5, 0.5),
                a: rng.range(-0.5, 0.5),
                alpha: rng.range(-3.0, 3.0),
            },
            drive,
            friction: Some(JointFriction {
                coefficients: FrictionCoefficients {
                    mu_kinetic: mu,
                    mu_static: mu * 1.2,
                    stribeck_velocity: 0.0,
                    viscous: 0.0,
                },
                geometry,
            }),
        });
        let mass = rng.range(0.5, 20.0);
        links.push(Link { mass, com: rng.vec3(0.3), inertia: random_inertia(&mut rng, mass) });
    }
    (joints, links)
}

/// One prismatic joint along z0 carrying a block of mass `mass` whose centre
/// of mass is the slider centre, so that the normal load is the weight
/// component across the axis. Gravity g makes angle `tilt` with the normal:
/// its component along −z0 is g·sin(tilt), along −y0 g·cos(tilt).
pub fn sliding_block(mass: f64, stiffness: f64, damping: f64, friction: FrictionCoefficients, tilt: f64) -> Model {
    let g = 9.81;
    let model = Model::from_dh(
        "sliding_block",
        &[DhJoint {
            kind: JointKind::Prismatic,
            dh: DhRow { theta: 0.0, d: 0.0, a: 0.0, alpha: 0.0 },
            drive: Drive::Flexible { stiffness, damping, clearance: 0.0 },
            friction: Some(JointFriction {
                coefficients: friction,
                geometry: ContactGeometry::Slider { centre: Vec3::zeros(), a: 0.2, b: 0.07, c: 0.07 },
            }),
        }],
        &[Link { mass, com: Vec3::zeros(), inertia: Mat3::from_diagonal(&Vec3::new(0.01, 0.01, 0.01)) }],
        Vec3::new(0.0, -g * tilt.cos(), -g * tilt.sin()),
        Vec3::zeros(),
        IntegratorSettings::default(),
    )
    .expect("the model is valid");
    model.validate().expect("sliding block is valid");
    model
}
