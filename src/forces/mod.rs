//! Generalized forces of the joints: drives (2.1), dry friction (3.11)–(3.15)
//! and the rotors of motor drives.

pub mod drive;
pub mod friction;
pub mod rotor;
