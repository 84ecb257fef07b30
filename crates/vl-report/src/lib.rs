//! What `vl`'s commands and windows report, at the bottom of the crate
//! graph so every crate prints alike: a result people read as an aligned
//! table and programs as JSON (`table`), and what a job cost in memory
//! (`memory`: a counting allocator the binary switches on only for the
//! commands that measure memory, and the process's peak resident set).

mod memory;
pub mod table;

pub use memory::{Counting, PeakMemory, peak_bytes, peak_resident_bytes};
pub use table::{Report, Table};
