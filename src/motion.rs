//! The reference motion: cycloidal point-to-point profiles of every joint
//! (shared/reference-manipulator.md).

/// A cycloidal point-to-point profile from `start` to `end` over [0, T],
/// s(τ) = τ − sin(2πτ)/(2π), τ = t/T, holding `end` afterwards. Velocity and
/// acceleration are zero at t = 0 and t = T.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cycloidal {
    /// Start value.
    pub start: f64,
    /// End value.
    pub end: f64,
    /// Duration T of the motion, s.
    pub duration: f64,
}

impl Cycloidal {
    /// (q, q̇, q̈) at time `t` (held at the ends outside [0, T]).
    pub fn eval(&self, t: f64) -> (f64, f64, f64) {
        use std::f64::consts::TAU;
        let d = self.end - self.start;
        let big_t = self.duration;
        if t <= 0.0 {
            return (self.start, 0.0, 0.0);
        }
        if t >= big_t {
            return (self.end, 0.0, 0.0);
        }
        let tau = t / big_t;
        let s = tau - (TAU * tau).sin() / TAU;
        let sd = (1.0 - (TAU * tau).cos()) / big_t;
        let sdd = TAU * (TAU * tau).sin() / (big_t * big_t);
        (self.start + d * s, d * sd, d * sdd)
    }
}

/// The reference motion of the reference manipulator: q1* 0 → π/3,
/// q2 0 → π/12, q3* 0.8 → 1.0, q4 0 → π/2, all over T = 1.5 s, then held
/// until the end of the 2 s run.
pub fn reference_motion() -> [Cycloidal; 4] {
    use std::f64::consts::PI;
    let c = |start, end| Cycloidal { start, end, duration: 1.5 };
    [c(0.0, PI / 3.0), c(0.0, PI / 12.0), c(0.8, 1.0), c(0.0, PI / 2.0)]
}

/// (q*, q̇*, q̈*) of the four joints of the reference motion at time `t`.
pub fn reference_inputs(t: f64) -> ([f64; 4], [f64; 4], [f64; 4]) {
    let (mut q, mut qd, mut qdd) = ([0.0; 4], [0.0; 4], [0.0; 4]);
    for (i, m) in reference_motion().iter().enumerate() {
        (q[i], qd[i], qdd[i]) = m.eval(t);
    }
    (q, qd, qdd)
}

/// Duration of the reference run, s.
pub const REFERENCE_RUN_TIME: f64 = 2.0;
