//! A whole experiment in one call ([`stickslip_run_experiment`](super::exports::stickslip_run_experiment)):
//! the inputs at every communication point go in, the outputs at every
//! point come out, and, on request, their sensitivities to parameters and
//! start values. The run is the FMI sequence a master would call —
//! fmi2EnterInitializationMode, the first inputs, fmi2ExitInitializationMode,
//! then per point the inputs, fmi2DoStep and fmi2GetReal — made by the same
//! [`Instance`] methods, so its outputs are the FMI path's bit for bit; what
//! it saves is a master's per-point calls (for the fit: Python's).
//!
//! The sensitivities are internal numerical differentiation (Bock): the run
//! records its sub-step schedule, and copies of the instance as it was
//! before initialization, each with one value moved by its step, replay that
//! schedule ([`Simulator::replay_schedule`](crate::Simulator::replay_schedule)).
//! Their differences are derivatives of the discrete scheme with its step
//! sizes and stick/slip decisions frozen: no error-control noise, so the
//! step can be 10⁻⁶ of the value, not the 10⁻³ of a range that differences
//! of free runs need. A column whose replays left the plan (an event
//! pattern that changed within the step) is reported in `departures`; the
//! caller falls back to differences of free runs there.

use super::instance::Instance;
use super::status::{Fault, Outcome, Status};
use crate::stepper::PlannedSubStep;
use fmi_sys::fmi2::{fmi2Boolean, fmi2Integer, fmi2ValueReference};
use std::sync::Arc;

/// The inputs and outputs of an experiment, row-major per communication
/// point.
pub(crate) struct Experiment<'a> {
    /// The communication points, s (at least one, increasing).
    pub time: &'a [f64],
    /// Drive inputs (q*, q̇*, q̈* by value reference) and their values,
    /// points × inputs.
    pub drive_vrs: &'a [fmi2ValueReference],
    pub drive: &'a [f64],
    /// Motor torques τ_m and their values, rates and accelerations (set with
    /// fmi2SetRealInputDerivatives orders 1 and 2), each points × torques.
    pub torque_vrs: &'a [fmi2ValueReference],
    pub torques: [&'a [f64]; 3],
    /// The outputs read at every point (Real or Boolean, as 0/1).
    pub output_vrs: &'a [fmi2ValueReference],
}

/// What the sensitivities are taken with respect to, and where they go.
pub(crate) struct Sensitivities<'a> {
    /// Real parameters or start values.
    pub vrs: &'a [fmi2ValueReference],
    /// The step of each (its units, positive).
    pub steps: &'a [f64],
    /// Central differences (two replays a column) instead of forward ones
    /// (one a column and one at the values themselves).
    pub central: bool,
    /// Threads for the replays (0: as many as the processor has).
    pub threads: usize,
    /// ∂output/∂value, points × outputs × values.
    pub out: &'a mut [f64],
    /// Per value: how often its replays left the plan (0: the column is the
    /// derivative of the run's scheme); u64::MAX where a replay failed.
    pub departures: &'a mut [u64],
}

/// The instance before initialization, which the replays copy, shared
/// by their threads.
struct Before(Instance);

// SAFETY: the instance comes from `Instance::silent_copy`: its logger sinks
// nothing and holds no pointer of the master's; everything else in an
// instance is owned data. The threads only read it (`silent_copy` takes
// `&self`); each replays on a copy of its own.
unsafe impl Sync for Before {}

impl Experiment<'_> {
    fn check(&self) -> Result<usize, Fault> {
        let n = self.time.len();
        if n == 0 {
            return Err(Fault::error("an experiment needs at least one communication point".to_string()));
        }
        if let Some(k) = self.time.iter().position(|t| !t.is_finite()) {
            return Err(Fault::error(format!("time[{k}] = {} is not finite", self.time[k])));
        }
        if let Some(k) = self.time.windows(2).position(|w| w[1] <= w[0]) {
            return Err(Fault::error(format!(
                "time[{}] = {} s does not follow time[{k}] = {} s: the points must increase",
                k + 1,
                self.time[k + 1],
                self.time[k]
            )));
        }
        if self.drive.len() != n * self.drive_vrs.len() {
            return Err(Fault::error(format!(
                "drive has {} values, not points × inputs = {n} × {}",
                self.drive.len(),
                self.drive_vrs.len()
            )));
        }
        for (name, values) in ["torque", "torque_rate", "torque_accel"].iter().zip(self.torques) {
            if values.len() != n * self.torque_vrs.len() {
                return Err(Fault::error(format!(
                    "{name} has {} values, not points × torques = {n} × {}",
                    values.len(),
                    self.torque_vrs.len()
                )));
            }
        }
        Ok(n)
    }

    /// Sets the inputs of point `k`.
    fn set_inputs(&self, inst: &mut Instance, k: usize) -> Result<(), Fault> {
        let nd = self.drive_vrs.len();
        if nd > 0 {
            inst.set_real(self.drive_vrs, &self.drive[k * nd..(k + 1) * nd])?;
        }
        let nt = self.torque_vrs.len();
        if nt > 0 {
            let row = |a: &[f64]| a[k * nt..(k + 1) * nt].to_vec();
            inst.set_real(self.torque_vrs, &row(self.torques[0]))?;
            for order in [1, 2] {
                let orders = vec![order as fmi2Integer; nt];
                inst.set_real_input_derivatives(self.torque_vrs, &orders, &row(self.torques[order]))?;
            }
        }
        Ok(())
    }

    /// Reads the outputs into `row`: the Real ones by one fmi2GetReal, as a
    /// master reads them; a Boolean one as 0 or 1.
    fn read(&self, inst: &mut Instance, row: &mut [f64]) -> Result<(), Fault> {
        let boolean = |inst: &Instance, vr: fmi2ValueReference| {
            inst.variables().get(vr as usize).is_some_and(|v| matches!(v.ty, super::description::Type::Boolean { .. }))
        };
        if !self.output_vrs.iter().any(|&vr| boolean(inst, vr)) {
            inst.get_real(self.output_vrs, row)?;
            return Ok(());
        }
        for (&vr, x) in self.output_vrs.iter().zip(row.iter_mut()) {
            if boolean(inst, vr) {
                let mut b: [fmi2Boolean; 1] = [0];
                inst.get_boolean(&[vr], &mut b)?;
                *x = f64::from(u8::from(b[0] != 0));
            } else {
                inst.get_real(&[vr], std::slice::from_mut(x))?;
            }
        }
        Ok(())
    }

    /// Initializes `inst` (instantiated, its values set) with the inputs of
    /// the first point, calls `started` on it, and steps through every point
    /// into `out` (points × outputs). On failure: the points filled and the
    /// fault; the rest of `out` is left as it was.
    ///
    /// An instance already in step mode (`initialize` false) goes on from
    /// its time, which must be the first point's.
    fn run(
        &self,
        inst: &mut Instance,
        out: &mut [f64],
        initialize: bool,
        started: impl FnOnce(&mut Instance),
    ) -> Result<(usize, Status), (usize, Fault)> {
        let no = self.output_vrs.len();
        let mut worst = Status::Ok;
        let mut note = |s: Status| {
            if s == Status::Warning {
                worst = Status::Warning;
            }
        };
        let setup = (|| -> Outcome {
            if !initialize {
                let now = inst.time();
                if (self.time[0] - now).abs() > 1e-9 * now.abs().max(1.0) {
                    return Err(Fault::error(format!(
                        "time[0] = {} s is not the FMU's time {now} s: an experiment goes on from where the FMU is",
                        self.time[0]
                    )));
                }
                self.read(inst, &mut out[..no])?;
                return Ok(Status::Ok);
            }
            note(inst.enter_initialization_mode()?);
            self.set_inputs(inst, 0)?;
            let status = inst.exit_initialization_mode()?;
            self.read(inst, &mut out[..no])?;
            Ok(status)
        })();
        note(setup.map_err(|f| (0, f))?);
        started(inst);
        for k in 0..self.time.len() - 1 {
            let step = (|| -> Outcome {
                self.set_inputs(inst, k)?;
                let status = inst.do_step(self.time[k], self.time[k + 1] - self.time[k])?;
                self.read(inst, &mut out[(k + 1) * no..(k + 2) * no])?;
                Ok(status)
            })();
            note(step.map_err(|f| (k + 1, f))?);
        }
        Ok((self.time.len(), worst))
    }
}

impl Instance {
    /// The experiment `e` from this instance's values, its outputs into
    /// `out`, the points reached into `reached`; with `sensitivities`, theirs
    /// too. An instantiated instance is initialized with the first point's
    /// inputs; one in step mode goes on from its time, the first point's
    /// (a master that runs an experiment in parts: no sensitivities then,
    /// which need the start). Leaves the instance where the last step left
    /// it.
    pub(crate) fn run_experiment(
        &mut self,
        e: &Experiment,
        out: &mut [f64],
        reached: &mut usize,
        sensitivities: Option<Sensitivities>,
    ) -> Outcome {
        *reached = 0;
        let n = e.check()?;
        let no = e.output_vrs.len();
        if out.len() != n * no {
            return Err(Fault::error(format!("outputs has {} values, not points × outputs = {n} × {no}", out.len())));
        }
        let initialize = self.lifecycle().is_configuring();
        if let Some(s) = &sensitivities {
            if !initialize {
                return Err(Fault::error(
                    "sensitivities are taken from the start: call it before fmi2EnterInitializationMode".to_string(),
                ));
            }
            check_sensitivities(self, s, n * no)?;
        }
        let before = sensitivities.as_ref().map(|_| Before(self.silent_copy()));
        let recording = sensitivities.is_some();
        let result = e.run(self, out, initialize, |inst| {
            if recording {
                inst.simulator_mut().record_schedule();
            }
        });
        let plan: Arc<[PlannedSubStep]> = self.simulator_mut().take_schedule().into();
        let status = match result {
            Ok((points, status)) => {
                *reached = points;
                status
            }
            Err((points, fault)) => {
                *reached = points;
                return Err(fault);
            }
        };
        if let (Some(s), Some(before)) = (sensitivities, before) {
            differentiate(e, &before, &plan, s, out)?;
        }
        Ok(status)
    }
}

fn check_sensitivities(inst: &Instance, s: &Sensitivities, size: usize) -> Result<(), Fault> {
    let p = s.vrs.len();
    if s.steps.len() != p || s.departures.len() != p || s.out.len() != size * p {
        return Err(Fault::error(format!(
            "sensitivities: {p} values need {p} steps, {p} departures and points × outputs × {p} = {} derivatives",
            size * p
        )));
    }
    for (&vr, &step) in s.vrs.iter().zip(s.steps) {
        let (_, name) = inst.sensitivity_variable(vr)?;
        if !(step.is_finite() && step > 0.0) {
            return Err(Fault::error(format!("the step of `{name}` is {step}: it must be positive and finite")));
        }
    }
    Ok(())
}

/// The replays of [`Instance::run_experiment`]'s sensitivities.
fn differentiate(
    e: &Experiment,
    before: &Before,
    plan: &Arc<[PlannedSubStep]>,
    s: Sensitivities,
    run: &[f64],
) -> Result<(), Fault> {
    let size = run.len();
    let p = s.vrs.len();
    // Each replay: (column, the signed change of its value), or the base
    // replay at the values themselves (forward differences).
    let mut jobs: Vec<(Option<usize>, f64)> = Vec::with_capacity(2 * p + 1);
    if !s.central {
        jobs.push((None, 0.0));
    }
    for j in 0..p {
        jobs.push((Some(j), s.steps[j]));
        if s.central {
            jobs.push((Some(j), -s.steps[j]));
        }
    }
    let replay = |&(column, change): &(Option<usize>, f64)| -> Replayed {
        // A value its range or the model's relations refuse (μ_k ≤ μ_s, at
        // initialization) is moved the other way: by as much (forward
        // differences), or by twice as much (central: the column becomes a
        // one-sided difference with the other replay).
        let first = replay_one(e, before, plan, column.map(|j| (s.vrs[j], change)));
        let other_way = if s.central { -2.0 * change } else { -change };
        match (column, &first) {
            (Some(j), Replayed { departures: u64::MAX, refused: true, .. }) => {
                replay_one(e, before, plan, Some((s.vrs[j], other_way)))
            }
            _ => first,
        }
    };
    let mut results = in_threads(&jobs, s.threads, &replay);
    // A column whose replays left the plan is taken again with smaller
    // steps (an event pattern that the step changed may hold under a
    // smaller one), at most twice.
    for _ in 0..RETRIES {
        let departed: Vec<usize> = (0..jobs.len())
            .filter(|&k| jobs[k].0.is_some() && results[k].departures > 0 && results[k].departures != u64::MAX)
            .collect();
        if departed.is_empty() {
            break;
        }
        let again: Vec<(Option<usize>, f64)> =
            departed.iter().map(|&k| (jobs[k].0, jobs[k].1 * RETRY_FACTOR)).collect();
        for (k, r) in departed.iter().zip(in_threads(&again, s.threads, &replay)) {
            if r.departures < results[*k].departures {
                results[*k] = r;
            }
        }
    }
    let out = s.out;
    out.fill(f64::NAN);
    let base = if s.central { None } else { Some(&results[0]) };
    for j in 0..p {
        let mine: Vec<&Replayed> =
            jobs.iter().zip(&results).filter(|((c, _), _)| *c == Some(j)).map(|(_, r)| r).collect();
        let (a, b) = match (s.central, base) {
            (true, _) => (mine[0], mine[1]),
            (false, Some(base)) => (mine[0], base),
            (false, None) => unreachable!("forward differences have a base replay"),
        };
        let dx = a.applied - b.applied;
        if a.departures == u64::MAX || b.departures == u64::MAX || dx == 0.0 {
            s.departures[j] = u64::MAX;
            continue;
        }
        s.departures[j] = a.departures.saturating_add(b.departures);
        for i in 0..size {
            out[i * p + j] = (a.values[i] - b.values[i]) / dx;
        }
    }
    Ok(())
}

/// How often a departed column is taken again, each time with its step
/// times [`RETRY_FACTOR`].
const RETRIES: usize = 2;
const RETRY_FACTOR: f64 = 0.0625;

/// One replay's outputs, the change of its value that was applied, and
/// its departures (u64::MAX: it failed; `refused`: at the change itself,
/// when set or at initialization).
struct Replayed {
    values: Vec<f64>,
    applied: f64,
    departures: u64,
    refused: bool,
}

/// A replay of `plan` from `before` with `change` = (value reference, by
/// how much) applied, or none.
fn replay_one(
    e: &Experiment,
    before: &Before,
    plan: &Arc<[PlannedSubStep]>,
    change: Option<(fmi2ValueReference, f64)>,
) -> Replayed {
    let size = e.time.len() * e.output_vrs.len();
    let mut inst = before.0.silent_copy();
    let mut values = vec![f64::NAN; size];
    let failed = |values, refused| Replayed { values, applied: 0.0, departures: u64::MAX, refused };
    let mut applied = 0.0;
    if let Some((vr, dx)) = change {
        let Ok((x, _)) = inst.sensitivity_variable(vr) else { return failed(values, false) };
        if inst.set_real(&[vr], &[x + dx]).is_err() {
            return failed(values, true);
        }
        applied = dx;
    }
    let plan = Arc::clone(plan);
    match e.run(&mut inst, &mut values, true, |inst| inst.simulator_mut().replay_schedule(plan)) {
        Ok(_) => {
            Replayed { values, applied, departures: inst.simulator().schedule_departures() as u64, refused: false }
        }
        Err((reached, _)) => failed(values, reached == 0),
    }
}

/// `f` of every job, in at most `threads` threads (0: the processor's).
fn in_threads<J: Sync, R: Send>(jobs: &[J], threads: usize, f: &(dyn Fn(&J) -> R + Sync)) -> Vec<R> {
    let threads = if threads == 0 { std::thread::available_parallelism().map_or(1, |n| n.get()) } else { threads };
    let threads = threads.clamp(1, jobs.len().max(1));
    if threads == 1 {
        return jobs.iter().map(f).collect();
    }
    let next = std::sync::atomic::AtomicUsize::new(0);
    let mut results: Vec<Option<R>> = (0..jobs.len()).map(|_| None).collect();
    let slots = std::sync::Mutex::new(&mut results);
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| loop {
                let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                if k >= jobs.len() {
                    break;
                }
                let r = f(&jobs[k]);
                slots.lock().unwrap_or_else(std::sync::PoisonError::into_inner)[k] = Some(r);
            });
        }
    });
    results.into_iter().map(|r| r.expect("every job ran")).collect()
}
