//! One way to print what a command found: a [`Table`] for people, or with
//! `--json` the same report as JSON for programs.

use anyhow::Result;
#[cfg(feature = "host")]
pub(crate) use vl_report::table::Table;
pub(crate) use vl_report::table::{Report, count};

/// Prints `report` as JSON when `json`, else as its table.
pub(crate) fn emit(report: &impl Report, json: bool) -> Result<()> {
    if json {
        println!("{}", serde_json::to_string_pretty(report)?);
    } else {
        print!("{}", report.table());
    }
    Ok(())
}
