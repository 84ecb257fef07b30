//! Every run recorded: the hub opens a run's file when it starts, hands the
//! recorder what it sends everyone, and closes the file after `done`.

use serde_json::json;
use vl_core::{
    Definition, ExperimentId, GuestMessage, HostMessage, MountedLab, RecordedRun, RecordingName,
    RecordingNote, Summary,
};

use super::Hub;
use crate::lab::Watching;
use vl_record::{Begin, Level, Owner, Recordable};

/// The run being recorded, and the frames kept encoded for it while it
/// lasts (as for a watcher: nobody watching, no frame is encoded).
pub(super) struct RunRecording {
    name: RecordingName,
    _frames: Watching,
}

impl Hub {
    /// Opens run `self.runs`'s file, with the lab as mounted, the
    /// definition, the Host's settings and the forecast it passed.
    pub(super) fn begin_recording(
        &mut self,
        id: u64,
        experiment: ExperimentId,
        definition: &Definition,
        controller: Option<std::sync::Arc<[u8]>>,
    ) {
        let Some(catalogue) = &self.config.recordings else {
            return;
        };
        let started_ms = vl_record::now_ms();
        let user = self.user_of(id);
        let run = RecordedRun {
            name: RecordingName::of_run(started_ms, self.runs),
            run: self.runs,
            experiment: Some(experiment),
            started_ms,
            user: user.clone(),
            ending: None,
            seconds: None,
            bytes: 0,
        };
        let owner = catalogue.owner(user.as_deref(), id);
        let mut beginning = self.beginning(run, owner, definition);
        beginning.controller = controller;
        if let Some(name) = self.lab.record.begin(beginning) {
            self.recording = Some(RunRecording {
                name,
                _frames: Watching::new(&self.lab.watchers),
            });
            if let Some(verdict) = &self.verdict {
                let forecast = HostMessage::Forecast(Box::new(verdict.clone()));
                self.lab.record.send(Recordable::Sent(forecast));
            }
        }
    }

    /// With `--record-idle`, begins the file of the time until the next
    /// run, which only administrators see.
    pub(super) fn begin_idle(&mut self) {
        let Some(catalogue) = self.config.recordings.as_ref().filter(|c| c.record_idle) else {
            return;
        };
        let started_ms = vl_record::now_ms();
        let run = RecordedRun {
            name: RecordingName::between_runs(started_ms),
            run: 0,
            experiment: None,
            started_ms,
            user: None,
            ending: None,
            seconds: None,
            bytes: 0,
        };
        let owner = catalogue.owner(None, 0);
        let definition = self.definition.clone().unwrap_or_default();
        self.lab
            .record
            .begin(self.beginning(run, owner, &definition));
    }

    /// What a file begins with: the lab as mounted (as it stands, before a
    /// mount), the definition and the Host's settings.
    fn beginning(&self, run: RecordedRun, owner: Owner, definition: &Definition) -> Begin {
        let config = &self.config;
        // Between runs, what is mounted (or the first offered) is the lab.
        let experiment = run
            .experiment
            .clone()
            .or_else(|| self.experiment.as_ref().map(|e| e.id.clone()))
            .or_else(|| config.experiments.ids().into_iter().next())
            .expect("a Host offers an experiment");
        Begin {
            run,
            owner,
            lab: MountedLab {
                experiment,
                scene: self.scene(),
            },
            definition: definition.clone(),
            controller: None,
            config: json!({
                "experiments": config.experiments.ids(),
                "lease_s": config.lease.as_secs_f64(),
                "slot_s": config.slot.map(|s| s.as_secs_f64()),
                "frames": format!("{:?}", config.frames),
                "forecast": format!("{:?}", config.forecast),
                "reset": config.reset,
                "compensate_latency": config.compensate_latency,
            }),
        }
    }

    /// Says in the run's summary where it was recorded, and whether its
    /// recording stopped early; a file that was not kept is not named.
    pub(super) fn note_recording(&self, summary: &mut Summary) {
        summary.recording = self.recording.as_ref().and_then(|r| {
            let stopped = self.lab.record.stopped(&r.name);
            if stopped.as_ref().is_some_and(|s| !s.kept) {
                return None;
            }
            Some(RecordingNote {
                name: r.name.clone(),
                dropped_frames: self.lab.record.dropped_frames(),
                stopped: stopped.map(|s| s.why),
            })
        });
    }

    /// The run's `done` was sent: its file closes (and the time until the
    /// next run's begins, when that is recorded).
    pub(super) fn end_recording(&mut self) {
        if self.recording.take().is_some() {
            self.lab.record.end();
            self.begin_idle();
        }
    }

    /// Records what the Host sends everyone, while a run is recorded.
    pub(super) fn record_sent(&self, message: &HostMessage) {
        if self.lab.record.active() {
            self.lab.record.send(Recordable::Sent(message.clone()));
        }
    }

    /// Writes a line in the run's log (firings, refusals, faults): what
    /// the Host saw happen during it; live, for Foxglove's watchers.
    pub(super) fn record_log(&self, level: Level, text: String) {
        // Nobody watching the log live is no error.
        let _ = self.lab.log.send((level, text.clone()));
        self.lab.record.send(Recordable::Log(level, text));
    }

    /// Records a command the run took.
    pub(super) fn record_command(&self, command: GuestMessage) {
        self.lab.record.send(Recordable::Command(command));
    }
}
