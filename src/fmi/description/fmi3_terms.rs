//! FMI 3.0's names for the FMI 2.0 functions the shared texts name: the
//! messages of the FMI 2.0 instance under the FMI 3.0 layer (its logger) and
//! the descriptions the FMI 3.0 modelDescription takes from the FMI 2.0
//! variables and log categories.

/// The FMI 2.0 names the shared instance's messages use, and what an FMI 3.0
/// master calls them (the longer names first: they contain the shorter).
const FMI3_NAMES: [(&str, &str); 20] = [
    ("fmi2SetRealInputDerivatives", "fmi3SetFloat64"),
    ("fmi2LastSuccessfulTime", "lastSuccessfulTime of fmi3DoStep"),
    ("fmi2EnterInitializationMode", "fmi3EnterInitializationMode"),
    ("fmi2ExitInitializationMode", "fmi3ExitInitializationMode"),
    ("fmi2SetupExperiment", "fmi3EnterInitializationMode"),
    ("fmi2GetRealStatus", "fmi3DoStep"),
    ("fmi2SetFMUstate", "fmi3SetFMUState"),
    ("fmi2GetFMUstate", "fmi3GetFMUState"),
    ("fmi2FreeInstance", "fmi3FreeInstance"),
    ("fmi2Instantiate", "fmi3InstantiateCoSimulation"),
    ("fmi2SetBoolean", "fmi3SetBoolean"),
    ("fmi2GetBoolean", "fmi3GetBoolean"),
    ("fmi2Terminate", "fmi3Terminate"),
    ("fmi2SetReal", "fmi3SetFloat64"),
    ("fmi2GetReal", "fmi3GetFloat64"),
    ("fmi2Warning", "fmi3Warning"),
    ("fmi2Discard", "fmi3Discard"),
    ("fmi2Error", "fmi3Error"),
    ("fmi2DoStep", "fmi3DoStep"),
    ("fmi2Reset", "fmi3Reset"),
];

/// `message` with the FMI 2.0 function names of [`FMI3_NAMES`] in FMI 3.0's.
pub fn in_fmi3_terms(message: &str) -> String {
    if !message.contains("fmi2") {
        return message.to_string();
    }
    FMI3_NAMES.iter().fold(message.to_string(), |m, (fmi2, fmi3)| m.replace(fmi2, fmi3))
}

#[cfg(test)]
mod tests {
    use super::in_fmi3_terms;

    #[test]
    fn messages_name_the_fmi3_functions() {
        assert_eq!(
            in_fmi3_terms("the state stays at t = 1 s (fmi2LastSuccessfulTime); call fmi2Reset, fmi2SetFMUstate"),
            "the state stays at t = 1 s (lastSuccessfulTime of fmi3DoStep); call fmi3Reset, fmi3SetFMUState"
        );
        assert_eq!(in_fmi3_terms("fmi2SetRealInputDerivatives: ignored"), "fmi3SetFloat64: ignored");
        assert_eq!(in_fmi3_terms("no FMI name here"), "no FMI name here");
    }
}
