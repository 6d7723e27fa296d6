//! The contact models turn a joint reaction into normal loads that balance it.
//!
//! Bearings (3.15): the radial forces of bearing A (l_A below the reaction
//! point) and B (l_B above it) add up to the radial joint force and their
//! moments to the bending moment. Slider (3.11): eight corner forces (four
//! across x, four across y, at the slider ends ±a/2 and edges ±b/2, ±c/2)
//! balance the force and moment at the slider centre, and N_s is the sum of
//! their magnitudes. Drives (2.1) and the friction characteristic are checked
//! at their special points. Tolerance 1e-12 relative.

use crate::common;

use common::Rng;
use stick_slip_manipulator::forces::drive::{
    acceleration_stiffness, clearance_margin, drive_force, spring_energy, DriveForce,
};
use stick_slip_manipulator::forces::friction::{
    bearing_loads, contact_load, holds_statically, prescribed_friction, slider_normal_load, slip_friction,
    slip_friction_load_derivative, slip_friction_velocity_slope, stuck_friction,
};
use stick_slip_manipulator::math::Vec3;
use stick_slip_manipulator::model::{ContactGeometry, FrictionCoefficients, JointFriction};

#[test]
fn bearing_forces_balance_the_joint_reaction() {
    let mut rng = Rng::new(5);
    for _ in 0..200 {
        let (l_a, l_b) = (rng.range(0.01, 0.2), rng.range(0.01, 0.2));
        let (f, n) = (rng.vec3(1e3), rng.vec3(1e2));
        let l = l_a + l_b;
        // Statically determinate split of the radial load between A and B.
        let f_a = Vec3::new((l_b * f.x - n.y) / l, (l_b * f.y + n.x) / l, 0.0);
        let f_b = Vec3::new(f.x, f.y, 0.0) - f_a;
        let moment = Vec3::new(0.0, 0.0, -l_a).cross(&f_a) + Vec3::new(0.0, 0.0, l_b).cross(&f_b);
        assert!((moment.xy() - n.xy()).norm() < 1e-12 * n.norm(), "bending moment not balanced");
        let (r_a, r_b) = bearing_loads(l_a, l_b, &f, &n);
        assert!((r_a - f_a.norm()).abs() < 1e-12 * r_a.max(1.0));
        assert!((r_b - f_b.norm()).abs() < 1e-12 * r_b.max(1.0));
    }
}

#[test]
fn bearing_friction_moment_is_eq_3_14() {
    let geometry = ContactGeometry::Bearings {
        reaction_point: Vec3::zeros(),
        l_a: 0.06,
        l_b: 0.06,
        d_a: 0.1,
        d_b: 0.08,
        d_c: 0.12,
    };
    // Pure radial force through the midpoint: each bearing takes half.
    let load = contact_load(&geometry, &Vec3::new(300.0, 400.0, 0.0), &Vec3::zeros());
    assert!((load.normal - 500.0).abs() < 1e-12);
    assert!((load.lever_load - (250.0 * 0.05 + 250.0 * 0.04)).abs() < 1e-12);
    // Pure thrust: ⅔·|f_z|·d_C/2.
    let load = contact_load(&geometry, &Vec3::new(0.0, 0.0, -90.0), &Vec3::zeros());
    assert!((load.normal - 90.0).abs() < 1e-12);
    assert!((load.lever_load - 2.0 / 3.0 * 90.0 * 0.06).abs() < 1e-12);
    // Pure bending moment n_x: a couple ±n_x/l on A and B.
    let load = contact_load(&geometry, &Vec3::zeros(), &Vec3::new(12.0, 0.0, 0.0));
    assert!((load.normal - 2.0 * 12.0 / 0.12).abs() < 1e-12);
    // The moment about the axis is the drive's and the friction's, not a bearing load.
    let load = contact_load(&geometry, &Vec3::zeros(), &Vec3::new(0.0, 0.0, 55.0));
    assert_eq!(load.normal, 0.0);
}

#[test]
fn slider_corner_forces_balance_the_reaction() {
    let mut rng = Rng::new(9);
    for _ in 0..500 {
        let (a, b, c) = (rng.range(0.05, 0.5), rng.range(0.0, 0.1), rng.range(0.01, 0.1));
        let (f, n) = (rng.vec3(1e3), rng.vec3(1e2));
        let bc = b * b + c * c;
        // Corners across y: at x = ±b/2, z = ±a/2; across x: at y = ±c/2, z = ±a/2.
        let mut corners = Vec::new();
        for sz in [-1.0, 1.0] {
            for sx in [-1.0, 1.0] {
                let fy = f.y / 4.0 - sz * n.x / (2.0 * a) + sx * n.z * b / (2.0 * bc);
                corners.push((Vec3::new(sx * b / 2.0, 0.0, sz * a / 2.0), Vec3::new(0.0, fy, 0.0)));
                let sy = sx;
                let fx = f.x / 4.0 + sz * n.y / (2.0 * a) - sy * n.z * c / (2.0 * bc);
                corners.push((Vec3::new(0.0, sy * c / 2.0, sz * a / 2.0), Vec3::new(fx, 0.0, 0.0)));
            }
        }
        let force: Vec3 = corners.iter().map(|(_, f)| f).sum();
        let moment: Vec3 = corners.iter().map(|(r, f)| r.cross(f)).sum();
        assert!((force - Vec3::new(f.x, f.y, 0.0)).norm() < 1e-9, "corner forces {force} vs {f}");
        assert!((moment - n).norm() < 1e-9, "corner moments {moment} vs {n}");
        let total: f64 = corners.iter().map(|(_, f)| f.norm()).sum();
        let n_s = slider_normal_load(a, b, c, &f, &n);
        assert!((n_s - total).abs() < 1e-12 * total, "N_s {n_s} vs Σ|corner| {total}");
    }
}

#[test]
fn drive_force_with_clearance_is_eq_2_1() {
    let (k, h, gap) = (1e6, 1e3, 0.002);
    let force = |q_star, qd_star, q, qd| drive_force(k, h, gap, q_star, qd_star, q, qd);
    // Inside the clearance the drive transmits nothing, damping included.
    for q_star in [0.0015, -0.0015] {
        let inside = force(q_star, 1.0, 0.0, 0.0);
        assert_eq!(inside, DriveForce { force: 0.0, damping: 0.0, engaged: false, flank: f64::INFINITY });
    }
    // Outside: k(q* − q − σΔ) + h(q̇* − q̇), σ = sgn(q* − q); damping part h(q̇* − q̇).
    let out = force(0.005, 0.3, 0.001, 0.1);
    assert!(out.engaged);
    assert!((out.force - (k * (0.004 - gap) + h * 0.2)).abs() < 1e-9);
    assert!((out.damping - h * 0.2).abs() < 1e-12);
    assert!((force(-0.005, 0.3, 0.001, 0.1).force - (k * (-0.006 + gap) + h * 0.2)).abs() < 1e-9);
    // The elastic part is continuous where the clearance is taken up, and
    // δ switches exactly where the clearance margin |q* − q| − Δ crosses zero.
    assert!(drive_force(k, 0.0, gap, gap * (1.0 + 1e-12), 0.0, 0.0, 0.0).force.abs() < 1e-6);
    for e in [gap * (1.0 - 1e-9), gap, gap * (1.0 + 1e-9), -gap * (1.0 + 1e-9)] {
        assert_eq!(drive_force(k, h, gap, e, 0.0, 0.0, 0.0).engaged, clearance_margin(gap, e) >= 0.0, "e = {e}");
    }
    assert!((spring_energy(k, gap, 0.005, 0.0) - 0.5 * k * 0.003f64.powi(2)).abs() < 1e-12);
    assert_eq!(spring_energy(k, gap, 0.001, 0.0), 0.0);
    // No clearance: a plain spring and damper.
    assert_eq!(drive_force(k, h, 0.0, 1e-3, 0.0, 0.0, 0.0).force, 1e3);
    // A NaN deflection is not hidden as "inside the clearance".
    assert!(drive_force(k, h, gap, f64::NAN, 0.0, 0.0, 0.0).force.is_nan());
}

/// With clearance and damping a flank only pushes: where (2.1) would pull
/// (the flanks separate faster than the spring relaxes) the force is 0, the
/// damper's part holds the spring (−k(q* − q − σΔ)), and the flank force
/// σ·F of (2.1) says by how much it would pull; F^d is continuous where the
/// flank force crosses zero. Without damping, or without clearance, (2.1)
/// bit for bit, and nothing to release.
#[test]
fn a_damped_flank_with_clearance_only_pushes() {
    let (k, h, gap) = (1e6, 1e3, 0.002);
    for sigma in [1.0, -1.0] {
        let (e, rate) = (sigma * 0.0025, -sigma * 0.6);
        // (2.1): k·σ·0.0005 + h·(−σ·0.6) = σ·(500 − 600): it would pull.
        let pulling = k * (e - sigma * gap) + h * rate;
        let out = drive_force(k, h, gap, e, rate, 0.0, 0.0);
        assert_eq!((out.force, out.engaged), (0.0, false), "σ = {sigma}: {out:?}");
        assert_eq!(out.flank, sigma * pulling);
        assert!(out.flank < 0.0);
        assert_eq!(out.damping, -k * (e - sigma * gap));
        // A slower separation: it pushes, (2.1) unchanged.
        let out = drive_force(k, h, gap, e, -sigma * 0.4, 0.0, 0.0);
        let pushing = k * (e - sigma * gap) + h * (-sigma * 0.4);
        assert_eq!((out.force, out.engaged, out.damping), (pushing, true, h * (-sigma * 0.4)));
        assert_eq!(out.flank, sigma * pushing);
        // Continuous through the release: the separation speed where the
        // flank force vanishes is k·(|e| − Δ)/h = 0.5.
        for rate in [0.5 - 1e-9, 0.5 + 1e-9] {
            let f = drive_force(k, h, gap, e, -sigma * rate, 0.0, 0.0).force;
            assert!(f.abs() < 1e-5, "σ = {sigma}, rate {rate}: {f}");
        }
    }
    // Without damping the flank force k(|e| − Δ) is never negative; without
    // clearance the drive may pull: both are (2.1) with nothing to release.
    let undamped = drive_force(k, 0.0, gap, 0.0025, -0.6, 0.0, 0.0);
    assert_eq!((undamped.force, undamped.engaged, undamped.flank), (k * (0.0025 - gap), true, f64::INFINITY));
    let bilateral = drive_force(k, h, 0.0, 0.0005, -0.6, 0.0, 0.0);
    assert_eq!((bilateral.force, bilateral.flank), (k * 0.0005 + h * -0.6, f64::INFINITY));
    assert!(bilateral.force < 0.0 && bilateral.engaged);
}

/// −∂F^d/∂q̈ through the Newmark relations (q by βh², q̇ by γh per unit q̈)
/// equals a difference quotient of (2.1) itself.
#[test]
fn drive_acceleration_stiffness_is_the_derivative_of_eq_2_1() {
    let (k, h_d, gap) = (2e6, 3e2, 1e-3);
    let (h, beta, gamma) = (2e-5, 0.25, 0.5);
    let (q_star, qd_star, q0, qd0) = (0.01, 0.2, 0.0, 0.05);
    let at =
        |dqdd: f64| drive_force(k, h_d, gap, q_star, qd_star, q0 + beta * h * h * dqdd, qd0 + gamma * h * dqdd).force;
    // (2.1) is linear outside the clearance: a large step loses nothing to rounding.
    let step = 100.0;
    let difference = -(at(step) - at(-step)) / (2.0 * step);
    let engaged = drive_force(k, h_d, gap, q_star, qd_star, q0, qd0).engaged;
    let analytic = acceleration_stiffness(k, h_d, engaged, h, beta, gamma);
    assert!((difference - analytic).abs() < 1e-9 * analytic, "{difference} vs {analytic}");
    assert_eq!(acceleration_stiffness(k, h_d, false, h, beta, gamma), 0.0);
}

/// (3.16)–(3.18): a stuck joint's friction balances F^d − F*, its margin is
/// the static reserve; a slipping joint's friction opposes its direction with
/// μ(q̇)·L, its margin is d·q̇ when static friction can hold it.
#[test]
fn friction_of_each_phase() {
    let coefficients = FrictionCoefficients { mu_kinetic: 0.12, mu_static: 0.2, stribeck_velocity: 0.01, viscous: 0.0 };
    let geometry = ContactGeometry::Slider { centre: Vec3::zeros(), a: 0.2, b: 0.07, c: 0.07 };
    let friction = JointFriction { coefficients, geometry };
    let lever = 50.0;
    let held = stuck_friction(Some(coefficients), lever, 30.0, 25.0);
    assert_eq!(held.force, 5.0);
    assert!((held.margin - (0.2 * 50.0 - 5.0)).abs() < 1e-12);
    assert!(
        stuck_friction(Some(coefficients), lever, 30.0, 19.0).margin < 0.0,
        "|F^d − F*| = 11 > μ_s L = 10 breaks away"
    );
    for d in [1i8, -1] {
        let slip = slip_friction(Some(&friction), lever, 0.02 * d as f64, d);
        assert!((slip.force - d as f64 * coefficients.kinetic(0.02) * lever).abs() < 1e-12);
        assert!((slip.margin - 0.02).abs() < 1e-15);
    }
    let frictionless_static = JointFriction {
        coefficients: FrictionCoefficients { mu_static: 0.0, mu_kinetic: 0.0, stribeck_velocity: 0.0, viscous: 0.0 },
        geometry,
    };
    assert_eq!(slip_friction(Some(&frictionless_static), lever, 0.1, 1).margin, f64::INFINITY);
    assert!(
        holds_statically(Some(&friction)) && !holds_statically(Some(&frictionless_static)) && !holds_statically(None)
    );
    assert_eq!(prescribed_friction(Some(coefficients), lever, -0.5), -coefficients.kinetic(-0.5) * lever);
    assert_eq!(prescribed_friction(Some(coefficients), lever, 0.0), 0.0);
    // The velocity slope is dF^f/dq̇ of the slip law.
    let (qd, dv) = (0.013, 1e-7);
    let slope = (slip_friction(Some(&friction), lever, qd + dv, 1).force
        - slip_friction(Some(&friction), lever, qd - dv, 1).force)
        / (2.0 * dv);
    let analytic = slip_friction_velocity_slope(coefficients, lever, qd, 1);
    assert!((slope - analytic).abs() < 1e-6 * analytic.abs(), "{slope} vs {analytic}");
}

/// The friction Jacobian's reaction term is the derivative of μ·L(f, n)
/// along a change of the reaction, away from the kinks of (3.11), (3.15).
#[test]
fn friction_load_derivative_is_the_derivative_of_the_contact_law() {
    let coefficients = FrictionCoefficients { mu_kinetic: 0.2, mu_static: 0.2, stribeck_velocity: 0.0, viscous: 0.0 };
    let geometries = [
        ContactGeometry::Slider { centre: Vec3::zeros(), a: 0.2, b: 0.07, c: 0.05 },
        ContactGeometry::Bearings {
            reaction_point: Vec3::zeros(),
            l_a: 0.06,
            l_b: 0.04,
            d_a: 0.1,
            d_b: 0.08,
            d_c: 0.1,
        },
    ];
    let (f, n) = (Vec3::new(30.0, -12.0, 7.0), Vec3::new(2.0, 1.5, -0.7));
    let (df, dn) = (Vec3::new(0.3, 0.2, -0.1), Vec3::new(-0.05, 0.02, 0.01));
    for geometry in geometries {
        let friction = JointFriction { coefficients, geometry };
        let lever = contact_load(&geometry, &f, &n).lever_load;
        let s = 1e-4;
        let lever_at = |t: f64| contact_load(&geometry, &(f + df * t), &(n + dn * t)).lever_load;
        let central = -0.2 * (lever_at(s) - lever_at(-s)) / (2.0 * s);
        let derivative = slip_friction_load_derivative(&friction, lever, 0.1, -1, &f, &n, &df, &dn);
        assert!((derivative - central).abs() < 1e-5 * central.abs(), "{geometry:?}: {derivative} vs {central}");
    }
}

#[test]
fn decreasing_friction_characteristic() {
    let c = FrictionCoefficients { mu_kinetic: 0.12, mu_static: 0.2, stribeck_velocity: 0.01, viscous: 0.0 };
    assert_eq!(c.kinetic(0.0), 0.2);
    assert!((c.kinetic(0.01) - (0.12 + 0.08 / std::f64::consts::E)).abs() < 1e-15);
    assert_eq!(c.kinetic(-0.01), c.kinetic(0.01));
    assert!((c.kinetic(1.0) - 0.12).abs() < 1e-15);
    let constant = FrictionCoefficients { stribeck_velocity: 0.0, ..c };
    assert_eq!(constant.kinetic(0.0), 0.12);
}

/// The viscous part b·q̇ of a moving joint's friction: on top of the dry
/// friction of a slipping and of a prescribed joint, in the velocity slope
/// (∂F^f/∂q̇ = d·L·μ'(q̇) + b, against a central difference), absent from a
/// stuck joint's friction and margin; with b = 0 each law gives the study's
/// value bit for bit, the sign of a zero included.
#[test]
fn viscous_part_of_the_friction_law() {
    let dry = FrictionCoefficients { mu_kinetic: 0.12, mu_static: 0.2, stribeck_velocity: 0.01, viscous: 0.0 };
    let viscous = FrictionCoefficients { viscous: 35.0, ..dry };
    let geometry = ContactGeometry::Slider { centre: Vec3::zeros(), a: 0.2, b: 0.07, c: 0.07 };
    let (with_b, without_b) =
        (JointFriction { coefficients: viscous, geometry }, JointFriction { coefficients: dry, geometry });
    let lever = 50.0;
    for (d, qd) in [(1i8, 0.02), (-1, -0.02), (1, 0.7), (-1, -3.0)] {
        let slip = slip_friction(Some(&with_b), lever, qd, d);
        let expected = d as f64 * dry.kinetic(qd) * lever + 35.0 * qd;
        assert!((slip.force - expected).abs() < 1e-12 * expected.abs(), "{} vs {expected}", slip.force);
        assert_eq!(slip.margin, slip_friction(Some(&without_b), lever, qd, d).margin);
        let prescribed = prescribed_friction(Some(viscous), lever, qd);
        assert!((prescribed - expected).abs() < 1e-12 * expected.abs(), "{prescribed} vs {expected}");
        let dv = 1e-7 * qd.abs();
        let central = (slip_friction(Some(&with_b), lever, qd + dv, d).force
            - slip_friction(Some(&with_b), lever, qd - dv, d).force)
            / (2.0 * dv);
        let analytic = slip_friction_velocity_slope(viscous, lever, qd, d);
        assert!((central - analytic).abs() < 1e-6 * analytic.abs(), "{central} vs {analytic}");
        assert!((analytic - slip_friction_velocity_slope(dry, lever, qd, d) - 35.0).abs() < 1e-12);
    }
    assert_eq!(prescribed_friction(Some(viscous), lever, 0.0), 0.0);
    assert_eq!(stuck_friction(Some(viscous), lever, 30.0, 25.0), stuck_friction(Some(dry), lever, 30.0, 25.0));
    // b = 0: the dry law bit for bit, also a dry friction of −0.
    for (coulomb, v) in [(-3.7, 0.4), (-0.0, 0.5), (0.0, -0.5), (1e-300, -2.0)] {
        assert_eq!(dry.with_viscous(coulomb, v).to_bits(), f64::to_bits(coulomb));
    }
    let no_load = JointFriction { coefficients: dry, geometry };
    assert_eq!(slip_friction(Some(&no_load), 0.0, 0.3, -1).force.to_bits(), (-0.0f64).to_bits());
}
