//! The units the variables use, with their SI base-unit exponents.

/// A unit of the `UnitDefinitions`: name and exponents of kg, m, s, rad.
#[derive(Debug, Clone, Copy)]
pub struct Unit {
    /// Name as used in the `unit` attribute.
    pub name: &'static str,
    /// Exponents (kg, m, s, rad) of the SI base units.
    pub base: [i32; 4],
    /// Display units: (name, factor) with display = factor · value.
    pub display: &'static [(&'static str, f64)],
}

const DEG: f64 = 180.0 / std::f64::consts::PI;

/// Every unit a variable may carry.
pub const UNITS: [Unit; 18] = [
    Unit { name: "m", base: [0, 1, 0, 0], display: &[("mm", 1e3)] },
    Unit { name: "rad", base: [0, 0, 0, 1], display: &[("deg", DEG)] },
    Unit { name: "s", base: [0, 0, 1, 0], display: &[] },
    Unit { name: "kg", base: [1, 0, 0, 0], display: &[] },
    Unit { name: "m/s", base: [0, 1, -1, 0], display: &[] },
    Unit { name: "rad/s", base: [0, 0, -1, 1], display: &[("deg/s", DEG)] },
    Unit { name: "m/s2", base: [0, 1, -2, 0], display: &[] },
    Unit { name: "rad/s2", base: [0, 0, -2, 1], display: &[("deg/s2", DEG)] },
    Unit { name: "N", base: [1, 1, -2, 0], display: &[] },
    Unit { name: "N.m", base: [1, 2, -2, 0], display: &[] },
    Unit { name: "J", base: [1, 2, -2, 0], display: &[] },
    Unit { name: "W", base: [1, 2, -3, 0], display: &[] },
    Unit { name: "N/m", base: [1, 0, -2, 0], display: &[] },
    Unit { name: "N.m/rad", base: [1, 2, -2, -1], display: &[] },
    Unit { name: "N.s/m", base: [1, 0, -1, 0], display: &[] },
    Unit { name: "N.m.s/rad", base: [1, 2, -1, -1], display: &[] },
    Unit { name: "kg.m2", base: [1, 2, 0, 0], display: &[] },
    Unit { name: "rad/m", base: [0, -1, 0, 1], display: &[] },
];
