//! A run out of its file for tools that do not read MCAP: the feedback
//! and commands as CSV, the camera's frames as PNGs, the summary as JSON.

use std::fmt::Write as _;
use std::path::Path;

use serde::Serialize;
use vl_core::{Drive, Feedback, FrameHeader, GuestMessage, HostMessage, Wire};
use vl_report::table::{Report, Table};

use super::reader::{Recording, Replayed};
use super::{RecordError, Topic};

/// What `export` wrote.
#[derive(Debug, Clone, Serialize)]
pub struct Exported {
    pub dir: String,
    pub feedback_rows: usize,
    pub command_rows: usize,
    pub frames: usize,
    /// Frames whose picture did not decode (a damaged file): skipped.
    pub frames_skipped: usize,
    pub summary: bool,
    /// Pictures of the run drawn by the caller (the Guest's plots).
    pub plots: Vec<String>,
}

impl Report for Exported {
    fn table(&self) -> Table {
        Table::pairs([
            ("folder", self.dir.clone()),
            ("feedback.csv", format!("{} rows", self.feedback_rows)),
            ("commands.csv", format!("{} rows", self.command_rows)),
            (
                "frames/",
                match self.frames_skipped {
                    0 => format!("{} PNGs", self.frames),
                    n => format!("{} PNGs ({n} damaged frames skipped)", self.frames),
                },
            ),
            (
                "summary.json",
                if self.summary {
                    "written"
                } else {
                    "none: the run did not end in the file"
                }
                .to_owned(),
            ),
            ("plots", self.plots.join(", ")),
        ])
    }
}

/// Writes `recording`'s feedback, commands, frames and summary into `dir`.
pub fn export(recording: &Recording, dir: &Path) -> Result<Exported, RecordError> {
    let io = |path: &Path| {
        let path = path.to_owned();
        move |e| RecordError::Io(path, e)
    };
    let frames_dir = dir.join("frames");
    std::fs::create_dir_all(&frames_dir).map_err(io(&frames_dir))?;
    let start = recording.messages.first().map_or(0, |m| m.log_ns);
    let seconds = |ns: u64| ns.saturating_sub(start) as f64 * 1e-9;

    let mut feedback = String::from(
        "t_s,event,x_mm,y_mm,theta_rad,source,left_mm_s,right_mm_s,contact,limited,force_x,force_y,proximity\n",
    );
    let mut feedback_rows = 0;
    let mut frames = 0;
    let mut frames_skipped = 0;
    for (ns, replayed) in recording.replay()? {
        match replayed {
            Replayed::Message(HostMessage::Feedback(Feedback {
                event,
                pose,
                wheels,
                proximity,
                contact,
                force,
                limited,
                source,
                ..
            })) => {
                let [fx, fy] =
                    force.map_or([String::new(), String::new()], |f| f.map(|x| x.to_string()));
                let proximity: Vec<String> = proximity.iter().map(u16::to_string).collect();
                let _ = writeln!(
                    feedback,
                    "{:.3},{event},{:.2},{:.2},{:.4},{source:?},{:.1},{:.1},{contact},{limited},{fx},{fy},{}",
                    seconds(ns),
                    pose.x_mm,
                    pose.y_mm,
                    pose.theta_rad,
                    wheels.left_mm_s,
                    wheels.right_mm_s,
                    proximity.join(" "),
                );
                feedback_rows += 1;
            }
            Replayed::Frame(wire) => {
                let Ok((_, jpeg)) = FrameHeader::decode(&wire) else {
                    continue;
                };
                // Limits on by default: a damaged header cannot make it
                // allocate more than image's 512 MiB.
                let Ok(picture) = image::load_from_memory(jpeg) else {
                    frames_skipped += 1;
                    continue;
                };
                frames += 1;
                let path = frames_dir.join(format!("frame-{frames:05}.png"));
                picture
                    .save(&path)
                    .map_err(|e| RecordError::Io(path.clone(), std::io::Error::other(e)))?;
            }
            Replayed::Message(_) => {}
        }
    }
    let mut commands = String::from("t_s,event,seen,kind,a,b\n");
    let mut command_rows = 0;
    for m in recording.on(Topic::Commands.name()) {
        let Some(GuestMessage::Command { event, seen, drive }) = std::str::from_utf8(&m.data)
            .ok()
            .and_then(|t| GuestMessage::decode(t).ok())
        else {
            continue;
        };
        let (kind, a, b) = match drive {
            Drive::Wheels { left, right } => ("wheels", left, right),
            Drive::Velocity { v, w } => ("velocity", v, w),
        };
        let seen = seen.map_or(String::new(), |s| s.to_string());
        let _ = writeln!(
            commands,
            "{:.3},{event},{seen},{kind},{a},{b}",
            seconds(m.log_ns)
        );
        command_rows += 1;
    }
    for (name, text) in [("feedback.csv", feedback), ("commands.csv", commands)] {
        let path = dir.join(name);
        std::fs::write(&path, text).map_err(io(&path))?;
    }
    let summary = recording.summary();
    if let Some(summary) = &summary {
        let path = dir.join("summary.json");
        let text = serde_json::to_string_pretty(summary).expect("summaries serialise");
        std::fs::write(&path, text).map_err(io(&path))?;
    }
    Ok(Exported {
        dir: dir.display().to_string(),
        feedback_rows,
        command_rows,
        frames,
        frames_skipped,
        summary: summary.is_some(),
        plots: Vec::new(),
    })
}
