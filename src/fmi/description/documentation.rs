//! `documentation/index.html`: the FMU's own documentation (FMI 2.0 §2.3,
//! the entry point of the archive's `documentation/` directory), written
//! from the same [`Model`] and the same variable list as
//! `modelDescription.xml`, so that it always describes the binary beside it.
//!
//! One self-contained HTML5 page (inline style, no script, nothing fetched
//! from the web): the chain, every variable with unit, range, start value and
//! description, how a master couples the FMU, and where to read more. The
//! icon `../model.png` (the archive's root) is shown when the page is read
//! inside the extracted FMU.

use super::variables::{guid, variables, Causality, Quantity, Type, Variability, Variable};
use super::{DEFAULT_EXPERIMENT, LOG_CATEGORIES, MODEL_IDENTIFIER};
use crate::model::{ContactGeometry, Drive, JointKind, Model};
use std::borrow::Cow;
use std::fmt::Write;

/// Colours of the drive kinds, shared with the icon (`model.png`): rigid,
/// flexible, motor, as `[r, g, b]`.
pub const DRIVE_COLOURS: [[u8; 3]; 3] = [[0x78, 0x80, 0x88], [0x1f, 0x6f, 0xc0], [0xe0, 0x6c, 0x10]];

/// Index into [`DRIVE_COLOURS`] of a drive: 0 rigid, 1 flexible, 2 motor.
pub fn drive_colour_index(drive: &Drive) -> usize {
    match drive {
        Drive::Rigid => 0,
        Drive::Flexible { .. } => 1,
        Drive::Motor { .. } => 2,
    }
}

/// Text with `&`, `<`, `>`, `"` and `'` replaced by character references
/// (quick-xml's escaping): safe as element content and as a quoted attribute
/// value.
pub fn escape_html(text: &str) -> Cow<'_, str> {
    quick_xml::escape::escape(text)
}

/// A number in its shortest round-trip digits, with an exponent outside
/// [1e-3, 1e5): `1e6`, `0.25`, `3e-4`.
fn number(x: f64) -> String {
    if x == 0.0 || (1e-3..1e5).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

fn kind_name(kind: JointKind) -> &'static str {
    match kind {
        JointKind::Revolute => "revolute",
        JointKind::Prismatic => "prismatic",
    }
}

fn drive_name(drive: &Drive) -> &'static str {
    match drive {
        Drive::Rigid => "rigid",
        Drive::Flexible { .. } => "flexible",
        Drive::Motor { .. } => "motor",
    }
}

/// (coordinate, stiffness, damping, rate) units of a joint kind.
fn units(kind: JointKind) -> (&'static str, &'static str, &'static str, &'static str) {
    match kind {
        JointKind::Revolute => ("rad", "N.m/rad", "N.m.s/rad", "rad/s"),
        JointKind::Prismatic => ("m", "N/m", "N.s/m", "m/s"),
    }
}

/// The variable groups of the page: (id, heading, what they are).
const GROUPS: [(&str, &str, &str); 5] = [
    (
        "inputs",
        "Inputs",
        "Set by the master at every communication point (before fmi2DoStep), and at initialization.",
    ),
    (
        "outputs",
        "Outputs",
        "The state at the last communication point; no direct feedthrough (setting an input changes no output before the next step).",
    ),
    (
        "parameters",
        "Parameters",
        "Model parameters per joint. Tunable ones may change between steps; fixed ones before fmi2ExitInitializationMode only.",
    ),
    (
        "start-values",
        "Start values",
        "How the motion starts; fixed after initialization.",
    ),
    (
        "settings",
        "Integrator settings",
        "The Newmark stepper's settings; fixed after initialization.",
    ),
];

/// The group of [`GROUPS`] a variable is listed in.
fn group(v: &Variable) -> usize {
    match (v.causality, v.quantity) {
        (Causality::Input, _) => 0,
        (Causality::Output, _) => 1,
        (Causality::Parameter, Quantity::Parameter(..)) => 2,
        (Causality::Parameter, Quantity::Setting(_)) => 4,
        (Causality::Parameter, _) => 3,
    }
}

const STYLE: &str = "
body { font-family: system-ui, -apple-system, 'Segoe UI', Helvetica, Arial, sans-serif; line-height: 1.45;
       color: #1d2228; background: #ffffff; margin: 0 auto; padding: 1em 1.5em 3em; max-width: 72em; }
header { display: flex; gap: 1.5em; align-items: center; border-bottom: 2px solid #d0d7de; padding-bottom: 1em; }
header img { width: 128px; height: 128px; flex: none; }
h1 { font-size: 1.7em; margin: 0 0 0.3em; }
h2 { font-size: 1.35em; margin-top: 2em; border-bottom: 1px solid #d0d7de; padding-bottom: 0.2em; }
h3 { font-size: 1.1em; margin-top: 1.6em; }
code { font-family: ui-monospace, 'SFMono-Regular', Menlo, Consolas, monospace; font-size: 0.92em;
       background: #f3f5f7; padding: 0 0.2em; border-radius: 3px; }
table { border-collapse: collapse; margin: 0.6em 0; font-size: 0.92em; }
th, td { border: 1px solid #d0d7de; padding: 0.25em 0.5em; text-align: left; vertical-align: top; }
th { background: #eef1f4; }
tbody tr:nth-child(even) { background: #f8f9fa; }
td.num { white-space: nowrap; font-variant-numeric: tabular-nums; }
td.name { white-space: nowrap; }
dl.facts { display: grid; grid-template-columns: max-content auto; gap: 0.2em 1em; }
dl.facts dt { font-weight: 600; }
dl.facts dd { margin: 0; }
.drive { font-weight: 600; }
.drive-rigid { color: #5b636b; }
.drive-flexible { color: #1f6fc0; }
.drive-motor { color: #c05a08; }
.legend span { display: inline-block; width: 0.9em; height: 0.9em; vertical-align: -0.1em; margin: 0 0.3em 0 0.8em;
               border: 1px solid #333; }
nav ul { display: flex; flex-wrap: wrap; gap: 0.4em 1.2em; list-style: none; padding: 0; }
footer { margin-top: 3em; color: #5b636b; font-size: 0.9em; border-top: 1px solid #d0d7de; padding-top: 0.6em; }
";

/// The page `documentation/index.html` of the FMU for `model`, parsed from
/// `model_text` (the text the GUID is derived from, as for
/// [`model_description_xml`](super::model_description_xml)).
pub fn documentation_html(model: &Model, model_text: &str) -> String {
    let vars = variables(model);
    let guid = guid(model_text, &vars);
    let mut h = String::with_capacity(64 * 1024 + 600 * vars.len());
    let e = escape_html;
    let version = env!("CARGO_PKG_VERSION");
    let n = model.nq();

    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
         <meta name=\"generator\" content=\"stick_slip_manipulator {version}\">\n\
         <title>{} &#8212; {MODEL_IDENTIFIER} FMU</title>\n<style>{STYLE}</style>\n</head>\n<body>\n",
        e(&model.name)
    );

    // Header: icon, name, one paragraph.
    let chain: Vec<String> =
        model.joints.iter().map(|j| format!("{} {}", kind_name(j.kind), drive_name(&j.drive))).collect();
    let _ = write!(
        h,
        "<header>\n<img src=\"../model.png\" width=\"128\" height=\"128\" alt=\"Icon: side view of the {n}-joint chain at q = 0\">\n\
         <div>\n<h1>{} <small>&#8212; {MODEL_IDENTIFIER}, an FMI 2.0 co-simulation FMU</small></h1>\n\
         <p>Forward dynamics of the open manipulator chain <code>{}</code> ({n} joints: {}) with flexible drives \
         (a spring with damping and backlash between drive and link) and dry friction in the joints whose normal \
         loads come from the joint reactions of the moving arm: stick&#8211;slip motion. Inputs are the drive \
         positions q* and their rates{}; outputs the joint coordinates, reactions, stick flags and positioning errors.</p>\n\
         </div>\n</header>\n",
        e(&model.name),
        e(&model.name),
        e(&chain.join(", ")),
        if model.motor_joints().is_empty() { "" } else { " (and the motor torques of the motor drives)" },
    );

    h.push_str(
        "<nav><ul>\n<li><a href=\"#facts\">The FMU</a></li>\n<li><a href=\"#chain\">The chain</a></li>\n\
         <li><a href=\"#variables\">Variables</a></li>\n<li><a href=\"#coupling\">Coupling it</a></li>\n\
         <li><a href=\"#logging\">Logging</a></li>\n<li><a href=\"#more\">Read more</a></li>\n</ul></nav>\n<main>\n",
    );

    // Facts.
    let (start, stop, step) = DEFAULT_EXPERIMENT;
    // A URDF model's text is the model file followed by its URDF
    // (`ModelSource::fingerprint_text`); the model file names the URDF.
    let urdf = Model::urdf_reference(model_text.split("\n# --- URDF ---\n").next().unwrap_or(model_text));
    let _ = write!(
        h,
        "<section id=\"facts\">\n<h2>The FMU</h2>\n<dl class=\"facts\">\n\
         <dt>FMI version</dt><dd>2.0, co-simulation</dd>\n\
         <dt>modelIdentifier</dt><dd><code>{MODEL_IDENTIFIER}</code></dd>\n\
         <dt>modelName</dt><dd><code>{}</code></dd>\n\
         <dt>GUID</dt><dd><code>{}</code></dd>\n\
         <dt>Generation tool</dt><dd>stick_slip_manipulator {version}</dd>\n\
         <dt>Model file</dt><dd><code>resources/model.toml</code> in this FMU{}</dd>\n\
         <dt>Default experiment</dt><dd>{} s to {} s, communication step {} s, relative tolerance {}</dd>\n\
         <dt>Variables</dt><dd>{} ({} inputs, {} outputs, {} parameters)</dd>\n\
         </dl>\n</section>\n",
        e(&model.name),
        e(&guid),
        match &urdf {
            Some(u) =>
                format!(", with the URDF it names (<code>resources/{}</code>)", e(u.rsplit('/').next().unwrap_or(u))),
            None => String::new(),
        },
        number(start),
        number(stop),
        number(step),
        number(model.integrator.error_tolerance),
        vars.len(),
        vars.iter().filter(|v| v.causality == Causality::Input).count(),
        vars.iter().filter(|v| v.causality == Causality::Output).count(),
        vars.iter().filter(|v| v.causality == Causality::Parameter).count(),
    );

    write_chain(&mut h, model);
    write_variables(&mut h, &vars);
    write_coupling(&mut h, model, &vars);

    // Logging.
    h.push_str(
        "<section id=\"logging\">\n<h2>Logging</h2>\n<p>Every fmi2Warning, fmi2Discard and fmi2Error comes with a message \
         to the master's logger that names the cause (the variable, its range, the time). Log categories \
         (fmi2SetDebugLogging):</p>\n<table id=\"log-categories\">\n<thead><tr><th>category</th><th>messages</th></tr></thead>\n<tbody>\n",
    );
    for (name, description) in LOG_CATEGORIES {
        let _ = writeln!(h, "<tr><td><code>{}</code></td><td>{}</td></tr>", e(name), e(description));
    }
    h.push_str("</tbody>\n</table>\n</section>\n");

    // Read more.
    h.push_str(
        "<section id=\"more\">\n<h2>Read more</h2>\n<p>This FMU is built by the Rust project \
         <code>stick_slip_manipulator</code> (<code>bash scripts/build_fmu.sh --model FILE</code>). Its repository \
         documents the method and the engine in more depth; these files are not part of the FMU:</p>\n<ul>\n",
    );
    let files = [
        ("README.md", "the project: the FMU's variables and the behaviour masters rely on, model files, the method and where each formula lives, verification, performance"),
        ("docs/motor_drives.md", "motor drives: the rotor behind the gear, torque in, encoder out, the energy account"),
        ("docs/control.md", "a cascaded position/velocity axis controller closed around a motor-driven FMU"),
        ("docs/urdf.md", "your own arm: URDF model files, drives and friction added to a URDF"),
        ("docs/motion.md", "motion files: driving any arm's FMU without writing Python"),
        ("docs/accuracy.md", "accuracy over the whole parameter space, and the error control"),
        ("docs/convergence.md", "whether a number is converged (--check-convergence)"),
        ("docs/study.md", "the source study's five cases reproduced on the reference manipulator"),
        ("docs/sweep.md", "parameter studies (stickslip sweep)"),
    ];
    for (file, what) in files {
        let _ = writeln!(h, "<li><code>{file}</code>: {}</li>", e(what));
    }
    h.push_str(
        "</ul>\n<p>The equation numbers in the variable descriptions, e.g. (2.1) for the drive law, are those of the source \
         study, &#8220;Stick-slip&#8221; motion of open manipulators with flexible drives and dry friction in joints.</p>\n</section>\n</main>\n",
    );
    let _ = write!(
        h,
        "<footer>Generated by stick_slip_manipulator {version} from <code>resources/model.toml</code> by the code that \
         writes this FMU&#39;s modelDescription.xml (GUID <code>{}</code>).</footer>\n</body>\n</html>\n",
        e(&guid)
    );
    h
}

fn write_chain(h: &mut String, model: &Model) {
    let e = escape_html;
    let named = model.joint_names.iter().any(Option::is_some);
    let _ = write!(
        h,
        "<section id=\"chain\">\n<h2>The chain</h2>\n<p>{} joints in chain order from the base; joint i moves link i. \
         Revolute joints in rad, rad/s, N.m; prismatic joints in m, m/s, N.</p>\n\
         <p class=\"legend\">Icon (<code>model.png</code>): a side view at q = 0, links as lines, revolute joints as circles, \
         prismatic joints as squares; drives:<span style=\"background:#{}\"></span>rigid\
         <span style=\"background:#{}\"></span>flexible<span style=\"background:#{}\"></span>motor.</p>\n\
         <table id=\"joints\">\n<thead><tr><th>joint</th>{}<th>kind</th><th>drive</th><th>drive data</th>\
         <th>friction contact</th><th>friction coefficients</th><th>link mass</th></tr></thead>\n<tbody>\n",
        model.nq(),
        hex(DRIVE_COLOURS[0]),
        hex(DRIVE_COLOURS[1]),
        hex(DRIVE_COLOURS[2]),
        if named { "<th>URDF joint</th>" } else { "" },
    );
    for (j, joint) in model.joints.iter().enumerate() {
        let (coordinate, stiffness, damping, rate) = units(joint.kind);
        let drive = drive_name(&joint.drive);
        let mut data = Vec::new();
        if let Some(s) = joint.drive.spring() {
            data.push(format!("k = {} {stiffness}", number(s.stiffness)));
            data.push(format!("h = {} {damping}", number(s.damping)));
            data.push(format!("&#916; = {} {coordinate}", number(s.clearance)));
        }
        if let Some(r) = joint.drive.rotor() {
            let ratio = match joint.kind {
                JointKind::Revolute => "",
                JointKind::Prismatic => " rad/m",
            };
            data.push(format!("N = {}{ratio}", number(r.gear_ratio)));
            data.push(format!("J_m = {} kg.m2", number(r.inertia)));
            data.push(format!("b_m = {} N.m.s/rad", number(r.viscous)));
            data.push(format!("&#964;_c = {} N.m", number(r.coulomb)));
        }
        if data.is_empty() {
            data.push("prescribed motion q = q*".into());
        }
        let (contact, coefficients) = match &joint.friction {
            None => ("none", "&#8211;".to_string()),
            Some(f) => {
                let c = f.coefficients;
                let contact = match f.geometry {
                    ContactGeometry::Bearings { .. } => "bearings",
                    ContactGeometry::Slider { .. } => "slider",
                };
                (
                    contact,
                    format!(
                        "&#956;_k = {}, &#956;_s = {}, v_s = {} {rate}",
                        number(c.mu_kinetic),
                        number(c.mu_static),
                        number(c.stribeck_velocity)
                    ),
                )
            }
        };
        let name = match (named, &model.joint_names[j]) {
            (false, _) => String::new(),
            (true, Some(name)) => format!("<td><code>{}</code></td>", e(name)),
            (true, None) => "<td>&#8211;</td>".into(),
        };
        let _ = writeln!(
            h,
            "<tr><td class=\"num\">{}</td>{name}<td>{}</td><td class=\"drive drive-{drive}\">{drive}</td><td>{}</td>\
             <td>{contact}</td><td>{coefficients}</td><td class=\"num\">{} kg</td></tr>",
            j + 1,
            kind_name(joint.kind),
            data.join(", "),
            number(model.links[j].mass),
        );
    }
    let g = model.gravity;
    let p = model.end_point;
    let _ = write!(
        h,
        "</tbody>\n</table>\n<p>Gravity ({}, {}, {}) m/s2 in the base frame; end point E ({}, {}, {}) m in the frame of link {}.</p>\n</section>\n",
        number(g.x),
        number(g.y),
        number(g.z),
        number(p.x),
        number(p.y),
        number(p.z),
        model.nq(),
    );
}

fn hex(c: [u8; 3]) -> String {
    format!("{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

fn write_variables(h: &mut String, vars: &[Variable]) {
    let e = escape_html;
    h.push_str(
        "<section id=\"variables\">\n<h2>Variables</h2>\n<p>Names are structured (<code>q[2]</code>: joint 2; \
         <code>f[2,3]</code>: joint 2, component 3); 1-based joint numbers as in the chain table. The value reference \
         (VR) is the variable&#39;s position in modelDescription.xml minus one. Every input and parameter has a physical \
         range, declared as min/max and enforced by fmi2SetReal with fmi2Error; FMI&#39;s min is inclusive, and where a \
         range excludes its lower end the description says so.</p>\n",
    );
    for (g, (id, heading, what)) in GROUPS.iter().enumerate() {
        let members: Vec<&Variable> = vars.iter().filter(|v| group(v) == g).collect();
        if members.is_empty() {
            continue;
        }
        let _ = write!(
            h,
            "<section id=\"{id}\">\n<h3>{heading} ({})</h3>\n<p>{}</p>\n<table class=\"variables\">\n\
             <thead><tr><th>name</th><th>VR</th><th>type</th><th>unit</th><th>range</th><th>start</th>\
             <th>variability</th><th>description</th></tr></thead>\n<tbody>\n",
            members.len(),
            e(what)
        );
        for v in members {
            let (ty, unit, range, start) = match v.ty {
                Type::Real { unit, min, max, start } => {
                    let range = match (min, max) {
                        (Some(a), Some(b)) => format!("[{}, {}]", number(a), number(b)),
                        (Some(a), None) => format!("&#8805; {}", number(a)),
                        (None, Some(b)) => format!("&#8804; {}", number(b)),
                        (None, None) => String::new(),
                    };
                    ("Real", unit.unwrap_or(""), range, start.map(number).unwrap_or_default())
                }
                Type::Boolean { start } => {
                    ("Boolean", "", String::new(), start.map(|s| s.to_string()).unwrap_or_default())
                }
            };
            let variability = match v.variability {
                Variability::Fixed => "fixed",
                Variability::Tunable => "tunable",
                Variability::Discrete => "discrete",
                Variability::Continuous => "continuous",
            };
            let _ = writeln!(
                h,
                "<tr><td class=\"name\"><code>{}</code></td><td class=\"num\">{}</td><td>{ty}</td><td class=\"unit\">{}</td>\
                 <td class=\"num\">{range}</td><td class=\"num\">{}</td><td>{variability}</td><td>{}</td></tr>",
                e(&v.name),
                v.value_reference,
                e(unit),
                e(&start),
                e(&v.description)
            );
        }
        h.push_str("</tbody>\n</table>\n</section>\n");
    }
    h.push_str("</section>\n");
}

fn write_coupling(h: &mut String, model: &Model, vars: &[Variable]) {
    let e = escape_html;
    let (_, _, step) = DEFAULT_EXPERIMENT;
    let _ = write!(
        h,
        "<section id=\"coupling\">\n<h2>Coupling it</h2>\n<ol>\n\
         <li><strong>Instantiate and set up.</strong> fmi2Instantiate reads <code>resources/model.toml</code>. \
         fmi2SetupExperiment: a defined tolerance sets <code>error_tolerance</code> (the error control&#39;s relative \
         tolerance, in (0, 0.1]). Set parameters, start values and settings before fmi2ExitInitializationMode.</li>\n\
         <li><strong>Initialize.</strong> In initialization mode set the inputs at the start time. Without start values \
         (<code>use_start_values = false</code>) the flexible joints start at q = q*, at rest, stuck where friction holds \
         them; with them at <code>q_start[i]</code>, <code>qd_start[i]</code>. The outputs are the start state after \
         fmi2ExitInitializationMode.</li>\n\
         <li><strong>Step.</strong> At each communication point t set the inputs <code>q_star[i]</code>, \
         <code>qd_star[i]</code>, <code>qdd_star[i]</code> of every joint i (the drive end q*, q*&#39;, q*&#39;&#39; \
         of a flexible drive, the prescribed q, q&#39;, q&#39;&#39; of a rigid one), then call fmi2DoStep(t, h). Across \
         the step the inputs are held as the polynomial q* + q*&#39; s + q*&#39;&#39; s&#178;/2 (canInterpolateInputs). \
         The rates may instead come as input derivatives: fmi2SetRealInputDerivatives on <code>q_star[i]</code> with \
         order 1 sets <code>qd_star[i]</code>, order 2 sets <code>qdd_star[i]</code> (order 1 on <code>qd_star[i]</code> \
         sets <code>qdd_star[i]</code>); a value holds until it is set again; nonzero higher orders are ignored with \
         fmi2Warning. The communication step may change from step to step \
         (canHandleVariableCommunicationStepSize; {} s by default, anything from 10 &#181;s to 1 s works): inside it \
         an error-controlled Newmark integrator takes sub-steps between <code>h_min</code> and <code>h_max</code> and \
         locates the stick&#8211;slip transitions. Outputs have no direct feedthrough: read them after fmi2DoStep.</li>\n\
         <li><strong>fmi2Discard.</strong> A step the engine cannot complete (the iteration does not converge, an output \
         is not finite, the tunable parameters are inconsistent, e.g. mu_s &lt; mu_k) returns fmi2Discard with a message \
         naming the cause; the state stays at the last good time (fmi2GetRealStatus(fmi2LastSuccessfulTime)), so the \
         master can correct the parameters or inputs, or take a shorter step, and step again from there.</li>\n\
         <li><strong>fmi2Error.</strong> A wrong call sequence, an unknown value reference, a NaN, a value outside its \
         range, a step &#8804; 0 or a wrong communication point returns fmi2Error with a message and changes nothing.</li>\n\
         <li><strong>FMU states.</strong> fmi2GetFMUstate, fmi2SetFMUstate and fmi2FreeFMUstate are supported, and the \
         states serialize (fmi2SerializeFMUstate, fmi2DeSerializeFMUstate): restoring one continues exactly, bit for \
         bit, also in another instance or process; corrupt or foreign buffers are rejected. Input derivatives set \
         earlier are part of the state.</li>\n\
         <li><strong>Not provided.</strong> Directional derivatives and output derivatives \
         (maxOutputDerivativeOrder = 0): those calls return fmi2Error. Instances are independent (no global \
         state) and may run in parallel threads.</li>\n</ol>\n",
        number(step),
    );

    let motors = model.motor_joints();
    h.push_str("<h3 id=\"motor-drives\">Motor drives</h3>\n");
    if motors.is_empty() {
        h.push_str(
            "<p>This model has no motor drives: every drive is rigid or flexible, and its drive position q* is an input. \
             A model file may give a joint <code>drive = { type = \"motor\", &#8230; }</code> instead: a rotor of inertia \
             J_m behind the gear spring, turned by the input torque <code>tau_m[i]</code>, whose angle \
             <code>theta_m[i]</code> is an output (see <code>docs/motor_drives.md</code>).</p>\n",
        );
    } else {
        let has = |name: &str| vars.iter().any(|v| v.name == name);
        h.push_str(
            "<p>A motor drive puts a physical motor behind the gear spring: a rotor of inertia J_m turned by the motor \
             torque tau_m (an input, N.m on the motor side), J_m theta_m&#39;&#39; = tau_m &#8722; F/N &#8722; b_m \
             theta_m&#39; &#8722; tau_f, driving the gear law (2.1) with q* = theta_m/N. <strong>Torque in, angle \
             out:</strong> set <code>tau_m[i]</code> at each communication point (its rates through \
             fmi2SetRealInputDerivatives, orders 1 and 2, held until set again) and read <code>theta_m[i]</code>; the \
             motor encoder reads theta_m/N, the link encoder <code>q[i]</code>. A motor joint&#39;s <code>q_star[i]</code> \
             is ignored while stepping (without start values it gives the link&#39;s start position); \
             <code>static_start = true</code> starts the rotors turned so that the gear springs hold the arm against \
             gravity.</p>\n<ul>\n",
        );
        for j in motors {
            let i = j + 1;
            let inputs: Vec<String> = [format!("tau_m[{i}]")]
                .into_iter()
                .filter(|n| has(n))
                .map(|n| format!("<code>{}</code>", e(&n)))
                .collect();
            let outputs: Vec<String> = ["theta_m", "omega_m", "stick_m", "tau_load", "tau_f_m", "q", "eps_joint"]
                .iter()
                .map(|k| format!("{k}[{i}]"))
                .filter(|n| has(n))
                .map(|n| format!("<code>{}</code>", e(&n)))
                .collect();
            let ratio = format!("gear_ratio[{i}]");
            let encoder = if has(&ratio) && has(&format!("theta_m[{i}]")) {
                format!("; motor encoder <code>theta_m[{i}]</code> / <code>{}</code>", e(&ratio))
            } else {
                String::new()
            };
            let _ = writeln!(
                h,
                "<li>joint {i}{}: in {}; out {}{encoder}</li>",
                match &model.joint_names[j] {
                    Some(name) => format!(" (<code>{}</code>)", e(name)),
                    None => String::new(),
                },
                inputs.join(", "),
                outputs.join(", "),
            );
        }
        h.push_str("</ul>\n");
    }
    h.push_str("</section>\n");
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{REFERENCE_RRPR_MOTOR_TOML, REFERENCE_RRPR_TOML};

    /// The page's tags balance (void elements excepted), its text has no raw
    /// `<` or `&` outside markup and references.
    fn check_balanced(html: &str) {
        const VOID: [&str; 5] = ["meta", "img", "br", "hr", "link"];
        let mut stack: Vec<String> = Vec::new();
        let mut rest = html.strip_prefix("<!DOCTYPE html>").expect("doctype first");
        while let Some(open) = rest.find('<') {
            let text = &rest[..open];
            assert!(!text.contains('>'), "raw > in text {text:?}");
            for (k, _) in text.match_indices('&') {
                let reference = &text[k..];
                let end = reference.find(';').expect("& starts a reference");
                assert!(
                    end <= 8 && reference[1..end].chars().all(|c| c.is_ascii_alphanumeric() || c == '#'),
                    "bare & in {text:?}"
                );
            }
            let close = rest[open..].find('>').expect("tag closes") + open;
            let tag = &rest[open + 1..close];
            if let Some(name) = tag.strip_prefix('/') {
                assert_eq!(stack.pop().as_deref(), Some(name), "close tag </{name}>");
            } else {
                let name: String = tag.chars().take_while(|c| c.is_ascii_alphanumeric()).collect();
                if name == "style" {
                    let end = rest[close..].find("</style>").expect("style closes") + close;
                    rest = &rest[end + "</style>".len()..];
                    continue;
                }
                if !VOID.contains(&name.as_str()) {
                    stack.push(name);
                }
            }
            rest = &rest[close + 1..];
        }
        assert!(stack.is_empty(), "unclosed {stack:?}");
    }

    #[test]
    fn escapes_the_five_characters() {
        assert_eq!(escape_html(r#"a<b>&"c'"#), "a&lt;b&gt;&amp;&quot;c&apos;");
        assert_eq!(escape_html("mu_s >= mu_k"), "mu_s &gt;= mu_k");
    }

    #[test]
    fn page_lists_every_variable_and_joint() {
        for text in [REFERENCE_RRPR_TOML, REFERENCE_RRPR_MOTOR_TOML] {
            let model = Model::from_toml_str(text).unwrap();
            let html = documentation_html(&model, text);
            check_balanced(&html);
            for v in variables(&model) {
                let row =
                    format!("<code>{}</code></td><td class=\"num\">{}</td>", escape_html(&v.name), v.value_reference);
                assert!(html.contains(&row), "{} missing", v.name);
                assert!(html.contains(&*escape_html(&v.description)), "description of {} missing", v.name);
            }
            assert!(html.contains(&guid(text, &variables(&model))));
            assert_eq!(html.matches("<tr><td class=\"num\">").count(), model.nq());
        }
    }

    #[test]
    fn motor_section_names_existing_variables() {
        let model = Model::from_toml_str(REFERENCE_RRPR_MOTOR_TOML).unwrap();
        let html = documentation_html(&model, REFERENCE_RRPR_MOTOR_TOML);
        for name in ["tau_m[1]", "theta_m[1]", "tau_m[3]", "theta_m[3]", "gear_ratio[3]"] {
            assert!(html.contains(&format!("<code>{name}</code>")), "{name}");
        }
        assert_eq!(html.matches("class=\"drive drive-motor\"").count(), 2);
        let reference = documentation_html(&Model::reference_rrpr(), REFERENCE_RRPR_TOML);
        assert!(!reference.contains("drive drive-motor\""));
        assert!(reference.contains("no motor drives"));
    }
}
