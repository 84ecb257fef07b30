//! The user's own controller in the window (issue 58): on an experiment
//! whose run it drives, a file chosen in the picker, dropped on the window
//! or its path typed is sent to the Host, which checks it and answers its hash; Define then
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
            if ui.button("Choose…").clicked() {
                add_symbol_fonts(ui.ctx());
                self.choose_controller();
            }
            ui.add(
                egui::TextEdit::singleline(&mut self.controller_path)
                    .hint_text("or drop a .wasm or .wat file here, or type its path")
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

    /// Opens the file picker on WebAssembly modules (binary or text) and
    /// folders, in the folder typed or the last file's.
    fn choose_controller(&mut self) {
        let filter = Box::new(|path: &Path| {
            path.extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("wasm") || e.eq_ignore_ascii_case("wat"))
        });
        let mut dialog = egui_file::FileDialog::open_file()
            .title("Your controller: a .wasm or .wat file")
            .show_files_filter(filter)
            .show_new_folder(false)
            .show_rename(false);
        let typed = Path::new(self.controller_path.trim());
        let folder = match typed.is_dir() {
            true => Some(typed),
            false => typed.parent().filter(|f| f.is_dir()),
        };
        if let Some(folder) = folder {
            dialog = dialog.initial_path(folder);
        }
        dialog.open();
        self.controller_picker = Some(dialog);
    }

    /// The file picker while it is open: the file chosen is sent.
    pub(super) fn show_controller_picker(&mut self, ctx: &egui::Context) {
        let Some(dialog) = &mut self.controller_picker else {
            return;
        };
        let chosen = match dialog.show(ctx).selected() {
            true => dialog.path().map(Path::to_path_buf),
            false => None,
        };
        if !dialog.visible() {
            self.controller_picker = None;
        }
        if let Some(path) = chosen {
            self.send_controller(&path);
        }
    }

    /// A file dropped on the window, on an experiment that takes one.
    pub(super) fn take_dropped(&mut self, ctx: &egui::Context) {
        let dropped = ctx.input(|i| i.raw.dropped_files.first().map(|f| f.path().to_path_buf()));
        if let Some(path) = dropped.filter(|_| self.runs_a_controller()) {
            self.send_controller(&path);
        }
    }

    /// Reads the file (refused unread when it is too large) and sends it
    /// to the Host in parts; its path stays in the row, to send again.
    fn send_controller(&mut self, path: &Path) {
        self.controller_path = path.display().to_string();
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

/// egui's emoji fonts as the last fallbacks, for the picker's folder and
/// file symbols; in use from the next frame, the picker's first.
fn add_symbol_fonts(ctx: &egui::Context) {
    use egui::epaint::text::{FontInsert, FontPriority, InsertFontFamily};
    for (name, data) in [
        ("emoji-icon-font", epaint_default_fonts::EMOJI_ICON),
        (
            "NotoEmoji-Regular",
            epaint_default_fonts::NOTO_EMOJI_REGULAR,
        ),
    ] {
        ctx.add_font(FontInsert::new(
            name,
            egui::FontData::from_static(data),
            vec![InsertFontFamily {
                family: egui::FontFamily::Proportional,
                priority: FontPriority::Lowest,
            }],
        ));
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
