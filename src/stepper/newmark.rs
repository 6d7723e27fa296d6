//! One sub-step of the iterative Newmark method: accelerations, joint
//! reactions and friction forces made mutually consistent.
//!
//! [`NewmarkSolver`] owns everything the iteration keeps between sub-steps:
//! the slipping joints, the factored Newton matrix and when it may be reused,
//! and the accelerations the predictor extrapolates from. Its invariants are
//! kept here; the simulator only asks it to solve a sub-step, to accept one,
//! or to start afresh.

use super::inputs::InputPolynomial;
use super::state::{Phase, State};
use crate::algorithms::crba::{crba, motion_subspace};
use crate::algorithms::kinematics::{forward_kinematics_at_transforms, reaction_point, update_joint_transforms};
use crate::algorithms::lu;
use crate::algorithms::rnea::{joint_reaction, rnea};
use crate::data::Data;
use crate::error::{NonConvergence, StepError};
use crate::forces::drive::{acceleration_stiffness, clearance_margin, drive_force_over_substep};
use crate::forces::friction::{
    friction_loads, prescribed_friction, slip_friction, slip_friction_load_derivative, slip_friction_velocity_slope,
    stuck_friction,
};
use crate::forces::rotor::{rotor_acceleration_inertia, rotor_torques};
use crate::model::{Drive, DriveSpring, Joint, JointKind, Model};

/// How many iterates back a failed iteration is judged as still converging.
const RECENT_ITERATES: usize = 5;

/// How far, relative to the sub-step, an error-controlled sub-step's length
/// may be from the one its Newton matrix was built for.
const NEWTON_REUSE: f64 = 0.3;

/// The iteration workspace of the Newmark sub-steps, sized once for a model.
///
/// Its unknowns are the accelerations of the free coordinates (see
/// [`State`]): the slipping joints, then the slipping rotors of motor
/// drives.
#[derive(Debug, Clone)]
pub(crate) struct NewmarkSolver {
    /// Number of joints n.
    n: usize,
    /// The motor drives: rotor r is coordinate n + r and turns joint `rotors[r]`.
    rotors: Vec<usize>,
    /// Indices of the coordinates with an equation of motion in this sub-step.
    free: Vec<usize>,
    /// The position of each coordinate in `free`, `usize::MAX` if it is not free.
    free_position: Vec<usize>,
    /// Newton matrix of the free joints, row-major, LU-factored in place.
    iteration_matrix: Vec<f64>,
    /// Row exchanges of its factorization.
    pivots: Vec<usize>,
    /// True while the factored Newton matrix may be reused.
    newton_valid: bool,
    /// Sub-step length the Newton matrix was built for, s.
    newton_h: f64,
    /// Free joints the Newton matrix was built for.
    newton_free: Vec<usize>,
    /// Refined q̈ (see [`NewmarkSolver::refine_acceleration`]) at the start of
    /// the current sub-step and of the two before it, for the predictor.
    qdd_history: [Vec<f64>; 3],
    /// Refined q̈ of the last solved sub-step; enters the history when the
    /// sub-step is accepted.
    refined_qdd: Vec<f64>,
    /// Lengths of the last two accepted sub-steps, s.
    previous_h: [f64; 2],
    /// How many of the previous sub-steps belong to the current phases and
    /// interval (0, 1 or 2).
    predictor_depth: usize,
    /// Residuals, then corrections, of the free joints.
    correction: Vec<f64>,
    /// Accelerations of the free joints at the last accepted Newton iterate.
    accepted_qdd: Vec<f64>,
    /// The Newton step taken from there (halved when it overshoots).
    newton_step: Vec<f64>,
    /// Inverse-dynamics evaluations since the last [`NewmarkSolver::reset_count`].
    iterations: u64,
    /// Diagonal of the mass matrix of the last Newton matrix built since the
    /// last restart, then the rotor inertias (empty before one is built): the
    /// coordinates' frequencies for
    /// the error estimate, from the state and inputs alone, so that a restored
    /// state continues exactly.
    mass_diagonal: Vec<f64>,
    /// Per joint: whether its drive transmitted force at the last iterate,
    /// and how often that changed in the current sub-step's iteration (the
    /// diagnosis of a failure, [`NonConvergence`]).
    engaged: Vec<bool>,
    engagement_changes: Vec<u32>,
    /// The relative residual of a replay (see `super::schedule`), where it
    /// is below the settings' iteration tolerance.
    pub(crate) replay_tolerance: Option<f64>,
}

/// The sub-step before the current one, for the velocity error estimate
/// (see [`NewmarkSolver::previous_sub_step`]).
pub(crate) struct PreviousSubStep<'a> {
    /// Refined q̈ at its start.
    pub qdd: &'a [f64],
    /// Its length, s.
    pub h: f64,
    /// Diagonal of the joint-space mass matrix.
    pub mass_diagonal: &'a [f64],
}

/// What a sub-step reads besides the state it solves: the model, the
/// workspace, the drive inputs and the state at the sub-step's start.
pub(crate) struct SubStep<'a> {
    pub model: &'a Model,
    pub data: &'a mut Data,
    pub inputs: &'a InputPolynomial,
    /// The motor torques τ_m, per joint.
    pub torques: &'a InputPolynomial,
    pub start: &'a State,
}

impl NewmarkSolver {
    /// A solver for `model`'s chain: n joints and the rotors of its motor
    /// drives.
    pub fn new(model: &Model) -> NewmarkSolver {
        let joints = model.nq();
        let rotors = model.motor_joints();
        let n = model.n_coordinates();
        NewmarkSolver {
            n: joints,
            rotors,
            free: Vec::with_capacity(n),
            free_position: vec![usize::MAX; n],
            iteration_matrix: vec![0.0; n * n],
            pivots: vec![0; n],
            newton_valid: false,
            newton_h: 0.0,
            newton_free: Vec::with_capacity(n),
            qdd_history: [vec![0.0; n], vec![0.0; n], vec![0.0; n]],
            refined_qdd: vec![0.0; n],
            previous_h: [0.0; 2],
            predictor_depth: 0,
            correction: vec![0.0; n],
            accepted_qdd: vec![0.0; n],
            newton_step: vec![0.0; n],
            iterations: 0,
            mass_diagonal: Vec::with_capacity(n),
            engaged: vec![false; joints],
            engagement_changes: vec![0; joints],
            replay_tolerance: None,
        }
    }

    /// The joints of the motor drives: rotor r (coordinate n + r) turns joint `rotors()[r]`.
    pub fn rotors(&self) -> &[usize] {
        &self.rotors
    }

    /// The joint a coordinate belongs to: itself, or the joint a rotor turns.
    pub fn joint_of(&self, coordinate: usize) -> usize {
        if coordinate < self.n {
            coordinate
        } else {
            self.rotors[coordinate - self.n]
        }
    }

    /// What the velocity error estimate needs besides the sub-step itself,
    /// once the history since the last restart has it: the refined q̈ at the
    /// start of the previous sub-step, that sub-step's length and the mass
    /// matrix's diagonal.
    pub fn previous_sub_step(&self) -> Option<PreviousSubStep<'_>> {
        (self.predictor_depth >= 1 && !self.mass_diagonal.is_empty()).then(|| PreviousSubStep {
            qdd: &self.qdd_history[1],
            h: self.previous_h[0],
            mass_diagonal: &self.mass_diagonal,
        })
    }

    /// Inverse-dynamics evaluations since the last [`NewmarkSolver::reset_count`].
    pub fn iterations(&self) -> u64 {
        self.iterations
    }

    /// Starts counting evaluations anew.
    pub fn reset_count(&mut self) {
        self.iterations = 0;
    }

    /// Forgets the Newton matrix and the predictor history, so that what
    /// follows depends only on the state and the inputs (an exact
    /// continuation after a state is restored), and predicts from the
    /// accelerations `qdd` of the state to solve.
    pub fn restart(&mut self, qdd: &[f64]) {
        self.newton_valid = false;
        self.predictor_depth = 0;
        self.mass_diagonal.clear();
        self.qdd_history[0].copy_from_slice(qdd);
    }

    /// Makes the last solved sub-step's refined accelerations the newest
    /// entry of the predictor history (after [`NewmarkSolver::restart`] and a
    /// zero-length solve: the accelerations to predict from).
    pub fn seed_history(&mut self) {
        self.qdd_history[0].copy_from_slice(&self.refined_qdd);
    }

    /// Books an accepted sub-step of length `dt` for the predictor: the
    /// history moves back by one and the refined q̈ becomes its newest
    /// entry (the oldest buffer is reused for the next refined q̈).
    #[inline(always)]
    pub fn accepted(&mut self, dt: f64) {
        // rotate_right(1) by two swaps: the library's rotate is not inlined here.
        self.qdd_history.swap(0, 2);
        self.qdd_history.swap(1, 2);
        std::mem::swap(&mut self.qdd_history[0], &mut self.refined_qdd);
        self.previous_h = [dt, self.previous_h[0]];
        self.predictor_depth = (self.predictor_depth + 1).min(2);
    }

    /// Solves the sub-step from `step.start` to time `t` with the phases in
    /// `state`; the result lands in `state` (q, q̇, q̈, forces, reactions,
    /// margins) and in the workspace.
    ///
    /// Newmark: q₁ = q₀ + h·q̇₀ + h²·((½ − β)·q̈₀ + β·q̈₁), q̇₁ = q̇₀ + h·((1 − γ)·q̈₀ + γ·q̈₁).
    /// The unknowns q̈₁ of the slipping joints start from q̈ extrapolated
    /// quadratically from the starts of this and the last two sub-steps (the
    /// first evaluation then mostly meets the tolerance, see
    /// [`NewmarkSolver::refine_acceleration`]) and are corrected with the Newton matrix
    /// (see `factor_newton_matrix`) until the residual of (3.9),
    /// F^d − F^f − (M q̈ + bias), is below the tolerance relative to the
    /// joint's force scale: then accelerations, reactions and friction agree.
    /// The Newton matrix is kept across sub-steps of the same length and
    /// the same slipping joints (it changes by O(h) per sub-step, which only
    /// slows convergence slightly) and rebuilt when an iteration needs more
    /// than two corrections.
    #[inline(always)]
    pub fn solve(&mut self, step: SubStep, state: &mut State, t: f64) -> Result<(), StepError> {
        let SubStep { model, data, inputs, torques, start } = step;
        let h = t - start.time;
        let settings = model.integrator;
        let (beta, gamma) = (settings.beta, settings.gamma);
        state.time = t;
        self.predict(model, inputs, torques, start, state, t, h);
        let nf = self.free.len();
        // Fixed sub-steps differ in length by rounding only; error-controlled
        // ones change gradually, and a Newton matrix of a nearby length still
        // contracts (one that does not is rebuilt after two corrections).
        let reuse = if settings.fixed_step() { 1e-9 } else { NEWTON_REUSE };
        let tolerance = match self.replay_tolerance {
            Some(tight) => tight.min(settings.iteration_tolerance()),
            None => settings.iteration_tolerance(),
        };
        let newton_fits = self.newton_valid
            && (self.newton_h - h).abs() <= reuse * h
            && self.newton_free.len() == nf
            && self.newton_free.iter().zip(&self.free).all(|(a, b)| a == b);
        if !newton_fits {
            self.newton_valid = false;
        }
        // Friction loads are sums of absolute values: a Newton step across one
        // of their kinks can overshoot and cycle. After a few plain Newton
        // steps, a step that does not lower the residual's 2-norm is halved
        // back towards the last accepted iterate.
        const PLAIN_NEWTON_STEPS: usize = 6;
        let mut accepted_merit = f64::INFINITY;
        // The merits of the last few iterates, to tell an iteration that was
        // still converging from one that cycles.
        let mut recent_merits = [f64::INFINITY; RECENT_ITERATES];
        // The clearance margins at the start of the sub-step: a damped drive
        // whose clearance is open there stays open until the located closing
        // (see `drive_force_over_substep`). A zero-length solve evaluates the
        // state as it is.
        let open = if h > 0.0 { &start.clearance_margin[..] } else { &[] };
        self.engagement_changes.fill(0);
        for iteration in 1..=settings.max_iterations {
            // q and q̇ of the free coordinates follow their q̈ (see `newmark`),
            // the drive positions of motor drives their rotors.
            // The DH transforms follow q (skipped when only rounding moved it).
            self.turn_drive_ends(model, state);
            let n = self.n;
            update_joint_transforms(model, data, &state.q[..n]);
            rnea(model, data, &state.q[..n], &state.qd[..n], &state.qdd[..n]);
            // Friction needs the reactions of the joints with friction; the
            // others are reported at the end of the interval.
            for (i, joint) in model.joints.iter().enumerate() {
                if joint.friction.is_some() {
                    joint_reaction(model, data, i);
                }
            }
            let (residual, merit, worst) = self.joint_forces(model, data, state, open, iteration == 1);
            let worst_joint = self.joint_of(worst);
            self.iterations += 1;
            if !residual.is_finite() {
                return Err(StepError::NonFiniteState { time: t });
            }
            if residual <= tolerance {
                self.refine_acceleration(state);
                return Ok(());
            }
            if iteration == settings.max_iterations {
                let contracting = merit < 1e-3 * recent_merits[iteration % RECENT_ITERATES];
                let cause = self.diagnose(model, worst_joint, iteration, residual, contracting);
                return Err(StepError::NotConverged {
                    time: t,
                    joint: worst_joint + 1,
                    iterations: iteration,
                    residual,
                    substep: h,
                    halvings: 0,
                    cause,
                });
            }
            recent_merits[iteration % RECENT_ITERATES] = merit;
            if iteration > PLAIN_NEWTON_STEPS && merit >= accepted_merit {
                for (k, &i) in self.free.iter().enumerate() {
                    self.newton_step[k] *= 0.5;
                    state.qdd[i] = self.accepted_qdd[k] + self.newton_step[k];
                    newmark(start, state, i, h, beta, gamma);
                }
                continue;
            }
            accepted_merit = merit;
            if !self.newton_valid || iteration > 2 {
                // The mass matrix and the friction Jacobian need the frame-0
                // kinematics, of the coordinates the inverse dynamics used.
                forward_kinematics_at_transforms(model, data);
                crba(model, data);
                self.mass_diagonal.clear();
                self.mass_diagonal.extend((0..model.nq()).map(|i| data.mass_matrix[(i, i)]));
                self.mass_diagonal
                    .extend(self.rotors.iter().filter_map(|&j| model.joints[j].drive.rotor()).map(|r| r.inertia));
                self.factor_newton_matrix(model, data, state, open, h, beta, gamma)?;
                self.newton_valid = true;
                self.newton_h = h;
                self.newton_free.clear();
                self.newton_free.extend_from_slice(&self.free);
            }
            lu::solve(&self.iteration_matrix, nf, &self.pivots, &mut self.correction[..nf]);
            for (k, &i) in self.free.iter().enumerate() {
                self.accepted_qdd[k] = state.qdd[i];
                self.newton_step[k] = self.correction[k];
                state.qdd[i] += self.correction[k];
                newmark(start, state, i, h, beta, gamma);
            }
        }
        unreachable!("the loop returns on its last iteration")
    }

    /// Why the iteration of the current sub-step found no consistent state
    /// for joint `joint` (0-based), whose residual `residual` is the largest
    /// after `iterations` iterations; `contracting` when the merit fell a
    /// thousandfold over the last [`RECENT_ITERATES`] iterates.
    fn diagnose(
        &self,
        model: &Model,
        joint: usize,
        iterations: usize,
        residual: f64,
        contracting: bool,
    ) -> NonConvergence {
        if self.engagement_changes[joint] > 0 {
            NonConvergence::DriveSwitching
        } else if model.joints[joint].drive.rotor().is_some_and(|r| r.coulomb > 0.0) && iterations > 2 && !contracting {
            // The rotor's Coulomb friction may change form as well.
            NonConvergence::Friction
        } else if iterations <= 2 || contracting || residual < 1e-12 || model.joints[joint].friction.is_none() {
            NonConvergence::IterationLimit
        } else {
            NonConvergence::Friction
        }
    }

    /// Sets up the sub-step to time `t` (length `h`): the drive inputs at
    /// `t`, the prescribed motion of rigid joints, stuck joints held at their
    /// start, the list of free (slipping) joints and their predicted q̈:
    /// the Lagrange extrapolation of the last three refined accelerations,
    /// and the q, q̇ that the Newmark relations give for it.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn predict(
        &mut self,
        model: &Model,
        inputs: &InputPolynomial,
        torques: &InputPolynomial,
        s: &State,
        st: &mut State,
        t: f64,
        h: f64,
    ) {
        let n = model.nq();
        // Lagrange weights of q̈ at t_n, t_{n−1}, t_{n−2} extrapolated to t_n + h.
        let (h1, h2) = (self.previous_h[0], self.previous_h[1]);
        let [w0, w1, w2] = match self.predictor_depth {
            0 => [1.0, 0.0, 0.0],
            1 => [1.0 + h / h1, -h / h1, 0.0],
            _ => [
                (h + h1 + h2) * (h + h1) / ((h1 + h2) * h1),
                -h * (h + h1 + h2) / (h1 * h2),
                h * (h + h1) / (h2 * (h1 + h2)),
            ],
        };
        let nc = n + self.rotors.len();
        // Slices of known length let the compiler drop the per-index bounds checks.
        let (q, qd, qdd) = (&mut st.q[..nc], &mut st.qd[..nc], &mut st.qdd[..nc]);
        let (q_star, qd_star, phase) = (&mut st.q_star[..n], &mut st.qd_star[..n], &st.phase[..nc]);
        let (start_q, start_qd, start_qdd) = (&s.q[..nc], &s.qd[..nc], &s.qdd[..nc]);
        let (beta, gamma) = (model.integrator.beta, model.integrator.gamma);
        let [h0, h1, h2] = &self.qdd_history;
        let (h0, h1, h2) = (&h0[..nc], &h1[..nc], &h2[..nc]);
        self.free.clear();
        for i in 0..nc {
            if i < n {
                // A motor drive's q* follows its rotor (`turn_drive_ends`).
                let (qs, qds, qdds) = inputs.eval(i, t);
                q_star[i] = qs;
                qd_star[i] = qds;
                if phase[i] == Phase::Prescribed {
                    q[i] = qs;
                    qd[i] = qds;
                    qdd[i] = qdds;
                    continue;
                }
            } else {
                st.motor_torque[i - n] = torques.eval(self.rotors[i - n], t).0;
            }
            match phase[i] {
                Phase::Stuck => {
                    q[i] = start_q[i];
                    qd[i] = 0.0;
                    qdd[i] = 0.0;
                    self.free_position[i] = usize::MAX;
                }
                Phase::Slipping(_) => {
                    self.free_position[i] = self.free.len();
                    self.free.push(i);
                    let qdd_i = w0 * h0[i] + w1 * h1[i] + w2 * h2[i];
                    qdd[i] = qdd_i;
                    (q[i], qd[i]) = newmark_step(start_q[i], start_qd[i], start_qdd[i], qdd_i, h, beta, gamma);
                }
                Phase::Prescribed => self.free_position[i] = usize::MAX,
            }
        }
    }

    /// Sets the drive position q* = θ_m/N and rate q̇* = θ̇_m/N of every
    /// motor drive from its rotor.
    #[inline(always)]
    fn turn_drive_ends(&self, model: &Model, st: &mut State) {
        for (r, &j) in self.rotors.iter().enumerate() {
            let Some(rotor) = model.joints[j].drive.rotor() else { continue };
            st.q_star[j] = st.q[self.n + r] / rotor.gear_ratio;
            st.qd_star[j] = st.qd[self.n + r] / rotor.gear_ratio;
        }
    }

    /// Stores in `self.refined_qdd` the accepted q̈ plus one more Newton
    /// correction computed from the residual already at hand (no further
    /// evaluation) when a Newton matrix fits this sub-step (`solve` clears
    /// `newton_valid` when it does not). The accepted state
    /// keeps the verified q̈; only the predictor uses the refined one. The
    /// accepted q̈ is off the exact solution by up to the tolerance, and the
    /// quadratic extrapolation multiplies such errors by up to 7: from raw
    /// values the prediction lands just above the tolerance in most
    /// sub-steps, from refined ones mostly below it.
    #[inline(always)]
    fn refine_acceleration(&mut self, state: &State) {
        self.refined_qdd.copy_from_slice(&state.qdd);
        let nf = self.free.len();
        if nf == 0 || !self.newton_valid {
            return;
        }
        lu::solve(&self.iteration_matrix, nf, &self.pivots, &mut self.correction[..nf]);
        for (k, &i) in self.free.iter().enumerate() {
            self.refined_qdd[i] += self.correction[k];
        }
    }

    /// Builds and factors the Newton matrix of the free joints,
    /// M_ff + γh·H_f + βh²·K_f + ∂F^f/∂q̈: the mass matrix of the sub-step
    /// start, the drive terms through the Newmark relations
    /// ([`acceleration_stiffness`]), and the friction Jacobian. Friction
    /// depends on q̈ through the reactions, which are linear in q̈: joint j's
    /// unit acceleration adds the spatial force I^c_max(s,j)·S_j to the
    /// reaction of joint s ([`slip_friction_load_derivative`] along it), and
    /// through q̇, by γh ([`slip_friction_velocity_slope`]). Without the
    /// reaction term the iteration only contracts slowly on long chains with
    /// much friction.
    #[allow(clippy::too_many_arguments)]
    fn factor_newton_matrix(
        &mut self,
        model: &Model,
        data: &Data,
        st: &State,
        open: &[f64],
        h: f64,
        beta: f64,
        gamma: f64,
    ) -> Result<(), StepError> {
        let nf = self.free.len();
        let n = self.n;
        for a in 0..nf {
            let s = self.free[a];
            if s >= n {
                self.factor_rotor_row(model, st, open, a, s, h, beta, gamma);
                continue;
            }
            for (b, &j) in self.free.iter().enumerate() {
                // Rotors come after the joints; the gear couples them (`factor_rotor_row`).
                self.iteration_matrix[a * nf + b] = if j < n { data.mass_matrix[(s, j)] } else { 0.0 };
            }
            let joint = &model.joints[s];
            if let Some(spring) = joint.drive.spring() {
                let DriveSpringTerms { stiffness, .. } = spring_terms(spring, open, s, st, h, beta, gamma);
                self.iteration_matrix[a * nf + a] += stiffness;
            }
            let (Some(friction), Phase::Slipping(d)) = (joint.friction.as_ref(), st.phase[s]) else { continue };
            self.iteration_matrix[a * nf + a] +=
                slip_friction_velocity_slope(friction.coefficients, st.lever_load[s], st.qd[s], d) * gamma * h;
            let (f0, n0) = (data.reaction_force[s], data.reaction_moment[s]);
            let rt = data.rotation[s + 1].transpose();
            let p = reaction_point(model, data, s);
            for (b, &j) in self.free.iter().enumerate() {
                if j >= n {
                    // A rotor's acceleration moves no link.
                    continue;
                }
                // Change of joint s's reaction (joint frame, about its
                // reaction point) per unit q̈_j.
                let w = data.composite[s.max(j)] * motion_subspace(model, data, j);
                let f = rt * w.fixed_rows::<3>(3);
                let n = rt * (w.fixed_rows::<3>(0) - p.cross(&w.fixed_rows::<3>(3)));
                self.iteration_matrix[a * nf + b] +=
                    slip_friction_load_derivative(friction, st.lever_load[s], st.qd[s], d, &f0, &n0, &f, &n);
            }
        }
        if lu::factor(&mut self.iteration_matrix[..nf * nf], nf, &mut self.pivots[..nf]) {
            Ok(())
        } else {
            Err(StepError::SingularMassMatrix { time: st.time })
        }
    }

    /// Row `a` of the Newton matrix for the free rotor coordinate `c`, and
    /// the gear's coupling to its joint: the rotor's equation resists θ̈_m
    /// with J_m + γh·b_m, and the gear spring, whose end q* = θ_m/N moves by
    /// βh²/N and q̇* by γh/N per unit θ̈_m, with K/N² (K = γh·h_d + βh²·k of
    /// [`acceleration_stiffness`]); a unit θ̈_m raises the link's drive force
    /// by K/N and a unit q̈ lowers the rotor's load F/N by K/N.
    #[allow(clippy::too_many_arguments)]
    fn factor_rotor_row(
        &mut self,
        model: &Model,
        st: &State,
        open: &[f64],
        a: usize,
        c: usize,
        h: f64,
        beta: f64,
        gamma: f64,
    ) {
        let nf = self.free.len();
        let j = self.rotors[c - self.n];
        let drive = model.joints[j].drive;
        let (Some(spring), Some(rotor)) = (drive.spring(), drive.rotor()) else {
            unreachable!("rotors belong to motor drives")
        };
        let gear = spring_terms(spring, open, j, st, h, beta, gamma).stiffness;
        let ratio = rotor.gear_ratio;
        self.iteration_matrix[a * nf..(a + 1) * nf].fill(0.0);
        self.iteration_matrix[a * nf + a] = rotor_acceleration_inertia(&rotor, h, gamma) + gear / (ratio * ratio);
        let b = self.free_position[j];
        if b != usize::MAX {
            self.iteration_matrix[a * nf + b] = -gear / ratio;
            self.iteration_matrix[b * nf + a] = -gear / ratio;
        }
    }

    /// Drive forces (2.1), contact loads and friction (3.11)–(3.15), phase
    /// margins (3.16) and clearance margins (2.1) of every joint from the reactions in the workspace;
    /// fills the residuals of the free joints into `self.correction` and
    /// returns the largest one relative to its joint's force scale, the
    /// sum of the squares of these relative residuals and the coordinate
    /// (0-based) of the largest; then the rotors' torques, friction and
    /// margins and the residuals of the free ones. Counts the changes of each drive's engagement since
    /// the last call, unless `first` (the first iterate of a sub-step).
    #[inline(always)]
    /// `open` holds the clearance margins at the sub-step's start (empty for
    /// a zero-length solve): see [`drive_force_over_substep`].
    fn joint_forces(
        &mut self,
        model: &Model,
        data: &Data,
        st: &mut State,
        open: &[f64],
        first: bool,
    ) -> (f64, f64, usize) {
        let n = model.nq();
        // Slices of length n let the compiler drop the per-index bounds checks.
        let (q, qd, q_star, qd_star, phase) =
            (&st.q[..n], &st.qd[..n], &st.q_star[..n], &st.qd_star[..n], &st.phase[..n]);
        let (normal_load, lever_load) = (&mut st.normal_load[..n], &mut st.lever_load[..n]);
        let (drive_force_out, damping_force) = (&mut st.drive_force[..n], &mut st.damping_force[..n]);
        let (friction_force, margin) = (&mut st.friction_force[..n], &mut st.margin[..n]);
        let clearance_edge = &mut st.clearance_margin[..n];
        let (tau, reaction_force, reaction_moment) =
            (&data.tau[..n], &data.reaction_force[..n], &data.reaction_moment[..n]);
        let correction = &mut self.correction[..n + self.rotors.len()];
        let (engaged, engagement_changes) = (&mut self.engaged[..n], &mut self.engagement_changes[..n]);
        let mut worst: f64 = 0.0;
        let mut worst_joint = 0;
        let mut merit = 0.0;
        let mut k = 0;
        for (i, joint) in model.joints.iter().enumerate().take(n) {
            let tau = tau[i];
            let loads = friction_loads(joint.friction.as_ref(), &reaction_force[i], &reaction_moment[i], tau);
            let lever = loads.lever_load;
            normal_load[i] = loads.normal;
            lever_load[i] = lever;
            let coefficients = joint.friction.map(|f| f.coefficients);
            match joint.drive {
                Drive::Rigid => {
                    // A rigid drive supplies the generalized force plus the friction it overcomes.
                    let friction = prescribed_friction(coefficients, lever, qd[i]);
                    friction_force[i] = friction;
                    drive_force_out[i] = tau + friction;
                    damping_force[i] = 0.0;
                    margin[i] = f64::INFINITY;
                    clearance_edge[i] = f64::INFINITY;
                }
                Drive::Flexible { stiffness, damping, clearance }
                | Drive::Motor { stiffness, damping, clearance, .. } => {
                    let open_at_start = open.get(i).is_some_and(|&m| m < 0.0);
                    let drive = drive_force_over_substep(
                        stiffness,
                        damping,
                        clearance,
                        open_at_start,
                        q_star[i],
                        qd_star[i],
                        q[i],
                        qd[i],
                    );
                    let fd = drive.force;
                    if !first && drive.engaged != engaged[i] {
                        engagement_changes[i] += 1;
                    }
                    engaged[i] = drive.engaged;
                    drive_force_out[i] = fd;
                    damping_force[i] = drive.damping;
                    clearance_edge[i] =
                        if clearance > 0.0 { clearance_margin(clearance, q_star[i] - q[i]) } else { f64::INFINITY };
                    match phase[i] {
                        Phase::Stuck => {
                            // (3.16): F* of (3.17) with the joint held.
                            let held = stuck_friction(coefficients, lever, fd, loads.axial);
                            friction_force[i] = held.force;
                            margin[i] = held.margin;
                        }
                        Phase::Slipping(d) => {
                            let slip = slip_friction(joint.friction.as_ref(), lever, qd[i], d);
                            friction_force[i] = slip.force;
                            margin[i] = slip.margin;
                            // (3.9), (3.10): Σ D_si q̈_i + bias = F^d − F^f.
                            let residual = fd - slip.force - tau;
                            let scale = fd.abs() + slip.force.abs() + tau.abs() + joint_load_scale(data, joint, i);
                            let relative = residual / scale.max(f64::MIN_POSITIVE);
                            if relative.abs() > worst {
                                (worst, worst_joint) = (relative.abs(), i);
                            }
                            merit += relative * relative;
                            correction[k] = residual;
                            k += 1;
                        }
                        Phase::Prescribed => unreachable!("a flexible joint is never prescribed"),
                    }
                }
            }
        }
        // The rotors of motor drives, against the gear forces just computed.
        for (r, &j) in self.rotors.iter().enumerate() {
            let c = n + r;
            let Some(rotor) = model.joints[j].drive.rotor() else { continue };
            let slip = match st.phase[c] {
                Phase::Slipping(d) => Some(d),
                _ => None,
            };
            let torques = rotor_torques(&rotor, st.motor_torque[r], st.drive_force[j], st.qd[c], st.qdd[c], slip);
            st.friction_force[c] = torques.friction;
            st.margin[c] = torques.margin;
            st.gear_torque[r] = st.drive_force[j] / rotor.gear_ratio;
            if slip.is_some() {
                // The residual counts on the link side (×N), against its
                // joint's force scale, as the rotor's error does: a rotor is
                // solved as precisely as the link it drives.
                let joint = &model.joints[j];
                let link_scale = st.drive_force[j].abs()
                    + st.friction_force[j].abs()
                    + data.tau[j].abs()
                    + joint_load_scale(data, joint, j);
                let scale = torques.scale + link_scale / rotor.gear_ratio;
                let relative = torques.residual / scale.max(f64::MIN_POSITIVE);
                if relative.abs() > worst {
                    (worst, worst_joint) = (relative.abs(), c);
                }
                merit += relative * relative;
                correction[k] = torques.residual;
                k += 1;
            }
        }
        (worst, merit, worst_joint)
    }
}

/// The Newmark relations: q₁ = q₀ + h·q̇₀ + h²·((½ − β)·q̈₀ + β·q̈₁) and
/// q̇₁ = q̇₀ + h·((1 − γ)·q̈₀ + γ·q̈₁), from the start (q₀, q̇₀, q̈₀) and q̈₁.
#[inline(always)]
fn newmark_step(q0: f64, qd0: f64, qdd0: f64, qdd1: f64, h: f64, beta: f64, gamma: f64) -> (f64, f64) {
    (q0 + h * qd0 + h * h * ((0.5 - beta) * qdd0 + beta * qdd1), qd0 + h * ((1.0 - gamma) * qdd0 + gamma * qdd1))
}

/// Sets q and q̇ of joint `i` of `state` from its q̈ by [`newmark_step`]
/// from `start`.
#[inline(always)]
fn newmark(start: &State, state: &mut State, i: usize, h: f64, beta: f64, gamma: f64) {
    (state.q[i], state.qd[i]) = newmark_step(start.q[i], start.qd[i], start.qdd[i], state.qdd[i], h, beta, gamma);
}

/// Size of the reaction a joint carries, as a floor for relative residuals:
/// the force for a prismatic joint, the moment for a revolute one.
#[inline(always)]
fn joint_load_scale(data: &Data, joint: &Joint, i: usize) -> f64 {
    match joint.kind {
        JointKind::Prismatic => data.force[i].norm(),
        JointKind::Revolute => data.moment[i].norm(),
    }
}

/// The drive spring's resistance to its joint's acceleration in a sub-step.
struct DriveSpringTerms {
    /// γh·h_d + βh²·k while the drive transmits force, 0 otherwise.
    stiffness: f64,
}

/// [`DriveSpringTerms`] of joint `i`'s drive spring in the current iterate
/// `st` of a sub-step of length `h` (`open`: see [`drive_force_over_substep`]).
#[inline(always)]
fn spring_terms(
    spring: DriveSpring,
    open: &[f64],
    i: usize,
    st: &State,
    h: f64,
    beta: f64,
    gamma: f64,
) -> DriveSpringTerms {
    let DriveSpring { stiffness, damping, clearance } = spring;
    let open_at_start = open.get(i).is_some_and(|&m| m < 0.0);
    let drive = drive_force_over_substep(
        stiffness,
        damping,
        clearance,
        open_at_start,
        st.q_star[i],
        st.qd_star[i],
        st.q[i],
        st.qd[i],
    );
    DriveSpringTerms { stiffness: acceleration_stiffness(stiffness, damping, drive.engaged, h, beta, gamma) }
}
