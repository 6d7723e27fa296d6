//! The units the variables use, with their SI base-unit exponents.

/// A unit of the `UnitDefinitions`: name and exponents of kg, m, s, rad.
#[derive(Debug, Clone, Copy)]
pub struct Unit {
    /// Name as used in the `unit` attribute.
    pub name: &'static str,
    /// The quantity measured in it, as the Modelica Standard Library names
    /// it (`Modelica.Units.SI`): the `Float64Type` through which FMI 3.0
    /// variables declare the unit (`declaredType`).
    pub quantity: &'static str,
    /// Exponents (kg, m, s, rad) of the SI base units.
    pub base: [i32; 4],
    /// Display units: (name, factor) with display = factor · value.
    pub display: &'static [(&'static str, f64)],
}

const DEG: f64 = 180.0 / std::f64::consts::PI;

/// Every unit a variable may carry.
pub const UNITS: [Unit; 18] = [
    Unit { name: "m", quantity: "Length", base: [0, 1, 0, 0], display: &[("mm", 1e3)] },
    Unit { name: "rad", quantity: "Angle", base: [0, 0, 0, 1], display: &[("deg", DEG)] },
    Unit { name: "s", quantity: "Time", base: [0, 0, 1, 0], display: &[] },
    Unit { name: "kg", quantity: "Mass", base: [1, 0, 0, 0], display: &[] },
    Unit { name: "m/s", quantity: "Velocity", base: [0, 1, -1, 0], display: &[] },
    Unit { name: "rad/s", quantity: "AngularVelocity", base: [0, 0, -1, 1], display: &[("deg/s", DEG)] },
    Unit { name: "m/s2", quantity: "Acceleration", base: [0, 1, -2, 0], display: &[] },
    Unit { name: "rad/s2", quantity: "AngularAcceleration", base: [0, 0, -2, 1], display: &[("deg/s2", DEG)] },
    Unit { name: "N", quantity: "Force", base: [1, 1, -2, 0], display: &[] },
    Unit { name: "N.m", quantity: "Torque", base: [1, 2, -2, 0], display: &[] },
    Unit { name: "J", quantity: "Energy", base: [1, 2, -2, 0], display: &[] },
    Unit { name: "W", quantity: "Power", base: [1, 2, -3, 0], display: &[] },
    Unit { name: "N/m", quantity: "TranslationalSpringConstant", base: [1, 0, -2, 0], display: &[] },
    Unit { name: "N.m/rad", quantity: "RotationalSpringConstant", base: [1, 2, -2, -1], display: &[] },
    Unit { name: "N.s/m", quantity: "TranslationalDampingConstant", base: [1, 0, -1, 0], display: &[] },
    Unit { name: "N.m.s/rad", quantity: "RotationalDampingConstant", base: [1, 2, -1, -1], display: &[] },
    Unit { name: "kg.m2", quantity: "Inertia", base: [1, 2, 0, 0], display: &[] },
    Unit { name: "rad/m", quantity: "AnglePerLength", base: [0, -1, 0, 1], display: &[] },
];
