//! Grades for an LMS from runs at cells: a cell tells the link of the
//! Guest who drove a run that it ended (`LinkDown::RunEnded`, from its
//! lab's event), and the gateway tells it as its own lab's event, driven
//! by the Guest it let in — whom the LMS side grades, for the launch whose
//! session let them in.

use std::sync::Arc;

use vl_core::Summary;

use vl_host::Admitted;
use vl_host::{LabEvent, LabEvents, RunDriver, RunEnded};

/// The run that `admitted`, on connection `id`, drove at its cell ended.
pub(super) fn ended(events: &LabEvents, id: u64, admitted: &Admitted, summary: Summary) {
    events.tell(LabEvent::RunEnded(Arc::new(RunEnded {
        // Numbered by its cell, not by the gateway.
        run: None,
        driver: Some(RunDriver {
            connection: id,
            admitted: admitted.clone(),
        }),
        summary,
    })));
}
