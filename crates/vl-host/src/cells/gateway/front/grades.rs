//! Grades for an LMS from runs at cells: a cell tells the link of the
//! Guest who drove a run that it ended (`LinkDown::RunEnded`, from its
//! lab's event), and the gateway grades it as the person it let in, for
//! the launch whose session let them in (`Lti::run_ended`).

use vl_core::Summary;

use crate::accounts::gate::Admitted;
use crate::server::HostConfig;

/// Grades the run that `admitted` drove at its cell, if an LMS sent them.
pub(super) fn grade(config: &HostConfig, admitted: &Admitted, summary: &Summary) {
    if let Some(lti) = &config.lti {
        lti.run_ended(None, admitted, summary);
    }
}
