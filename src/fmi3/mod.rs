//! The FMI 3.0 co-simulation layer, beside the FMI 2.0 one ([`crate::fmi`]):
//! the same engine, the same variables (grouped into arrays by
//! [`variables3`](crate::fmi::description::variables3)) and the same FMI 2.0
//! [`Instance`](crate::fmi) underneath, with FMI 3.0's modes on top of its
//! life cycle, early return at stick-slip and clearance events, and the
//! intermediate update of the drive inputs at the engine's own sub-steps.
//! Compiled with the crate's feature `fmi3` (on by default), which the FMI
//! 2.0 library is built without (docs/platforms.md).
//!
//! * [`api`] — every FMI 3.0 function, as plain `extern "C"` functions. The
//!   library `StickSlipManipulator` of the FMI 3.0 FMU is the crate `fmi3/`,
//!   which exports each of them under its FMI name and nothing else (the
//!   FMI 2.0 library exports none of them);
//! * `boundary` — the handle behind an `fmi3Instance`: the instance, and
//!   what a master's calls from inside the intermediate-update callback may
//!   see (they run while `fmi3DoStep` holds the instance);
//! * `instance` — one FMI 3.0 instance: its mode, the array value
//!   references, and `fmi3DoStep` with its observer of the sub-steps.

pub mod api;
mod boundary;
mod frame;
mod instance;
#[cfg(test)]
mod tests;
mod values;
