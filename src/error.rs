//! The errors of the engine: one enum for models, one for stepping.

/// A model that cannot be built: each variant names the field and the reason.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ModelError {
    /// The model file, or the URDF it names, could not be read.
    #[error("cannot read `{path}`: {reason}")]
    Io {
        /// The path as given.
        path: String,
        /// What the operating system said.
        reason: String,
    },
    /// The file is not valid TOML or does not have the expected structure
    /// (unknown key, wrong type, missing field, unknown joint type …).
    #[error("model file is malformed: {reason}")]
    Syntax {
        /// The parser's message, with line and column where known.
        reason: String,
    },
    /// A numeric parameter is out of its range.
    #[error("`{field}` = {}: {reason}", number(*.value))]
    InvalidParameter {
        /// The field, e.g. `joint[3].drive.k`.
        field: String,
        /// The rejected value.
        value: f64,
        /// Why it is rejected.
        reason: String,
    },
    /// A URDF file that cannot be used: names the element and what is wrong.
    #[error("URDF {element}: {reason}")]
    Urdf {
        /// The element, e.g. `<joint name="elbow">` or `<link name="link3"><inertial>`.
        element: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A structural problem that is not one number (missing geometry, chain
    /// length, …).
    #[error("`{field}`: {reason}")]
    Invalid {
        /// The field or section concerned.
        field: String,
        /// Why it is rejected.
        reason: String,
    },
}

/// A communication interval the engine could not complete. The state is left
/// as it was at the start of the interval.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StepError {
    /// An input vector has the wrong length.
    #[error("input `{field}` has {got} values, the model has {expected} joints")]
    InputLength {
        /// Which input.
        field: &'static str,
        /// Number of joints of the model.
        expected: usize,
        /// Number of values given.
        got: usize,
    },
    /// An input is NaN or infinite.
    #[error("input `{field}[{joint}]` is not finite ({value})")]
    NonFiniteInput {
        /// Which input (`q_star`, `qd_star`, `qdd_star`).
        field: &'static str,
        /// Joint number, 1-based.
        joint: usize,
        /// The rejected value.
        value: f64,
    },
    /// An input lies outside its admissible range (see
    /// [`INPUT_RANGES`](crate::stepper::INPUT_RANGES)).
    #[error("input `{field}[{joint}]` = {value:e} lies outside its range {range}")]
    InputOutOfRange {
        /// Which input (`q_star`, `qd_star`, `qdd_star`).
        field: &'static str,
        /// Joint number, 1-based.
        joint: usize,
        /// The rejected value.
        value: f64,
        /// Its admissible range, as text.
        range: String,
    },
    /// A reported quantity became NaN or infinite (an overflow of what the
    /// inputs and parameters produce).
    #[error("{quantity} is not finite ({value}) at t = {time} s; likely cause: a parameter or input far outside the physical range of the model")]
    NonFiniteOutput {
        /// The quantity, by name (an FMU output variable name, or the state
        /// field and joint).
        quantity: String,
        /// Its value.
        value: f64,
        /// Time of the end of the interval, s.
        time: f64,
    },
    /// The interval length is not a positive finite number.
    #[error("communication interval {interval} s is not positive and finite")]
    InvalidInterval {
        /// The rejected interval, s.
        interval: f64,
    },
    /// The Newmark iteration found no consistent state: it did not converge
    /// within its iteration limit, also at the shortest sub-step it was
    /// tried with.
    #[error(
        "Newmark iteration did not converge at t = {time} s for joint {joint} after {iterations} iterations \
         (residual {residual:e}{}): {cause}",
        shortest_note(*substep, *halvings)
    )]
    NotConverged {
        /// Time of the end of the failed sub-step, s.
        time: f64,
        /// The joint with the largest residual, 1-based.
        joint: usize,
        /// Iterations done.
        iterations: usize,
        /// Largest residual of (3.9) relative to the joint's force scale.
        residual: f64,
        /// Length of the failed sub-step, s.
        substep: f64,
        /// How often the sub-step had been halved before it failed.
        halvings: usize,
        /// Why that joint's equation has no consistent solution.
        cause: NonConvergence,
    },
    /// The mass matrix of the slipping joints is not positive definite.
    #[error("mass matrix of the slipping joints is not positive definite at t = {time} s")]
    SingularMassMatrix {
        /// Time of the failed sub-step, s.
        time: f64,
    },
    /// The state became NaN or infinite.
    #[error("state is not finite at t = {time} s")]
    NonFiniteState {
        /// Time of the failed sub-step, s.
        time: f64,
    },
    /// The interval cost more evaluations than a converging run could
    /// (see `work_budget` in `src/stepper/integrator.rs`): time constants far
    /// below the smallest sub-step.
    #[error(
        "the step needed more than {evaluations} evaluations in {substeps} sub-steps by t = {time} s without finishing: \
         the model has time constants far below h_min = {h_min:e} s (a rotor of negligible reflected inertia N^2 J_m against \
         a strong gear damper, or stiffness far beyond the chain's masses); change those parameters"
    )]
    TooMuchWork {
        /// Time reached, s.
        time: f64,
        /// Evaluations spent in the interval.
        evaluations: u64,
        /// Sub-steps accepted since initialization.
        substeps: u64,
        /// The smallest sub-step, s.
        h_min: f64,
    },
    /// The simulation was advanced before it was initialized.
    #[error("the simulation is not initialized")]
    NotInitialized,
    /// A parameter change left the model inconsistent.
    #[error("model is not valid: {reason}")]
    InvalidModel {
        /// What is wrong, naming the parameter.
        reason: String,
    },
    /// An instruction set was requested that this processor lacks.
    #[error("this processor does not support the {name} instruction set")]
    UnsupportedInstructionSet {
        /// Name of the instruction set.
        name: &'static str,
    },
}

/// Why the Newmark iteration found no consistent state for a joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NonConvergence {
    /// The joint's drive switched between transmitting force and not (an edge
    /// of its clearance, or its flank's release) from one iterate to the next.
    DriveSwitching,
    /// The joint's friction changed its form from one iterate to the next (a
    /// kink of the contact loads (3.11), (3.15) or of the characteristic), or
    /// grows with the load its own acceleration causes (a slider or bearing
    /// too short for the load it guides wedges: no slip is consistent).
    Friction,
    /// The iterates still approached the solution when the iteration limit
    /// `max_iterations` was reached, or the tolerance `tolerance` is below
    /// what rounding lets the residual reach.
    IterationLimit,
}

impl std::fmt::Display for NonConvergence {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            NonConvergence::DriveSwitching => {
                "its drive switches between engaged and free from one iterate to the next (an edge of its clearance \
                 or the release of its flank); check the drive's stiffness, damping and clearance"
            }
            NonConvergence::Friction => {
                "its friction changes form from one iterate to the next or grows with the load its own acceleration \
                 causes (a slider or bearing too short for the load it guides wedges, and no slip is consistent); \
                 check the joint's contact geometry and friction coefficients"
            }
            NonConvergence::IterationLimit => {
                "the residual still fell when the iteration limit was reached, or cannot reach the tolerance in \
                 floating point; raise `max_iterations` or loosen `tolerance`"
            }
        })
    }
}

/// Which solve failed: at an instant (no sub-step), a sub-step, or the
/// shortest of the halved sub-steps.
fn shortest_note(substep: f64, halvings: usize) -> String {
    if substep == 0.0 {
        ", solving the state at that instant after a phase change or at the start of a step".to_string()
    } else if halvings == 0 {
        format!(", sub-step {substep:e} s")
    } else {
        format!(", even at the shortest sub-step tried, {substep:e} s after {halvings} halvings")
    }
}

/// A bound or value as people write it: 2, 0.5, 1e-3, 1e12, 1e300 (not the
/// 301 digits of `{}`).
pub(crate) fn number(x: f64) -> String {
    if x == 0.0 || (1e-2..1e4).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}
