//! The user's own controller in the window (issue 58): on an experiment
//! whose run it drives, a file dropped on the window (or its path typed)
//! is sent to the Host, which checks it and answers its hash; Define then
//! names it, with the goal clicked on the view.

use std::path::{Path, PathBuf};

use vl_core::{Definition, Experiment, ModuleHash};

use super::GuestApp;

impl GuestApp {
    /// Whether the mounted experiment's run is the user's controller's.
    pub(super) fn runs_a_controller(&self) -> bool {
        self.session
            .mounted()
            .is_some_and(Experiment::runs_a_controller)
    }

    /// Whether the mounted experiment's run takes the operator's commands
    /// (none mounted yet: the stick is shown).
    pub(super) fn takes_commands(&self) -> bool {
        self.session
            .mounted()
            .is_none_or(Experiment::takes_commands)
    }

    /// The controller's row: what the Host took, and a path to send.
    pub(super) fn controller_row(&mut self, ui: &mut egui::Ui) {
        let taken = match self.session.controller {
            Some(hash) => format!(
                "your controller: taken, SHA-256 {}…",
                &hash.to_string()[..12]
            ),
            None => "your controller: none sent yet".to_owned(),
        };
        ui.label(taken);
        ui.horizontal(|ui| {
            ui.add(
                egui::TextEdit::singleline(&mut self.controller_path)
                    .hint_text("drop a .wasm or .wat file here, or type its path")
                    .desired_width(ui.available_width() - 60.0),
            )
            .on_hover_text("a WebAssembly module: docs/controllers.md");
            if ui
                .add_enabled(!self.controller_path.is_empty(), egui::Button::new("Send"))
                .clicked()
            {
                let path = PathBuf::from(self.controller_path.trim());
                self.send_controller(&path);
            }
        });
        // "Sent" until the Host answers for that file; its refusal is
        // the session's error.
        match &self.controller_note {
            Some(ControllerNote::Sent { hash, .. }) if self.session.controller == Some(*hash) => {}
            Some(note) => {
                ui.label(note.to_string());
            }
            None => {}
        }
    }

    /// A file dropped on the window, on an experiment that takes one.
    pub(super) fn take_dropped(&mut self, ctx: &egui::Context) {
        let dropped = ctx.input(|i| i.raw.dropped_files.first().map(|f| f.path().to_path_buf()));
        if let Some(path) = dropped.filter(|_| self.runs_a_controller()) {
            self.controller_path = path.display().to_string();
            self.send_controller(&path);
        }
    }

    /// Reads the file (refused unread when it is too large) and sends it
    /// to the Host in parts.
    fn send_controller(&mut self, path: &Path) {
        self.controller_note = Some(match vl_client::read_controller(path) {
            Ok(file) => {
                for part in vl_client::controller_parts(&file) {
                    self.connection.send(part);
                }
                ControllerNote::Sent {
                    bytes: file.len(),
                    hash: ModuleHash::of(&file),
                }
            }
            Err(e) => ControllerNote::NotSent(e.to_string()),
        });
    }

    /// The definition of a controller's run: its goal and the module the
    /// Host took; none (saying why) before it took one.
    pub(super) fn controller_definition(&mut self) -> Option<Definition> {
        let Some(controller) = self.session.controller else {
            self.plan_note = Some("Not defined: send your controller first.".into());
            return None;
        };
        self.plan_note = None;
        Some(Definition {
            goal: Some(self.goal),
            controller: Some(controller),
            virtual_obstacles: self.virtual_obstacles.clone(),
            ..Definition::default()
        })
    }
}

/// What became of the last file the user sent.
pub(super) enum ControllerNote {
    Sent { bytes: usize, hash: ModuleHash },
    NotSent(String),
}

impl std::fmt::Display for ControllerNote {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ControllerNote::Sent { bytes, .. } => {
                write!(f, "sent {bytes} bytes: the Host checks it")
            }
            ControllerNote::NotSent(why) => write!(f, "Not sent: {why}"),
        }
    }
}
