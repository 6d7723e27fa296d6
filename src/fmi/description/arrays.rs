//! The FMI 3.0 variables: the FMI 2.0 scalars of [`variables`](super::variables)
//! grouped by stem into arrays, so that FMI 2.0's list stays the one
//! description of the variables.
//!
//! `q[1]`…`q[n]` become the vector `q` with dimensions [n], `f[i,k]` the
//! matrix `f` with dimensions [n, 3] (elements row-major: `f[1,1]`,
//! `f[1,2]`, …), a scalar without `[` stays a scalar. Before them comes the
//! independent variable `time`, value reference 0; the others are numbered 1,
//! 2, … in the FMI 2.0 order of their first elements. Some arrays cover only
//! some of the joints (`tau_m` the motor joints, `q_start` the flexible and
//! motor ones, `k` those with a drive spring): their dimension is the number
//! of elements, in ascending joint order.

use super::outputs::OutputUnit;
use super::variables::{Quantity, Type, Variable};

/// The FMI 3.0 type of a variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Type3 {
    /// `fmi3Float64`: the FMI 2.0 Reals.
    Float64,
    /// `fmi3Int32`: the outputs that count (`n_stick`, `n_substeps`, …),
    /// FMI 2.0 Reals of an output kind without unit ("a count or a flag")
    /// that is not a flag.
    Int32,
    /// `fmi3Boolean`: the FMI 2.0 Booleans.
    Boolean,
}

/// An FMI 3.0 variable: the independent variable `time`, or the FMI 2.0
/// scalars of one stem (`q[1]`…`q[n]` → `q`, `f[i,k]` → `f` with dimensions
/// [m, 3]) as one scalar or array.
#[derive(Debug, Clone, PartialEq)]
pub struct Variable3 {
    /// Name: "time", "q_star", "f", "eps", "h_max", …
    pub name: String,
    /// FMI 3.0 value reference: 0 = time, then 1, 2, … in FMI 2.0 order of
    /// the first elements.
    pub value_reference: u32,
    /// Its FMI 3.0 type.
    pub ty: Type3,
    /// [] for a scalar, [m] for a vector, [m, 3] for an m×3 matrix.
    pub dimensions: Vec<usize>,
    /// FMI 2.0 value references of the elements, in FMI 3.0 serialization
    /// order (row-major); empty for `time`.
    pub elements: Vec<u32>,
}

/// Stem and 1-based indices of a structured FMI 2.0 name: `f[2,3]` →
/// ("f", [2, 3]), `eps` → ("eps", []). Panics on a malformed name (the names
/// are the FMU's own).
pub(super) fn split_name(name: &str) -> (&str, Vec<usize>) {
    let Some((stem, rest)) = name.split_once('[') else { return (name, Vec::new()) };
    let inner = rest.strip_suffix(']').unwrap_or_else(|| panic!("variable name `{name}`: no closing `]`"));
    let indices = inner
        .split(',')
        .map(|i| match i.parse::<usize>() {
            Ok(i) if i >= 1 => i,
            _ => panic!("variable name `{name}`: index `{i}` is not a positive integer"),
        })
        .collect();
    (stem, indices)
}

/// The FMI 3.0 type of an FMI 2.0 variable: Boolean for Booleans, Int32 for
/// the Real outputs of a kind without unit (a count: a flag would be a
/// Boolean), Float64 otherwise.
fn type3(v: &Variable) -> Type3 {
    match (v.ty, v.quantity) {
        (Type::Boolean { .. }, _) => Type3::Boolean,
        (Type::Real { .. }, Quantity::Output(o)) if o.kind().unit == OutputUnit::None && !o.kind().boolean => {
            Type3::Int32
        }
        (Type::Real { .. }, _) => Type3::Float64,
    }
}

/// The FMI 3.0 variables of `vars` (the FMI 2.0 list of `variables(model)`).
///
/// Panics if the FMI 2.0 list does not group: the scalars of one stem must
/// be consecutive, of one causality, variability, `initial` and type, with
/// the same number of indices, ascending, and a multi-index stem must fill
/// its whole index grid (units may differ: a revolute and a prismatic joint
/// share `q`).
pub fn variables3(vars: &[Variable]) -> Vec<Variable3> {
    let mut out = vec![Variable3 {
        name: "time".into(),
        value_reference: 0,
        ty: Type3::Float64,
        dimensions: Vec::new(),
        elements: Vec::new(),
    }];
    let mut rest = vars;
    while let Some(first) = rest.first() {
        let (stem, first_indices) = split_name(&first.name);
        assert!(stem != "time", "FMI 2.0 variable `{}` would take the name of the independent variable", first.name);
        assert!(
            out.iter().all(|v| v.name != stem),
            "the FMI 2.0 variables of stem `{stem}` are not consecutive (again at `{}`)",
            first.name
        );
        let len = rest.iter().take_while(|v| split_name(&v.name).0 == stem).count();
        let (group, tail) = rest.split_at(len);
        rest = tail;
        let ty = type3(first);
        let mut members: Vec<(Vec<usize>, u32)> = Vec::with_capacity(len);
        for v in group {
            let same = v.causality == first.causality
                && v.variability == first.variability
                && v.initial == first.initial
                && std::mem::discriminant(&v.ty) == std::mem::discriminant(&first.ty)
                && type3(v) == ty;
            assert!(
                same,
                "`{}` and `{}` differ in causality, variability, initial or type: they cannot form one FMI 3.0 array",
                first.name, v.name
            );
            let indices = split_name(&v.name).1;
            assert_eq!(
                indices.len(),
                first_indices.len(),
                "`{}` and `{}` differ in their number of indices",
                first.name,
                v.name
            );
            members.push((indices, v.value_reference));
        }
        let dimensions = match first_indices.len() {
            0 => {
                assert_eq!(len, 1, "scalar `{stem}` appears {len} times");
                Vec::new()
            }
            1 => {
                assert!(
                    members.windows(2).all(|w| w[0].0 < w[1].0),
                    "the indices of `{stem}` are not strictly ascending in the FMI 2.0 list"
                );
                vec![len]
            }
            rank => {
                // Row-major order, and the whole grid 1..=d_1 × … × 1..=d_r.
                members.sort();
                let dimensions: Vec<usize> =
                    (0..rank).map(|d| members.iter().map(|(i, _)| i[d]).max().unwrap_or(0)).collect();
                assert_eq!(
                    dimensions.iter().product::<usize>(),
                    len,
                    "`{stem}` does not fill its index grid {dimensions:?} (or repeats an index)"
                );
                dimensions
            }
        };
        out.push(Variable3 {
            name: stem.to_string(),
            value_reference: out.len() as u32,
            ty,
            dimensions,
            elements: members.into_iter().map(|(_, vr)| vr).collect(),
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::super::variables::{variables, Causality, Variable};
    use super::*;
    use crate::model::{Model, REFERENCE_RRPR_MOTOR_TOML};
    use std::path::{Path, PathBuf};

    fn find<'a>(vars3: &'a [Variable3], name: &str) -> &'a Variable3 {
        vars3.iter().find(|v| v.name == name).unwrap_or_else(|| panic!("no FMI 3.0 variable `{name}`"))
    }

    fn vr(vars: &[Variable], name: &str) -> u32 {
        vars.iter().find(|v| v.name == name).unwrap_or_else(|| panic!("no FMI 2.0 variable `{name}`")).value_reference
    }

    /// Every model file of the repository: models/*.toml and models/urdf/*/*.toml.
    fn model_files() -> Vec<PathBuf> {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
        let mut files = Vec::new();
        let tomls = |dir: &Path| -> Vec<PathBuf> {
            let mut found: Vec<PathBuf> = std::fs::read_dir(dir)
                .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
                .map(|e| e.expect("directory entry").path())
                .filter(|p| p.extension().is_some_and(|x| x == "toml"))
                .collect();
            found.sort();
            found
        };
        files.extend(tomls(&root));
        let mut urdf_dirs: Vec<PathBuf> = std::fs::read_dir(root.join("urdf"))
            .expect("models/urdf")
            .map(|e| e.expect("directory entry").path())
            .filter(|p| p.is_dir())
            .collect();
        urdf_dirs.sort();
        for dir in urdf_dirs {
            files.extend(tomls(&dir));
        }
        files
    }

    /// The invariants of a grouping: value references 0, 1, 2, …; `time`
    /// first and alone; every FMI 2.0 value reference in exactly one variable,
    /// exactly once; dimensions multiply to the number of elements.
    fn check_invariants(vars: &[Variable], vars3: &[Variable3], what: &str) {
        assert_eq!(
            vars3[0],
            Variable3 {
                name: "time".into(),
                value_reference: 0,
                ty: Type3::Float64,
                dimensions: vec![],
                elements: vec![]
            }
        );
        let mut seen = vec![0usize; vars.len()];
        for (i, v) in vars3.iter().enumerate() {
            assert_eq!(v.value_reference, i as u32, "{what}: {}", v.name);
            if i > 0 {
                assert_eq!(v.dimensions.iter().product::<usize>(), v.elements.len(), "{what}: {}", v.name);
                assert!(v.dimensions.iter().all(|&d| d > 0), "{what}: {}", v.name);
            }
            for &e in &v.elements {
                seen[e as usize] += 1;
                assert_eq!(split_name(&vars[e as usize].name).0, v.name, "{what}");
            }
        }
        for (vr, count) in seen.iter().enumerate() {
            assert_eq!(*count, 1, "{what}: FMI 2.0 `{}` appears {count} times", vars[vr].name);
        }
        // FMI 2.0 order of the first elements.
        let firsts: Vec<u32> = vars3[1..].iter().map(|v| v.elements.iter().copied().min().unwrap()).collect();
        assert!(firsts.windows(2).all(|w| w[0] < w[1]), "{what}");
    }

    #[test]
    fn split_name_reads_stem_and_indices() {
        assert_eq!(split_name("f[2,3]"), ("f", vec![2, 3]));
        assert_eq!(split_name("q_star[12]"), ("q_star", vec![12]));
        assert_eq!(split_name("eps"), ("eps", vec![]));
    }

    #[test]
    fn the_reference_arm_groups_into_arrays() {
        let model = Model::reference_rrpr();
        let vars = variables(&model);
        let vars3 = variables3(&vars);
        check_invariants(&vars, &vars3, "reference");
        let names: Vec<&str> = vars3.iter().take(8).map(|v| v.name.as_str()).collect();
        assert_eq!(names, ["time", "q_star", "qd_star", "qdd_star", "q", "qd", "qdd", "stick"]);
        let q = find(&vars3, "q");
        assert_eq!((q.ty, q.dimensions.clone()), (Type3::Float64, vec![4]));
        assert_eq!(q.elements, ["q[1]", "q[2]", "q[3]", "q[4]"].map(|n| vr(&vars, n)));
        let f = find(&vars3, "f");
        assert_eq!(f.dimensions, [4, 3]);
        let row_major: Vec<u32> =
            (1..=4).flat_map(|i| (1..=3).map(move |k| format!("f[{i},{k}]"))).map(|n| vr(&vars, &n)).collect();
        assert_eq!(f.elements, row_major);
        assert_eq!(find(&vars3, "x_E").dimensions, [3]);
        for (name, ty) in [("stick", Type3::Boolean), ("n_stick", Type3::Int32), ("t_stick", Type3::Float64)] {
            assert_eq!((find(&vars3, name).ty, find(&vars3, name).dimensions.clone()), (ty, vec![4]), "{name}");
        }
        for name in ["n_substeps", "n_rejected"] {
            assert_eq!(
                (find(&vars3, name).ty, find(&vars3, name).dimensions.clone()),
                (Type3::Int32, vec![]),
                "{name}"
            );
        }
        for name in ["eps", "E_kin", "h_max", "h_min", "error_tolerance"] {
            let v = find(&vars3, name);
            assert_eq!(
                (v.ty, v.dimensions.clone(), v.elements.clone()),
                (Type3::Float64, vec![], vec![vr(&vars, name)])
            );
        }
        assert_eq!(find(&vars3, "use_start_values").ty, Type3::Boolean);
        // Joints 1 and 3 are the flexible ones: their spring, friction and start values.
        for name in ["k", "h", "Delta", "mu_k", "q_start", "qd_start"] {
            let v = find(&vars3, name);
            assert_eq!(v.dimensions, [2], "{name}");
            assert_eq!(v.elements, [vr(&vars, &format!("{name}[1]")), vr(&vars, &format!("{name}[3]"))], "{name}");
        }
        assert!(vars3.iter().all(|v| v.name != "tau_m" && v.name != "static_start"));
        let outputs = vars.iter().filter(|v| v.causality == Causality::Output).count();
        assert!(vars3.len() < outputs, "{} FMI 3.0 variables for {} FMI 2.0 outputs", vars3.len(), outputs);
    }

    #[test]
    fn the_motor_arm_groups_its_motor_joints() {
        let model = Model::from_toml_str(REFERENCE_RRPR_MOTOR_TOML).unwrap();
        let vars = variables(&model);
        let vars3 = variables3(&vars);
        check_invariants(&vars, &vars3, "motor");
        for name in ["tau_m", "theta_m_start", "omega_m_start", "theta_m", "omega_m", "tau_load", "J_m"] {
            let v = find(&vars3, name);
            assert_eq!(v.dimensions, [2], "{name}");
            assert_eq!(v.elements, [vr(&vars, &format!("{name}[1]")), vr(&vars, &format!("{name}[3]"))], "{name}");
        }
        assert_eq!(find(&vars3, "stick_m").ty, Type3::Boolean);
        assert_eq!(find(&vars3, "n_stick_m").ty, Type3::Int32);
        assert_eq!(find(&vars3, "static_start").ty, Type3::Boolean);
        assert_eq!(find(&vars3, "E_rotor").dimensions, Vec::<usize>::new());
        // tau_m follows qdd_star, as in FMI 2.0.
        assert_eq!(find(&vars3, "tau_m").value_reference, find(&vars3, "qdd_star").value_reference + 1);
    }

    #[test]
    fn every_model_file_groups() {
        let files = model_files();
        assert!(files.len() >= 5, "{files:?}");
        for file in files {
            let what = file.display().to_string();
            let model = Model::from_file(&file).unwrap_or_else(|e| panic!("{what}: {e}"));
            let vars = variables(&model);
            let vars3 = variables3(&vars);
            check_invariants(&vars, &vars3, &what);
            let n = model.nq();
            for name in ["q_star", "qd_star", "qdd_star", "q", "qd", "qdd", "stick", "n_stick", "eps_joint"] {
                assert_eq!(find(&vars3, name).dimensions, [n], "{what}: {name}");
            }
            assert_eq!(find(&vars3, "f").dimensions, [n, 3], "{what}");
            assert_eq!(find(&vars3, "n").dimensions, [n, 3], "{what}");
        }
    }

    #[test]
    #[should_panic(expected = "not consecutive")]
    fn a_stem_split_by_another_is_refused() {
        let mut vars = variables(&Model::reference_rrpr());
        vars.swap(1, 4); // q_star[2] <-> qd_star[1]
        variables3(&vars);
    }

    #[test]
    #[should_panic(expected = "cannot form one FMI 3.0 array")]
    fn a_stem_of_mixed_causality_is_refused() {
        let mut vars = variables(&Model::reference_rrpr());
        let i = vars.iter().position(|v| v.name == "q[2]").unwrap();
        vars[i].causality = Causality::Input;
        variables3(&vars);
    }
}
