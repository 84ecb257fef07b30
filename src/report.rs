//! One way to print what a command found: a [`Table`] for people, or with
//! `--json` the same report as JSON for programs.

use anyhow::Result;
use serde::Serialize;
pub(crate) use vl_core::table::{Table, count, yes};

/// A report a command prints.
pub(crate) trait Report: Serialize {
    /// The report as people read it.
    fn table(&self) -> Table;
}

/// Prints `report` as JSON when `json`, else as its table.
pub(crate) fn emit(report: &impl Report, json: bool) -> Result<()> {
    if json {
        println!("{}", serde_json::to_string_pretty(report)?);
    } else {
        print!("{}", report.table());
    }
    Ok(())
}

/// Error statistics in a table cell; a dash when nothing was measured.
pub(crate) fn error_mm(e: Option<vl_core::ErrorMm>) -> String {
    e.map_or("–".into(), |e| {
        format!(
            "mean {:.1} mm, max {:.1} mm, rms {:.1} mm",
            e.mean, e.max, e.rms
        )
    })
}
