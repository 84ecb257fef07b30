//! Where the searches that keep no graph hold their markings: a table of
//! packed markings in open addressing, grown in place (`table`), in memory
//! mapped from the system (`pages`).

mod pages;
mod table;

pub(crate) use pages::Stack;
pub(crate) use table::{EMPTY, MarkingTable, copy_marking, hash};
