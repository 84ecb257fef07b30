//! The window's recordings: the runs the Host kept that this Guest may
//! see, downloaded with a progress bar, and a downloaded one played back
//! in place of the live view (and back to the lab after).

use std::path::PathBuf;

use std::time::{Duration, Instant};

use vl_core::{ErrorCode, GuestMessage, HostMessage, PartHeader, RecordedRun};

use super::GuestApp;
use vl_client::Downloading;
use vl_client::Replay;

/// The line a run is listed with.
fn describe(run: &RecordedRun) -> String {
    let what = run
        .experiment
        .as_ref()
        .map_or("between runs".to_owned(), |e| e.to_string());
    let seconds = run.seconds.map_or(String::new(), |s| format!(", {s:.1} s"));
    let ending = run.ending.map_or(String::new(), |e| format!(", {e}"));
    format!(
        "run {}: {what}{seconds}{ending}, {:.1} MB",
        run.run,
        run.bytes as f64 / 1e6
    )
}

/// How long to wait before asking again for a file still being written.
const STILL_WRITING_WAIT: Duration = Duration::from_millis(200);

impl GuestApp {
    /// Whether `message` says the file being downloaded is still being
    /// written (the run just ended): it is asked for again in a moment.
    pub(super) fn still_writing(&mut self, message: &HostMessage) -> bool {
        let still = matches!(
            message,
            HostMessage::Error {
                code: ErrorCode::NotAllowedNow,
                message,
            } if message.contains("still being recorded")
        );
        if let Some(d) = self.download.as_mut().filter(|_| still) {
            d.retry_at = Some(Instant::now() + STILL_WRITING_WAIT);
        }
        still && self.download.is_some()
    }

    /// Asks again for a file that was still being written, once it is time.
    pub(super) fn retry_download(&mut self) {
        if let Some(d) = self
            .download
            .as_mut()
            .filter(|d| d.retry_at.is_some_and(|at| Instant::now() >= at))
        {
            d.retry_at = None;
            self.connection.send(d.ask());
        }
    }

    /// A part of the recording being downloaded: kept, and the next asked for.
    pub(super) fn take_part(&mut self, header: &PartHeader, bytes: &[u8]) {
        let Some(mut downloading) = self.download.take() else {
            return;
        };
        match downloading.take(header, bytes) {
            Ok(false) => {
                self.connection.send(downloading.ask());
                self.download = Some(downloading);
            }
            Ok(true) => {
                self.recordings_note = Some(match downloading.finish() {
                    Ok(file) => format!("Downloaded {}.", file.display()),
                    Err(e) => e.to_string(),
                });
            }
            Err(e) => self.recordings_note = Some(e.to_string()),
        }
    }

    /// The runs the Host kept for this Guest, those downloaded, and the
    /// way to play one back.
    pub(super) fn recordings_panel(&mut self, ui: &mut egui::Ui) {
        let Some(dir) = self.downloads.clone() else {
            return;
        };
        egui::CollapsingHeader::new("Recordings").show(ui, |ui| {
            if ui.button("List my runs").clicked() {
                self.connection.send(GuestMessage::Recordings);
            }
            match self.session.recordings.clone() {
                None => {}
                Some(runs) if runs.is_empty() => {
                    ui.label("The Host has recorded no run of yours yet.");
                }
                Some(runs) => {
                    for run in runs {
                        ui.label(describe(&run));
                        let download = egui::Button::new(format!("Download run {}", run.run));
                        if ui.add_enabled(self.download.is_none(), download).clicked() {
                            self.start_download(&run, &dir);
                        }
                    }
                }
            }
            if let Some(d) = &self.download {
                let done = d.total.map_or(0.0, |t| d.have as f32 / t.max(1) as f32);
                ui.add(egui::ProgressBar::new(done).text(format!("downloading {}", d.name)));
            }
            for file in downloaded(&dir) {
                let name = file
                    .file_name()
                    .unwrap_or_default()
                    .to_string_lossy()
                    .into_owned();
                if ui.button(format!("Replay {name}")).clicked() {
                    match Replay::open(&file) {
                        Ok(replay) => self.play(replay),
                        Err(e) => self.recordings_note = Some(e.to_string()),
                    }
                }
            }
            if let Some(note) = &self.recordings_note {
                ui.label(note);
            }
        });
    }

    fn start_download(&mut self, run: &RecordedRun, dir: &std::path::Path) {
        match Downloading::open(&run.name, dir) {
            Ok(downloading) => {
                self.connection.send(downloading.ask());
                self.download = Some(downloading);
                self.recordings_note = None;
            }
            Err(e) => self.recordings_note = Some(e.to_string()),
        }
    }
}

/// The whole recordings in `dir`, by name.
fn downloaded(dir: &std::path::Path) -> Vec<PathBuf> {
    let Ok(listing) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut files: Vec<PathBuf> = listing
        .filter_map(Result::ok)
        .map(|f| f.path())
        .filter(|p| p.extension().is_some_and(|x| x == "mcap"))
        .collect();
    files.sort();
    files
}
