//! The window's tasks: the definition in force saved under a name, and a
//! saved one loaded and defined again (thesis A.1.4).

use vl_core::{Action, ExperimentId, GuestMessage};

use super::GuestApp;
use vl_client::{Task, TaskName};

impl GuestApp {
    /// Save the definition in force as a task; load one saved and define it.
    pub(super) fn tasks_panel(&mut self, ui: &mut egui::Ui, experiment: &ExperimentId) {
        let Some(tasks) = self.tasks.clone() else {
            return;
        };
        egui::CollapsingHeader::new("Tasks").show(ui, |ui| {
            ui.horizontal(|ui| {
                let label = ui.label("Name");
                ui.add(egui::TextEdit::singleline(&mut self.task_name).desired_width(120.0))
                    .labelled_by(label.id);
                let definition = self.session.definition.clone();
                let save = ui.add_enabled(definition.is_some(), egui::Button::new("Save"));
                if let (true, Some(definition)) = (save.clicked(), definition) {
                    let saved = self.task_name.parse::<TaskName>().and_then(|name| {
                        let file = tasks.save(
                            &name,
                            &Task {
                                experiment: experiment.clone(),
                                definition,
                            },
                        )?;
                        Ok((name, file))
                    });
                    self.task_note = Some(match saved {
                        Ok((name, file)) => {
                            format!("Saved the definition as \"{name}\" in {}.", file.display())
                        }
                        Err(e) => e.to_string(),
                    });
                }
            });
            let may_define = self.session.is_operator() && self.session.allows(Action::Define);
            for name in tasks.names() {
                let load = egui::Button::new(format!("Load \"{name}\""));
                if ui.add_enabled(may_define, load).clicked() {
                    self.task_note = Some(match tasks.load(&name) {
                        Ok(task) if task.experiment != *experiment => format!(
                            "\"{name}\" is a task of {}: mount it first.",
                            task.experiment
                        ),
                        Ok(task) => {
                            if let Some(goal) = task.definition.goal {
                                self.goal = goal;
                            }
                            self.virtual_obstacles = task.definition.virtual_obstacles.clone();
                            self.connection.send(GuestMessage::Define {
                                definition: task.definition,
                            });
                            format!("Loaded \"{name}\" and defined it again.")
                        }
                        Err(e) => e.to_string(),
                    });
                }
            }
            if let Some(note) = &self.task_note {
                ui.label(note);
            }
        });
    }
}
