//! The operator's own controller (issue 58): its file arrives in parts
//! (each within a message's size), is checked whole by the sandbox, and is
//! kept for the definitions that name it, the twin's forecast, the run and
//! its recording.

use std::sync::Arc;

use base64::Engine as _;
use vl_core::{
    Action, Definition, ErrorCode, Experiment, HostMessage, MAX_MODULE_BYTES, ModuleHash,
};
use vl_sandbox::Module;

use super::Hub;

/// The bytes of modules the Host checks a second on average, and at once:
/// a check parses and validates the whole file, so a flood of the largest
/// would cost everyone; four of the largest go at once, then one a second.
pub(super) const CHECKED_BYTES_PER_S: f64 = MAX_MODULE_BYTES as f64;
pub(super) const CHECKED_BYTES_BURST: f64 = 4.0 * MAX_MODULE_BYTES as f64;

/// A module that passed its checks, and its file as sent.
#[derive(Clone)]
pub(super) struct Taken {
    pub(super) module: Arc<Module>,
    pub(super) file: Arc<[u8]>,
}

/// A module arriving in parts.
pub(super) struct Upload {
    total: usize,
    file: Vec<u8>,
}

impl Hub {
    /// Takes a part of the operator's controller; the last part's file is
    /// checked, kept and answered with its hash.
    pub(super) fn take_controller_part(&mut self, id: u64, offset: u64, total: u64, data: &str) {
        if !self
            .experiment
            .as_ref()
            .is_some_and(Experiment::runs_a_controller)
        {
            let why = "this experiment runs no controller of yours: mount one that does";
            return self.refuse(id, ErrorCode::NotAllowedNow, why);
        }
        if !self.permitted(id, Action::Define) {
            return;
        }
        let refuse = |hub: &mut Hub, why: String| {
            hub.upload = None;
            hub.refuse(id, ErrorCode::InvalidDefinition, why);
        };
        let Ok(total) = usize::try_from(total) else {
            return refuse(self, "a controller's total is no size".into());
        };
        if total > MAX_MODULE_BYTES || total == 0 {
            let why = format!(
                "a controller is a file of 1 to {MAX_MODULE_BYTES} bytes (2 MiB), not {total}"
            );
            return refuse(self, why);
        }
        let Ok(part) = base64::engine::general_purpose::STANDARD.decode(data) else {
            let why = format!("the controller's part at byte {offset} is not base64");
            return refuse(self, why);
        };
        if offset == 0 {
            self.upload = Some(Upload {
                total,
                file: Vec::new(),
            });
        }
        let Some(upload) = self.upload.as_mut() else {
            let why = "a controller's first part starts at byte 0".to_owned();
            return refuse(self, why);
        };
        if upload.total != total || offset != upload.file.len() as u64 {
            let why = format!(
                "the controller's parts came out of order: byte {} of {} was next, not {offset} of {total}",
                upload.file.len(),
                upload.total
            );
            return refuse(self, why);
        }
        if upload.file.len() + part.len() > total {
            let why = format!("the controller's parts carry more than its {total} bytes");
            return refuse(self, why);
        }
        upload.file.extend_from_slice(&part);
        if upload.file.len() < total {
            return;
        }
        let Some(Upload { file, .. }) = self.upload.take() else {
            return;
        };
        let wait = self.checks.take(file.len() as f64);
        if !wait.is_zero() {
            self.checks.refund(file.len() as f64);
            let why = format!(
                "the Host checks {} MiB of controllers a second: send it again in {:.1} s",
                MAX_MODULE_BYTES >> 20,
                wait.as_secs_f64()
            );
            return self.refuse(id, ErrorCode::NotAllowedNow, why);
        }
        match Module::load(&file) {
            Ok(module) => {
                let taken = HostMessage::ControllerTaken {
                    sha256: module.hash(),
                    bytes: file.len() as u64,
                };
                self.controller = Some(Taken {
                    module: Arc::new(module),
                    file: file.into(),
                });
                self.send(id, taken);
            }
            Err(e) => self.refuse(id, ErrorCode::InvalidDefinition, e.to_string()),
        }
    }

    /// The controller `definition` names, if the mounted experiment runs
    /// one: it must be the one sent.
    pub(super) fn named_controller(
        &self,
        definition: &Definition,
    ) -> Result<Option<Taken>, String> {
        if !self
            .experiment
            .as_ref()
            .is_some_and(Experiment::runs_a_controller)
        {
            return Ok(None);
        }
        let taken = self.controller.as_ref();
        match (definition.controller, taken) {
            (Some(named), Some(taken)) if named == taken.module.hash() => Ok(Some(taken.clone())),
            (Some(named), _) => Err(format!(
                "the definition names controller {}, which is not the one sent: send it first (controller messages)",
                short(named)
            )),
            (None, _) => Err(
                "this experiment runs your own controller: send it, then name it in the definition (controller: its sha256)"
                    .into(),
            ),
        }
    }
}

/// A hash's first 12 digits, as people compare them.
fn short(hash: ModuleHash) -> String {
    hash.to_string()[..12].to_owned()
}
