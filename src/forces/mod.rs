//! Generalized forces of the joints: drives (2.1) and dry friction (3.11)–(3.15).

pub mod drive;
pub mod friction;
