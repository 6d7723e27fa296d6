//! One sub-step of the iterative Newmark method: accelerations, joint
//! reactions and friction forces made mutually consistent.

use super::simulator::Simulator;
use super::state::{Phase, State};
use crate::algorithms::crba::{crba, motion_subspace};
use crate::algorithms::kinematics::{forward_kinematics, joint_transforms, joint_transforms_near_anchors, reaction_point};
use crate::algorithms::lu;
use crate::algorithms::rnea::{joint_reaction, rnea};
use crate::error::StepError;
use crate::forces::drive::drive_force as drive_force_of;
use crate::forces::friction::contact_load;
use crate::model::{Drive, Joint};

/// True if the joint has static friction that can hold it.
pub(crate) fn holds_statically(joint: &Joint) -> bool {
    joint.friction.is_some_and(|f| f.coefficients.mu_static > 0.0)
}

impl Simulator {
    /// Solves the state at the current time with the current phases, without
    /// advancing (a zero-length sub-step): used at initialization, at the start
    /// of an interval and after a phase change. It also forgets the Newton
    /// matrix and the predictor history, so that everything after it depends
    /// only on the state and the inputs (an exact continuation after a state
    /// is restored).
    pub(crate) fn evaluate(&mut self) -> Result<(), StepError> {
        self.start.take_step_start(&mut self.state);
        self.newton_valid = false;
        self.predictor_depth = 0;
        self.qdd_history[0].copy_from_slice(&self.start.qdd);
        self.solve_out_of_line(self.start.time)?;
        self.qdd_history[0].copy_from_slice(&self.refined_qdd);
        Ok(())
    }

    /// Solves the sub-step from `self.start` to time `t` with the phases in
    /// `self.state`; the result lands in `self.state` (q, q̇, q̈, forces,
    /// reactions, margins) and in the workspace.
    ///
    /// Newmark: q₁ = q₀ + h·q̇₀ + h²·((½ − β)·q̈₀ + β·q̈₁), q̇₁ = q̇₀ + h·((1 − γ)·q̈₀ + γ·q̈₁).
    /// The unknowns q̈₁ of the slipping joints start from q̈ extrapolated
    /// quadratically from the starts of this and the last two sub-steps (the
    /// first evaluation then mostly meets the tolerance, see
    /// [`Simulator::refine_acceleration`]) and are corrected with the Newton matrix
    /// (see `factor_newton_matrix`) until the residual of (3.9),
    /// F^d − F^f − (M q̈ + bias), is below the tolerance relative to the
    /// joint's force scale: then accelerations, reactions and friction agree.
    /// The Newton matrix is kept across sub-steps of the same length and
    /// the same slipping joints (it changes by O(h) per sub-step, which only
    /// slows convergence slightly) and rebuilt when an iteration needs more
    /// than two corrections.
    #[inline(always)]
    pub(crate) fn solve(&mut self, t: f64) -> Result<(), StepError> {
        let h = t - self.start.time;
        let settings = self.model.integrator;
        let (beta, gamma) = (settings.beta, settings.gamma);
        self.state.time = t;
        self.predict(t, h);
        let nf = self.free.len();
        // Grid sub-steps differ in length by rounding only.
        let newton_fits = self.newton_valid
            && (self.newton_h - h).abs() <= 1e-9 * h
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
        for iteration in 1..=settings.max_iterations {
            // q and q̇ of the free joints follow their q̈ (see `newmark`).
            self.update_kinematics();
            rnea(&self.model, &mut self.data, &self.state.qd, &self.state.qdd);
            // Friction needs the reactions of the joints with friction; the
            // others are reported at the end of the interval.
            for (i, joint) in self.model.joints.iter().enumerate() {
                if joint.friction.is_some() {
                    joint_reaction(&self.model, &mut self.data, i);
                }
            }
            let (residual, merit) = self.joint_forces();
            self.iterations += 1;
            if !residual.is_finite() {
                return Err(StepError::NonFiniteState { time: t });
            }
            if residual <= settings.tolerance {
                self.refine_acceleration();
                return Ok(());
            }
            if iteration == settings.max_iterations {
                return Err(StepError::NotConverged { time: t, iterations: iteration, residual });
            }
            if iteration > PLAIN_NEWTON_STEPS && merit >= accepted_merit {
                for (k, &i) in self.free.iter().enumerate() {
                    self.newton_step[k] *= 0.5;
                    self.state.qdd[i] = self.accepted_qdd[k] + self.newton_step[k];
                    newmark(&self.start, &mut self.state, i, h, beta, gamma);
                }
                continue;
            }
            accepted_merit = merit;
            if !self.newton_valid || iteration > 2 {
                // The mass matrix and the friction Jacobian need the frame-0
                // kinematics, of the coordinates the inverse dynamics used.
                forward_kinematics(&self.model, &mut self.data, &self.kinematics_q);
                crba(&self.model, &mut self.data);
                self.factor_newton_matrix(h, beta, gamma)?;
                self.newton_valid = true;
                self.newton_h = h;
                self.newton_free.clear();
                self.newton_free.extend_from_slice(&self.free);
            }
            lu::solve(&self.iteration_matrix, nf, &self.pivots, &mut self.correction[..nf]);
            for (k, &i) in self.free.iter().enumerate() {
                self.accepted_qdd[k] = self.state.qdd[i];
                self.newton_step[k] = self.correction[k];
                self.state.qdd[i] += self.correction[k];
                newmark(&self.start, &mut self.state, i, h, beta, gamma);
            }
        }
        unreachable!("the loop returns on its last iteration")
    }

    /// [`Simulator::solve`] as a call, for the solves outside the stepping
    /// loop's common path (evaluations, locating a transition), which need
    /// not be inlined into it.
    #[inline(never)]
    pub(crate) fn solve_out_of_line(&mut self, t: f64) -> Result<(), StepError> {
        self.solve(t)
    }

    /// Sets up the sub-step to time `t` (length `h`): the drive inputs at
    /// `t`, the prescribed motion of rigid joints, stuck joints held at their
    /// start, the list of free (slipping) joints and their predicted q̈:
    /// the Lagrange extrapolation of the last three refined accelerations,
    /// and the q, q̇ that the Newmark relations give for it.
    #[inline(always)]
    fn predict(&mut self, t: f64, h: f64) {
        let n = self.model.nq();
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
        // Slices of length n let the compiler drop the per-index bounds checks.
        let (s, st) = (&self.start, &mut self.state);
        let (q, qd, qdd) = (&mut st.q[..n], &mut st.qd[..n], &mut st.qdd[..n]);
        let (q_star, qd_star, phase) = (&mut st.q_star[..n], &mut st.qd_star[..n], &st.phase[..n]);
        let (start_q, start_qd, start_qdd) = (&s.q[..n], &s.qd[..n], &s.qdd[..n]);
        let (beta, gamma) = (self.model.integrator.beta, self.model.integrator.gamma);
        let [h0, h1, h2] = &self.qdd_history;
        let (h0, h1, h2) = (&h0[..n], &h1[..n], &h2[..n]);
        self.free.clear();
        for i in 0..n {
            let (qs, qds, qdds) = self.inputs.eval(i, t);
            q_star[i] = qs;
            qd_star[i] = qds;
            match phase[i] {
                Phase::Prescribed => {
                    q[i] = qs;
                    qd[i] = qds;
                    qdd[i] = qdds;
                }
                Phase::Stuck => {
                    q[i] = start_q[i];
                    qd[i] = 0.0;
                    qdd[i] = 0.0;
                }
                Phase::Slipping(_) => {
                    self.free.push(i);
                    let qdd_i = w0 * h0[i] + w1 * h1[i] + w2 * h2[i];
                    qdd[i] = qdd_i;
                    (q[i], qd[i]) = newmark_step(start_q[i], start_qd[i], start_qdd[i], qdd_i, h, beta, gamma);
                }
            }
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
    fn refine_acceleration(&mut self) {
        self.refined_qdd.copy_from_slice(&self.state.qdd);
        let nf = self.free.len();
        if nf == 0 || !self.newton_valid {
            return;
        }
        lu::solve(&self.iteration_matrix, nf, &self.pivots, &mut self.correction[..nf]);
        for (k, &i) in self.free.iter().enumerate() {
            self.refined_qdd[i] += self.correction[k];
        }
    }

    /// The DH transforms of the current coordinates, skipped when they
    /// differ from the last ones by rounding only (a Newton correction moves
    /// q by βh²·Δq̈, often below 1e-15). The first ones of an interval are
    /// computed by the library's sin_cos, the others expanded about them:
    /// either way a function of the interval's start and inputs only.
    #[inline(always)]
    fn update_kinematics(&mut self) {
        if !self.kinematics_current {
            joint_transforms(&self.model, &mut self.data, &self.state.q);
            self.kinematics_q.copy_from_slice(&self.state.q);
            self.kinematics_current = true;
            return;
        }
        let moved = self.state.q.iter().zip(&self.kinematics_q).any(|(a, b)| (a - b).abs() > 1e-15 * (1.0 + a.abs()));
        if moved {
            joint_transforms_near_anchors(&self.model, &mut self.data, &self.state.q);
            self.kinematics_q.copy_from_slice(&self.state.q);
            self.kinematics_current = true;
        }
    }

    /// Builds and factors the Newton matrix of the free joints,
    /// M_ff + γh·H_f + βh²·K_f + ∂F^f/∂q̈: the mass matrix of the sub-step
    /// start, the drive terms through the Newmark relations, and the friction
    /// Jacobian. Friction depends on q̈ through the reactions, which are linear
    /// in q̈: joint j's unit acceleration adds the spatial force I^c_max(s,j)·S_j
    /// to the reaction of joint s. Without this term the iteration only
    /// contracts slowly on long chains with much friction.
    fn factor_newton_matrix(&mut self, h: f64, beta: f64, gamma: f64) -> Result<(), StepError> {
        let (model, data, st) = (&self.model, &self.data, &self.state);
        let nf = self.free.len();
        for (a, &s) in self.free.iter().enumerate() {
            for (b, &j) in self.free.iter().enumerate() {
                self.iteration_matrix[a * nf + b] = data.mass_matrix[(s, j)];
            }
            let joint = &model.joints[s];
            if let Drive::Flexible { stiffness, damping, clearance } = joint.drive {
                if (st.q_star[s] - st.q[s]).abs() >= clearance {
                    self.iteration_matrix[a * nf + a] += gamma * h * damping + beta * h * h * stiffness;
                }
            }
            let (Some(friction), Phase::Slipping(d)) = (joint.friction, st.phase[s]) else { continue };
            let d = d as f64;
            let c = friction.coefficients;
            self.iteration_matrix[a * nf + a] += d * st.lever_load[s] * c.kinetic_slope(st.qd[s]) * gamma * h;
            let mu = c.kinetic(st.qd[s]);
            if mu == 0.0 {
                continue;
            }
            let (f0, n0) = (data.reaction_force[s], data.reaction_moment[s]);
            let rt = data.joint_rotation[s].transpose();
            let p = reaction_point(model, data, s);
            let size = f0.norm() + n0.norm();
            for (b, &j) in self.free.iter().enumerate() {
                let w = data.composite[s.max(j)] * motion_subspace(model, data, j);
                let f = rt * w.fixed_rows::<3>(3);
                let n = rt * (w.fixed_rows::<3>(0) - p.cross(&w.fixed_rows::<3>(3)));
                let step = 1e-7 * size.max(1e-9) / (f.norm() + n.norm()).max(1e-300);
                let shifted = contact_load(&friction.geometry, &(f0 + f * step), &(n0 + n * step)).lever_load;
                self.iteration_matrix[a * nf + b] += d * mu * (shifted - st.lever_load[s]) / step;
            }
        }
        for k in 0..nf {
            self.newton_diagonal[k] = self.iteration_matrix[k * nf + k];
        }
        if lu::factor(&mut self.iteration_matrix[..nf * nf], nf, &mut self.pivots[..nf]) {
            Ok(())
        } else {
            Err(StepError::SingularMassMatrix { time: st.time })
        }
    }

    /// Drive forces (2.1), contact loads and friction (3.11)–(3.15), phase
    /// margins (3.16) of every joint from the reactions in the workspace;
    /// fills the residuals of the free joints into `self.correction` and
    /// returns the largest one relative to its joint's force scale, and the
    /// sum of the squares of these relative residuals.
    #[inline(always)]
    fn joint_forces(&mut self) -> (f64, f64) {
        let (model, data, st) = (&self.model, &self.data, &mut self.state);
        let n = model.nq();
        // Slices of length n let the compiler drop the per-index bounds checks.
        let (q, qd, q_star, qd_star, phase) = (&st.q[..n], &st.qd[..n], &st.q_star[..n], &st.qd_star[..n], &st.phase[..n]);
        let (normal_load, lever_load) = (&mut st.normal_load[..n], &mut st.lever_load[..n]);
        let (drive_force, damping_force) = (&mut st.drive_force[..n], &mut st.damping_force[..n]);
        let (friction_force, margin) = (&mut st.friction_force[..n], &mut st.margin[..n]);
        let (tau, reaction_force, reaction_moment) = (&data.tau[..n], &data.reaction_force[..n], &data.reaction_moment[..n]);
        let correction = &mut self.correction[..n];
        let mut worst: f64 = 0.0;
        let mut merit = 0.0;
        let mut k = 0;
        for (i, joint) in model.joints.iter().enumerate().take(n) {
            let tau = tau[i];
            let (normal, lever) = match joint.friction {
                Some(f) => {
                    let load = contact_load(&f.geometry, &reaction_force[i], &reaction_moment[i]);
                    (load.normal, load.lever_load)
                }
                None => (0.0, 0.0),
            };
            normal_load[i] = normal;
            lever_load[i] = lever;
            let coefficients = joint.friction.map(|f| f.coefficients);
            match joint.drive {
                Drive::Rigid => {
                    // A rigid drive supplies the generalized force plus the friction it overcomes.
                    let friction = coefficients.map_or(0.0, |c| c.kinetic(qd[i]) * lever * sign(qd[i]));
                    friction_force[i] = friction;
                    drive_force[i] = tau + friction;
                    damping_force[i] = 0.0;
                    margin[i] = f64::INFINITY;
                }
                Drive::Flexible { stiffness, damping, clearance } => {
                    let fd = drive_force_of(stiffness, damping, clearance, q_star[i], qd_star[i], q[i], qd[i]);
                    drive_force[i] = fd;
                    damping_force[i] =
                        if (q_star[i] - q[i]).abs() < clearance { 0.0 } else { damping * (qd_star[i] - qd[i]) };
                    let static_limit = coefficients.map_or(0.0, |c| c.mu_static) * lever;
                    match phase[i] {
                        Phase::Stuck => {
                            // (3.16)–(3.18): F* = τ is the axial reaction with the joint held.
                            friction_force[i] = fd - tau;
                            margin[i] = static_limit - (fd - tau).abs();
                        }
                        Phase::Slipping(d) => {
                            let d = d as f64;
                            let friction = coefficients.map_or(0.0, |c| c.kinetic(qd[i])) * lever * d;
                            friction_force[i] = friction;
                            margin[i] = if holds_statically(joint) { d * qd[i] } else { f64::INFINITY };
                            // (3.9), (3.10): Σ D_si q̈_i + bias = F^d − F^f.
                            let residual = fd - friction - tau;
                            let scale = fd.abs() + friction.abs() + tau.abs() + joint_load_scale(data, joint, i);
                            let relative = residual / scale.max(f64::MIN_POSITIVE);
                            worst = worst.max(relative.abs());
                            merit += relative * relative;
                            correction[k] = residual;
                            k += 1;
                        }
                        Phase::Prescribed => unreachable!("a flexible joint is never prescribed"),
                    }
                }
            }
        }
        (worst, merit)
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
fn joint_load_scale(data: &crate::data::Data, joint: &Joint, i: usize) -> f64 {
    match joint.kind {
        crate::model::JointKind::Prismatic => data.force[i].norm(),
        crate::model::JointKind::Revolute => data.moment[i].norm(),
    }
}

#[inline(always)]
fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}
