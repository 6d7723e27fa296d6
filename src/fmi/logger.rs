//! Messages to the master's logger callback, filtered by log category.

#[cfg(feature = "fmi3")]
use super::description::in_fmi3_terms;
use super::description::LOG_CATEGORIES;
use super::status::Status;
use fmi_sys::fmi2::{fmi2CallbackLogger, fmi2ComponentEnvironment};
#[cfg(feature = "fmi3")]
use fmi_sys::fmi3::{fmi3InstanceEnvironment, fmi3LogMessageCallback};
use std::ffi::CString;

/// A log category of the modelDescription (`logAll` is only a name for all
/// of them in fmi2SetDebugLogging).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Category {
    Events,
    StatusWarning,
    StatusDiscard,
    StatusError,
}

const _: () = assert!(LOG_CATEGORIES.len() == Category::COUNT + 1, "LOG_CATEGORIES: one per Category, then logAll");

impl Category {
    /// Number of categories; `logAll` follows them in [`LOG_CATEGORIES`].
    const COUNT: usize = 4;

    /// Index into [`LOG_CATEGORIES`].
    fn index(self) -> usize {
        self as usize
    }

    /// The category of a message that comes with `status`.
    pub(crate) fn of_status(status: Status) -> Category {
        match status {
            Status::Ok => Category::Events,
            Status::Warning => Category::StatusWarning,
            Status::Discard => Category::StatusDiscard,
            Status::Error => Category::StatusError,
        }
    }
}

/// The messages of a [`Logger::memory`]: status, category, text.
#[cfg(test)]
pub(crate) type MemoryLog = std::rc::Rc<std::cell::RefCell<Vec<(Status, &'static str, String)>>>;

/// Where messages go.
#[derive(Debug, Clone)]
enum Sink {
    /// The master's `fmi2CallbackLogger`.
    Callback { callback: fmi2CallbackLogger, environment: fmi2ComponentEnvironment, instance_name: CString },
    /// The master's `fmi3LogMessageCallback` (FMI 3.0: no instance name, no
    /// printf format).
    #[cfg(feature = "fmi3")]
    Fmi3 { callback: fmi3LogMessageCallback, environment: fmi3InstanceEnvironment },
    /// Nowhere: the replays of a run's sensitivities, whose messages would
    /// repeat the run's (see `super::experiment`).
    Silent,
    /// Kept in memory, for the unit tests.
    #[cfg(test)]
    Memory(MemoryLog),
}

/// The logger of one instance.
#[derive(Debug, Clone)]
pub(crate) struct Logger {
    sink: Sink,
    enabled: [bool; Category::COUNT],
}

impl Logger {
    /// A logger calling `callback` with `environment` and `instance_name`.
    /// Status messages are on; events follow `logging_on`.
    pub(crate) fn new(
        callback: fmi2CallbackLogger,
        environment: fmi2ComponentEnvironment,
        instance_name: CString,
        logging_on: bool,
    ) -> Logger {
        Logger::with_sink(Sink::Callback { callback, environment, instance_name }, logging_on)
    }

    /// A logger calling the FMI 3.0 `callback` with `environment`.
    #[cfg(feature = "fmi3")]
    pub(crate) fn fmi3(
        callback: fmi3LogMessageCallback,
        environment: fmi3InstanceEnvironment,
        logging_on: bool,
    ) -> Logger {
        Logger::with_sink(Sink::Fmi3 { callback, environment }, logging_on)
    }

    fn with_sink(sink: Sink, logging_on: bool) -> Logger {
        let mut enabled = [true; Category::COUNT];
        enabled[Category::Events.index()] = logging_on;
        Logger { sink, enabled }
    }

    /// A logger that passes nothing on.
    pub(crate) fn silent() -> Logger {
        Logger::with_sink(Sink::Silent, false)
    }

    /// A logger that keeps its messages in the returned list.
    #[cfg(test)]
    pub(crate) fn memory(logging_on: bool) -> (Logger, MemoryLog) {
        let list = MemoryLog::default();
        (Logger::with_sink(Sink::Memory(MemoryLog::clone(&list)), logging_on), list)
    }

    /// fmi2SetDebugLogging: with no categories, switches the debug category
    /// (`logEvents`) on or off; otherwise the named categories (`logAll`:
    /// every one). An unknown name changes nothing and is an error.
    pub(crate) fn set_debug_logging(&mut self, on: bool, categories: &[&str]) -> Result<(), String> {
        if categories.is_empty() {
            self.enabled[Category::Events.index()] = on;
            return Ok(());
        }
        let mut enabled = self.enabled;
        for name in categories {
            match LOG_CATEGORIES.iter().position(|(c, _)| c == name) {
                Some(Category::COUNT) => enabled = [on; Category::COUNT],
                Some(i) => enabled[i] = on,
                None => {
                    let known: Vec<&str> = LOG_CATEGORIES.iter().map(|(c, _)| *c).collect();
                    return Err(format!("unknown log category `{name}` (known: {})", known.join(", ")));
                }
            }
        }
        self.enabled = enabled;
        Ok(())
    }

    /// True if messages of `category` are passed on.
    pub(crate) fn enabled(&self, category: Category) -> bool {
        self.enabled[category.index()]
    }

    /// Passes `message` on if its category is enabled.
    pub(crate) fn log(&self, status: Status, category: Category, message: &str) {
        if !self.enabled(category) {
            return;
        }
        let name = LOG_CATEGORIES[category.index()].0;
        match &self.sink {
            Sink::Callback { callback, environment, instance_name } => {
                let Some(callback) = callback else { return };
                // The message is a printf format for the master: escape '%'.
                let text = CString::new(message.replace('%', "%%").replace('\0', " ")).unwrap_or_default();
                let category = CString::new(name).unwrap_or_default();
                // SAFETY: the master's logger, given at fmi2Instantiate, takes
                // these NUL-terminated strings, which outlive the call.
                unsafe {
                    callback(*environment, instance_name.as_ptr(), status.to_fmi(), category.as_ptr(), text.as_ptr())
                }
            }
            #[cfg(feature = "fmi3")]
            Sink::Fmi3 { callback, environment } => {
                let Some(callback) = callback else { return };
                let text = CString::new(in_fmi3_terms(message).replace('\0', " ")).unwrap_or_default();
                let category = CString::new(name).unwrap_or_default();
                // SAFETY: the master's callback, given at fmi3InstantiateCoSimulation,
                // takes these NUL-terminated strings, which outlive the call.
                unsafe { callback(*environment, status.to_fmi(), category.as_ptr(), text.as_ptr()) }
            }
            Sink::Silent => {}
            #[cfg(test)]
            Sink::Memory(list) => list.borrow_mut().push((status, name, message.to_string())),
        }
    }
}
