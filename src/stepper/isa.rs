//! Instruction-set selection for the stepping loop.
//!
//! The loop that advances one communication interval
//! (`Integrator::step_interval`) and everything it calls per sub-step are
//! `#[inline(always)]`, so the loop is compiled twice: once for the x86-64
//! baseline every host has, and once with AVX2 enabled, chosen at run time
//! when the processor has it. A shared library (the FMU) built for the
//! baseline alone would give away a fifth of its speed; one built for AVX2
//! alone would crash hosts without it.
//!
//! Both variants give bit-identical results. Rust never fuses a·b + c into a
//! fused multiply–add unless the code asks for it (this crate never does),
//! and AVX2 does not enable FMA: both variants perform the same IEEE
//! operations in the same order. The AVX2 one only encodes them in VEX
//! three-operand form with wider registers (fewer register moves and
//! shuffles around the 3-vectors). `tests/engine/instruction_sets.rs` runs the
//! reference motion under both and compares every output bit for bit.

/// The instruction set the stepping loop runs with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InstructionSet {
    /// The target's baseline (SSE2 on x86-64): runs everywhere.
    Baseline,
    /// x86-64 with AVX2, detected at run time.
    Avx2,
}

impl InstructionSet {
    /// The fastest instruction set this processor supports.
    pub fn best_available() -> InstructionSet {
        if InstructionSet::Avx2.is_available() {
            InstructionSet::Avx2
        } else {
            InstructionSet::Baseline
        }
    }

    /// True if this processor can run the loop compiled for `self`.
    pub fn is_available(self) -> bool {
        match self {
            InstructionSet::Baseline => true,
            #[cfg(target_arch = "x86_64")]
            InstructionSet::Avx2 => std::arch::is_x86_feature_detected!("avx2"),
            #[cfg(not(target_arch = "x86_64"))]
            InstructionSet::Avx2 => false,
        }
    }

    /// Its name, as in error messages.
    pub fn name(self) -> &'static str {
        match self {
            InstructionSet::Baseline => "baseline",
            InstructionSet::Avx2 => "AVX2",
        }
    }
}
