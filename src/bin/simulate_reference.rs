//! Simulates the reference motion of a model (default: the reference
//! manipulator) with the Rust engine and writes a CSV with the FMU's
//! outputs, named and ordered as in its modelDescription (the same table).
//!
//! Usage: simulate_reference [--model FILE] [--out FILE] [--interval S] [--end S]
//!                           [--h-min S] [--h-max S] [--tol TOL]
//!
//! `--h-max` below the model's h_min gives fixed sub-steps of that length.

use std::io::Write;
use stick_slip_manipulator::fmi::description::{variables, Output, Quantity};
use stick_slip_manipulator::motion::{reference_inputs, REFERENCE_RUN_TIME};
use stick_slip_manipulator::{DriveInputs, Model, Simulator};

fn main() {
    if let Err(e) = run() {
        eprintln!("simulate_reference: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let mut model_path = None;
    let mut out = "results/reference.csv".to_string();
    let mut interval = 1e-3;
    let mut end = REFERENCE_RUN_TIME;
    let mut h_max = None;
    let mut h_min = None;
    let mut error_tolerance = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().ok_or_else(|| format!("{a} needs a value"));
        match a.as_str() {
            "--model" => model_path = Some(value()?),
            "--out" => out = value()?,
            "--interval" => interval = value()?.parse()?,
            "--end" => end = value()?.parse()?,
            "--h-max" => h_max = Some(value()?.parse::<f64>()?),
            "--h-min" => h_min = Some(value()?.parse::<f64>()?),
            "--tol" => error_tolerance = Some(value()?.parse::<f64>()?),
            _ => return Err(format!("unknown argument {a}").into()),
        }
    }
    let mut model = match model_path {
        Some(p) => Model::from_file(p)?,
        None => Model::reference_rrpr(),
    };
    for warning in &model.warnings {
        eprintln!("simulate_reference: warning: {warning}");
    }
    // --h-max alone below the model's h_min means fixed sub-steps of that length.
    if let Some(h) = h_max {
        model.integrator.h_max = h;
        model.integrator.h_min = model.integrator.h_min.min(h);
    }
    if let Some(h) = h_min {
        model.integrator.h_min = h;
    }
    if let Some(t) = error_tolerance {
        model.integrator.error_tolerance = t;
    }
    let n = model.nq();
    if n != 4 {
        return Err(format!("the reference motion drives 4 joints, the model has {n}").into());
    }
    let mut sim = Simulator::new(model)?;
    let (q, qd, qdd) = reference_inputs(0.0);
    sim.initialize(0.0, &DriveInputs { q_star: &q, qd_star: &qd, qdd_star: &qdd }, None)?;
    if let Some(dir) = std::path::Path::new(&out).parent() {
        std::fs::create_dir_all(dir)?;
    }
    let mut file = std::io::BufWriter::new(std::fs::File::create(&out)?);
    let outputs = outputs(sim.model());
    write_header(&mut file, &outputs)?;
    write_row(&mut file, &sim, &outputs)?;
    let steps = (end / interval).round() as usize;
    let wall = std::time::Instant::now();
    let mut stepping = std::time::Duration::ZERO;
    let mut evaluations = 0;
    for k in 0..steps {
        let t = k as f64 * interval;
        let (q, qd, qdd) = reference_inputs(t);
        let started = std::time::Instant::now();
        sim.advance(&DriveInputs { q_star: &q, qd_star: &qd, qdd_star: &qdd }, interval)?;
        stepping += started.elapsed();
        evaluations += sim.iterations();
        write_row(&mut file, &sim, &outputs)?;
    }
    let st = sim.state().steps;
    eprintln!(
        "simulated {end} s in {:.3} s wall stepping ({:.3} s with writing the results); {} sub-steps, {} rejected, {evaluations} inverse-dynamics evaluations; results in {out}",
        stepping.as_secs_f64(),
        wall.elapsed().as_secs_f64(),
        st.accepted,
        st.rejected,
    );
    Ok(())
}

/// The FMU's output variables of `model`, in their modelDescription order.
fn outputs(model: &Model) -> Vec<(String, Output)> {
    variables(model)
        .into_iter()
        .filter_map(|v| match v.quantity {
            Quantity::Output(o) => Some((v.name, o)),
            _ => None,
        })
        .collect()
}

fn write_header(w: &mut impl Write, outputs: &[(String, Output)]) -> std::io::Result<()> {
    let mut cols = vec!["time"];
    cols.extend(outputs.iter().map(|(name, _)| name.as_str()));
    // Names such as f[1,2] contain a comma: quote them (RFC 4180).
    let quoted: Vec<String> =
        cols.iter().map(|c| if c.contains(',') { format!("\"{c}\"") } else { c.to_string() }).collect();
    writeln!(w, "{}", quoted.join(","))
}

fn write_row(w: &mut impl Write, sim: &Simulator, outputs: &[(String, Output)]) -> std::io::Result<()> {
    let s = sim.state();
    let values = std::iter::once(s.time).chain(outputs.iter().map(|(_, o)| o.value(s)));
    let text: Vec<String> = values.map(|x| format!("{x:.17e}")).collect();
    writeln!(w, "{}", text.join(","))
}
