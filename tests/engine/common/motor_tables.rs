//! Motor drive tables for the fuzz tests (tests/model_file_properties.rs,
//! tests/urdf_fuzz.rs): `drive = { type = "motor", … }` generated field by
//! field, each of k, h, clearance, gear_ratio, rotor_inertia, motor_viscous,
//! motor_coulomb omitted, a random admissible value, an extreme number or
//! garbage; sometimes a misspelt key or drive type; with the drive the table
//! must be read as (`Table::expected`, `None`: it must be refused).
//! A module of `common` (`use crate::common::motor_tables;`).
#![allow(dead_code)]

use proptest::prelude::*;
use stick_slip_manipulator::model::{Drive, Range, Rotor};

/// How one field of a generated motor drive table is written.
#[derive(Debug, Clone)]
pub enum Field {
    Omitted,
    /// A TOML number: its text and the value it must be read as.
    Number(String, f64),
    /// Not a number (a string, boolean, array, table, date): a syntax error.
    Garbage(&'static str),
}

/// The keys of a motor drive table: whether required, and their ranges.
pub const MOTOR_KEYS: [(&str, bool, Range); 7] = [
    ("k", true, Range::STIFFNESS),
    ("h", false, Range::DAMPING),
    ("clearance", false, Range::CLEARANCE),
    ("gear_ratio", true, Range::GEAR_RATIO),
    ("rotor_inertia", true, Range::ROTOR_INERTIA),
    ("motor_viscous", false, Range::MOTOR_VISCOUS),
    ("motor_coulomb", false, Range::MOTOR_COULOMB),
];

/// Extreme numbers, as written and as read.
pub const EXTREME_FIELDS: [(&str, f64); 17] = [
    ("0.0", 0.0),
    ("-0.0", -0.0),
    ("0", 0.0),
    ("100", 100.0),
    ("-1.0", -1.0),
    ("1e300", 1e300),
    ("-1e300", -1e300),
    ("5e-324", 5e-324),
    ("nan", f64::NAN),
    ("inf", f64::INFINITY),
    ("-inf", f64::NEG_INFINITY),
    ("1e3", 1e3),
    ("1e6", 1e6),
    ("1.0000000000000002e6", 1.0000000000000002e6),
    ("1e12", 1e12),
    ("1_000.5", 1000.5),
    ("+2.5", 2.5),
];

pub const GARBAGE: [&str; 6] = ["\"1.0\"", "true", "[1.0]", "{ x = 1.0 }", "1979-05-27", "'abc'"];

/// A field: omitted, an admissible value of `range` (log-uniform, or its
/// bounds), an extreme number, or garbage.
pub fn field(range: Range) -> impl Strategy<Value = Field> {
    prop_oneof![
        1 => Just(Field::Omitted),
        12 => (-9.0..range.max.log10()).prop_map(|e: f64| { let x = 10f64.powf(e); Field::Number(format!("{x:?}"), x) }),
        1 => prop_oneof![Just(range.max), Just(range.min)].prop_map(|x| Field::Number(format!("{x:?}"), x)),
        2 => (0..EXTREME_FIELDS.len()).prop_map(|i| Field::Number(EXTREME_FIELDS[i].0.to_string(), EXTREME_FIELDS[i].1)),
        1 => (0..GARBAGE.len()).prop_map(|i| Field::Garbage(GARBAGE[i])),
    ]
}

/// A generated motor drive table: its fields, in `MOTOR_KEYS` order, the
/// drive type written, a misspelt key if any, and the joint it replaces.
#[derive(Debug, Clone)]
pub struct Table {
    pub fields: Vec<Field>,
    pub kind: &'static str,
    pub extra_key: Option<&'static str>,
    /// The joint (1-based) the test puts the table on.
    pub joint: usize,
}

pub fn table() -> impl Strategy<Value = Table> {
    let fields: Vec<_> = MOTOR_KEYS.iter().map(|(_, _, range)| field(*range)).collect();
    (
        fields,
        prop_oneof![12 => Just("motor"), 1 => Just("motr"), 1 => Just("Motor")],
        prop_oneof![12 => Just(None), 1 => Just(Some("rotor_inertial")), 1 => Just(Some("gear"))],
        1..=4usize,
    )
        .prop_map(|(fields, kind, extra_key, joint)| Table { fields, kind, extra_key, joint })
}

impl Table {
    /// The table as a model-file line `drive = { … }`.
    pub fn toml(&self) -> String {
        let mut entries = vec![format!("type = \"{}\"", self.kind)];
        for ((key, _, _), f) in MOTOR_KEYS.iter().zip(&self.fields) {
            match f {
                Field::Omitted => {}
                Field::Number(text, _) => entries.push(format!("{key} = {text}")),
                Field::Garbage(text) => entries.push(format!("{key} = {text}")),
            }
        }
        if let Some(key) = self.extra_key {
            entries.push(format!("{key} = 1.0"));
        }
        format!("drive = {{ {} }}", entries.join(", "))
    }

    /// The drive the table must be read as, or `None` if it must be refused.
    pub fn expected(&self) -> Option<Drive> {
        if self.kind != "motor" || self.extra_key.is_some() {
            return None;
        }
        let mut values = [0.0; 7];
        for (((_, required, range), f), v) in MOTOR_KEYS.iter().zip(&self.fields).zip(&mut values) {
            match f {
                Field::Omitted if *required => return None,
                Field::Omitted => {}
                Field::Number(_, x) if range.contains(*x) => *v = *x,
                Field::Number(..) | Field::Garbage(_) => return None,
            }
        }
        let [k, h, clearance, gear_ratio, inertia, viscous, coulomb] = values;
        Some(Drive::Motor {
            stiffness: k,
            damping: h,
            clearance,
            rotor: Rotor { gear_ratio, inertia, viscous, coulomb },
        })
    }
}

/// True if the rotor's time constants against its gear, N²·J_m/h and
/// √(N²·J_m/k) (the reflected rotor inertia against the gear's damping and
/// stiffness, s), are at least 1e-7 s, h_min/20 of the reference settings.
/// Only such drives are stepped by the generated-table properties: below
/// that (a rotor of vanishing reflected inertia, admissible by the ranges)
/// one interval of 1 ms can take seconds to minutes at 9a851d5 and cd52240
/// (see `a_rotor_of_vanishing_reflected_inertia_steps_in_reasonable_time` in
/// tests/model_file_properties.rs), which a property of hundreds of cases
/// cannot afford.
pub fn resolvable(drive: &Drive) -> bool {
    let (Some(rotor), Some(spring)) = (drive.rotor(), drive.spring()) else { return true };
    let reflected = rotor.gear_ratio * rotor.gear_ratio * rotor.inertia;
    reflected >= 1e-7 * spring.damping && reflected >= 1e-14 * spring.stiffness
}

/// A motor torque: moderate, or the ends of its range.
pub fn torque() -> impl Strategy<Value = f64> {
    prop_oneof![8 => -2.0..2.0f64, 1 => Just(1e6), 1 => Just(-1e6), 1 => Just(0.0)]
}

/// The seed of the generated-table properties: fixed
/// ([`DEFAULT_SEED`]) unless `STICKSLIP_MOTOR_FUZZ_SEED` gives another
/// number, or `random`. Fixed while the panic of the event location that
/// these properties found is open (a random seed hits it in about one run
/// of twenty; reproducer:
/// `a_damped_motor_gear_with_a_tiny_clearance_steps_without_panicking` in
/// tests/model_file_properties.rs); a long exploring run:
/// `STICKSLIP_MOTOR_FUZZ_SEED=random cargo test --release --test model_file_properties`.
pub fn seed() -> proptest::test_runner::RngSeed {
    use proptest::test_runner::RngSeed;
    match std::env::var("STICKSLIP_MOTOR_FUZZ_SEED").ok().as_deref() {
        Some("random") => RngSeed::Random,
        Some(n) => RngSeed::Fixed(n.parse().expect("STICKSLIP_MOTOR_FUZZ_SEED is a number or `random`")),
        None => RngSeed::Fixed(DEFAULT_SEED),
    }
}

/// The fixed seed of [`seed`].
pub const DEFAULT_SEED: u64 = 20_261_125;
