//! The model's rigid-body dynamics at given states, for checking a model
//! against another rigid-body library (the URDF tests compare it with
//! Pinocchio) and for users who want the joint loads of a motion.
//!
//! Usage: inverse_dynamics --model FILE --states IN.csv --out OUT.csv [--set NAME[i]=VALUE ...]
//!
//! `--set` changes a tunable parameter of the model file by its FMU name
//! (`m[3]`, `d_A[1]`, `mu_k[1]`, ...), checked as the FMU checks it.
//!
//! IN.csv has a header and the columns q[1..n], qd[1..n], qdd[1..n] (any
//! order, named so). For each row OUT.csv has: `tau[i]` (the generalized
//! force M(q)·q̈ + bias(q, q̇) including gravity, N·m or N), `f[i,k]` and
//! `n[i,k]` (force and moment that link i−1 exerts on link i at the joint's
//! origin, resolved in link i's frame as the model source describes it: the
//! URDF child link frame), `x_E[k]` (end point in the base frame),
//! `M[i,j]` (the joint-space mass matrix), and for each joint i with friction
//! the loads its friction law reads: `load[i]` (the lever load L, N or N·m:
//! the dry friction is μ·L, bearing radii included, (3.11)–(3.15)) and
//! `axial[i]` (F* of (3.17), N or N·m, the reaction along the joint axis,
//! which equals `tau[i]`), all at full precision.
//!
//! `tau`, `load` and `axial` come from `algorithms::inverse_dynamics` (the
//! engine's `friction_loads` on the joint reactions of `algorithms::rnea`, as
//! the stepper computes them at every iterate), which the FMU library's
//! `stickslip_inverse_dynamics` export also runs for the fit's
//! equation-error stage (python/stickslip/fit/idim.py): the same numbers.
//! With the measured q, q̇, q̈ they are the engine's for that state, whether
//! the joint slips or sticks. The friction of a slipping joint is then
//! μ(q̇)·L·sgn q̇ + b·q̇ and its drive force F^d = τ + F^f (3.9), (3.10); a
//! stuck one can be held while |F^d − F*| ≤ μ_s·L (3.16).

use std::io::Write;
use stick_slip_manipulator::algorithms::crba::crba;
use stick_slip_manipulator::algorithms::inverse_dynamics::{inverse_dynamics, joint_friction_loads, with_settings};
use stick_slip_manipulator::algorithms::kinematics::end_point;
use stick_slip_manipulator::{Data, Model};

const USAGE: &str = "usage: inverse_dynamics --model FILE --states IN.csv --out OUT.csv [--set NAME[i]=VALUE ...]";

fn main() {
    if let Err(e) = run() {
        eprintln!("inverse_dynamics: {e}");
        std::process::exit(2);
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let (mut model_path, mut states, mut out) = (None, None, None);
    let mut sets = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().ok_or_else(|| format!("{a} needs a value"));
        match a.as_str() {
            "--model" => model_path = Some(value()?),
            "--states" => states = Some(value()?),
            "--out" => out = Some(value()?),
            "--set" => sets.push(value()?),
            _ => return Err(format!("unknown argument {a} ({USAGE})").into()),
        }
    }
    let model = with_settings(Model::from_file(model_path.ok_or(USAGE)?)?, &sets).map_err(|e| format!("--set: {e}"))?;
    for warning in &model.warnings {
        eprintln!("inverse_dynamics: warning: {warning}");
    }
    let states = states.ok_or(USAGE)?;
    let text = std::fs::read_to_string(&states).map_err(|e| format!("cannot read {states}: {e}"))?;
    let n = model.nq();
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    let header: Vec<&str> =
        lines.next().ok_or("the states file is empty")?.split(',').map(|s| s.trim().trim_matches('"')).collect();
    let column = |name: String| header.iter().position(|h| *h == name).ok_or(format!("{states}: no column `{name}`"));
    let mut columns = Vec::with_capacity(3 * n);
    for base in ["q", "qd", "qdd"] {
        for i in 1..=n {
            columns.push(column(format!("{base}[{i}]"))?);
        }
    }
    let mut data = Data::new(&model);
    let mut w = std::io::BufWriter::new(std::fs::File::create(out.ok_or(USAGE)?)?);
    let mut names: Vec<String> = (1..=n).map(|i| format!("tau[{i}]")).collect();
    for i in 1..=n {
        names.extend((1..=3).map(|k| format!("f[{i},{k}]")));
        names.extend((1..=3).map(|k| format!("n[{i},{k}]")));
    }
    names.extend((1..=3).map(|k| format!("x_E[{k}]")));
    for i in 1..=n {
        names.extend((1..=n).map(|j| format!("M[{i},{j}]")));
    }
    let with_friction: Vec<usize> = (0..n).filter(|&i| model.joints[i].friction.is_some()).collect();
    names.extend(with_friction.iter().map(|i| format!("load[{}]", i + 1)));
    names.extend(with_friction.iter().map(|i| format!("axial[{}]", i + 1)));
    // Quoted (RFC 4180): the names hold commas.
    writeln!(w, "{}", names.iter().map(|s| format!("\"{s}\"")).collect::<Vec<_>>().join(","))?;
    for (row, line) in lines.enumerate() {
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        let value = |c: usize| -> Result<f64, String> {
            let x: f64 = cells
                .get(c)
                .ok_or(format!("{states}: row {} is short", row + 1))?
                .parse()
                .map_err(|e| format!("{states}: row {}: {e}", row + 1))?;
            x.is_finite().then_some(x).ok_or(format!("{states}: row {}: not a finite number", row + 1))
        };
        let v = columns.iter().map(|&c| value(c)).collect::<Result<Vec<f64>, _>>()?;
        let (q, qd, qdd) = (&v[..n], &v[n..2 * n], &v[2 * n..]);
        inverse_dynamics(&model, &mut data, q, qd, qdd);
        crba(&model, &mut data);
        let mut out: Vec<f64> = data.tau.clone();
        for (i, joint) in model.joints.iter().enumerate() {
            out.extend((joint.reported_axes * data.force[i]).iter());
            out.extend((joint.reported_axes * data.moment[i]).iter());
        }
        out.extend(end_point(&model, &data).iter());
        out.extend(data.mass_matrix.transpose().iter());
        let loads: Vec<_> = with_friction.iter().filter_map(|&i| joint_friction_loads(&model, &data, i)).collect();
        out.extend(loads.iter().map(|l| l.lever_load));
        out.extend(loads.iter().map(|l| l.axial));
        writeln!(w, "{}", out.iter().map(|x| format!("{x:e}")).collect::<Vec<_>>().join(","))?;
    }
    Ok(())
}
