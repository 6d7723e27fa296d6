//! The call-sequence state machine of an FMI 2.0 co-simulation slave:
//! instantiated → initialization mode → step complete (⇄ step failed) →
//! terminated; any state → error on an internal failure; fmi2Reset back to
//! instantiated. Each exported function names the set of states that allow it.

/// Where an instance is in its life cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum LifeCycle {
    /// After fmi2Instantiate or fmi2Reset.
    Instantiated,
    /// Between fmi2EnterInitializationMode and fmi2ExitInitializationMode.
    InitializationMode,
    /// Step mode, last step completed.
    StepComplete,
    /// Step mode, last fmi2DoStep returned fmi2Discard; the state is the one
    /// of the last good communication point.
    StepFailed,
    /// After fmi2Terminate.
    Terminated,
    /// After an internal failure (a caught panic): only reset, restore of an
    /// FMU state, termination, getters and free are allowed.
    Error,
}

impl LifeCycle {
    const ALL: [LifeCycle; 6] = [
        LifeCycle::Instantiated,
        LifeCycle::InitializationMode,
        LifeCycle::StepComplete,
        LifeCycle::StepFailed,
        LifeCycle::Terminated,
        LifeCycle::Error,
    ];

    const fn bit(self) -> u8 {
        1 << self as u8
    }

    /// Name for messages.
    pub(crate) fn name(self) -> &'static str {
        match self {
            LifeCycle::Instantiated => "instantiated",
            LifeCycle::InitializationMode => "initialization mode",
            LifeCycle::StepComplete => "step complete",
            LifeCycle::StepFailed => "step failed",
            LifeCycle::Terminated => "terminated",
            LifeCycle::Error => "error",
        }
    }

    /// Code in serialized FMU states.
    pub(crate) fn code(self) -> u8 {
        self as u8
    }

    /// Inverse of [`LifeCycle::code`].
    pub(crate) fn from_code(code: u8) -> Option<LifeCycle> {
        LifeCycle::ALL.into_iter().find(|l| l.code() == code)
    }

    /// True before fmi2ExitInitializationMode (parameters of every kind may
    /// be set; the engine is started from them at the end).
    pub(crate) fn is_configuring(self) -> bool {
        matches!(self, LifeCycle::Instantiated | LifeCycle::InitializationMode)
    }

    /// True where the engine holds an initialized state.
    pub(crate) fn is_running(self) -> bool {
        matches!(self, LifeCycle::StepComplete | LifeCycle::StepFailed | LifeCycle::Terminated | LifeCycle::Error)
    }
}

/// A set of life-cycle states.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct States(u8);

impl States {
    /// The states in `list`.
    pub(crate) const fn of(list: &[LifeCycle]) -> States {
        let mut bits = 0;
        let mut i = 0;
        while i < list.len() {
            bits |= list[i].bit();
            i += 1;
        }
        States(bits)
    }

    /// True if `state` is in the set.
    pub(crate) fn contains(self, state: LifeCycle) -> bool {
        self.0 & state.bit() != 0
    }

    /// "instantiated, initialization mode" for messages.
    pub(crate) fn names(self) -> String {
        LifeCycle::ALL.iter().filter(|l| self.contains(**l)).map(|l| l.name()).collect::<Vec<_>>().join(", ")
    }
}
