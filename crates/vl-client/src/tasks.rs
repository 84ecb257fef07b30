//! The Guest's tasks (thesis A.1.4, its Settings/Tasks Database): a
//! definition — goal, path, virtual obstacles, speed, time limit — saved
//! under a name with its experiment, in the user's configuration directory
//! (`$XDG_CONFIG_HOME/vl/tasks/NAME.json`), to be loaded and run again.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use thiserror::Error;
use vl_core::{Definition, ExperimentId};

/// The longest name a task has.
const MAX_NAME: usize = 64;

/// A task's name: letters, digits, spaces, dashes and underscores, so it
/// is a file name of the tasks folder and nothing else.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub struct TaskName(String);

impl std::str::FromStr for TaskName {
    type Err = TaskError;

    fn from_str(name: &str) -> Result<Self, Self::Err> {
        let name = name.trim();
        let fits = !name.is_empty()
            && name.len() <= MAX_NAME
            && name
                .chars()
                .all(|c| c.is_alphanumeric() || matches!(c, ' ' | '-' | '_'));
        if fits {
            Ok(TaskName(name.to_owned()))
        } else {
            Err(TaskError::Name(name.to_owned()))
        }
    }
}

impl std::fmt::Display for TaskName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

/// A definition kept to be run again.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Task {
    pub experiment: ExperimentId,
    pub definition: Definition,
}

#[derive(Debug, Error)]
pub enum TaskError {
    #[error(
        "\"{0}\" cannot name a task: use up to {MAX_NAME} letters, digits, spaces, dashes and underscores"
    )]
    Name(String),
    #[error("{0}: {1}")]
    Io(PathBuf, std::io::Error),
    #[error("{0} is not a task vl saved: {1}")]
    NotATask(PathBuf, serde_json::Error),
    #[error("no task \"{name}\"; saved: {saved}")]
    Unknown { name: TaskName, saved: String },
    #[error("no configuration directory to keep tasks in (set HOME or XDG_CONFIG_HOME)")]
    NoConfigDir,
}

/// A folder of tasks.
#[derive(Debug, Clone)]
pub struct Tasks {
    dir: PathBuf,
}

impl Tasks {
    pub fn at(dir: &Path) -> Tasks {
        Tasks {
            dir: dir.to_owned(),
        }
    }

    /// This user's tasks.
    pub fn of_user() -> Result<Tasks, TaskError> {
        let dir = crate::settings::config_dir().ok_or(TaskError::NoConfigDir)?;
        Ok(Tasks::at(&dir.join("tasks")))
    }

    fn path(&self, name: &TaskName) -> PathBuf {
        self.dir.join(format!("{name}.json"))
    }

    /// Keeps `task` as `name`, replacing any task of that name.
    /// Saves `task` as `name`; returns the file it is in.
    pub fn save(&self, name: &TaskName, task: &Task) -> Result<PathBuf, TaskError> {
        std::fs::create_dir_all(&self.dir).map_err(|e| TaskError::Io(self.dir.clone(), e))?;
        let path = self.path(name);
        let text = serde_json::to_vec_pretty(task).expect("tasks serialise");
        std::fs::write(&path, text).map_err(|e| TaskError::Io(path.clone(), e))?;
        Ok(path)
    }

    pub fn load(&self, name: &TaskName) -> Result<Task, TaskError> {
        let path = self.path(name);
        let text = std::fs::read(&path).map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound => TaskError::Unknown {
                name: name.clone(),
                saved: self
                    .names()
                    .iter()
                    .map(|n| n.to_string())
                    .collect::<Vec<_>>()
                    .join(", "),
            },
            _ => TaskError::Io(path.clone(), e),
        })?;
        serde_json::from_slice(&text).map_err(|e| TaskError::NotATask(path, e))
    }

    /// The tasks kept, by name.
    pub fn names(&self) -> Vec<TaskName> {
        let Ok(listing) = std::fs::read_dir(&self.dir) else {
            return Vec::new();
        };
        let mut names: Vec<TaskName> = listing
            .filter_map(Result::ok)
            .filter_map(|f| f.file_name().to_str()?.strip_suffix(".json")?.parse().ok())
            .collect();
        names.sort();
        names
    }
}

/// A task to run and a name to keep the run's definition under.
#[derive(Debug, Clone, Default)]
pub struct TaskChoice {
    /// Run the task saved under this name (its experiment and definition)
    /// instead of planning one.
    pub task: Option<TaskName>,
    /// Save this run's definition as a task of this name.
    pub save_task: Option<TaskName>,
}

impl TaskChoice {
    /// The task to run, if one is named.
    pub(crate) fn to_run(&self) -> Result<Option<Task>, TaskError> {
        self.task
            .as_ref()
            .map(|name| Tasks::of_user()?.load(name))
            .transpose()
    }

    /// Keeps the definition a run was given, if a name was given for it;
    /// returns the file it went to.
    pub(crate) fn keep(
        &self,
        experiment: ExperimentId,
        definition: &Definition,
    ) -> Result<Option<PathBuf>, TaskError> {
        let Some(name) = &self.save_task else {
            return Ok(None);
        };
        let task = Task {
            experiment,
            definition: definition.clone(),
        };
        Tasks::of_user()?.save(name, &task).map(Some)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_file_names_of_the_folder_and_nothing_else() {
        for bad in ["", "../x", "a/b", ".hidden", "tab\there", &"x".repeat(65)] {
            assert!(bad.parse::<TaskName>().is_err(), "{bad:?}");
        }
        assert!("lap 2_fast-one".parse::<TaskName>().is_ok());
    }

    #[test]
    fn a_saved_task_loads_as_it_was_and_a_missing_one_names_the_saved() {
        let dir = std::env::temp_dir().join(format!("vl-tasks-{}", std::process::id()));
        let tasks = Tasks::at(&dir);
        let task = Task {
            experiment: ExperimentId::new("navigation").unwrap(),
            definition: Definition {
                path: vec![vl_core::Point {
                    x_mm: 1.0,
                    y_mm: 2.0,
                }],
                max_speed_mm_s: Some(50.0),
                ..Definition::default()
            },
        };
        let name: TaskName = "lap".parse().unwrap();
        tasks.save(&name, &task).unwrap();
        assert_eq!(tasks.load(&name).unwrap(), task);
        assert_eq!(tasks.names(), vec![name]);
        let missing = tasks.load(&"other".parse().unwrap()).unwrap_err();
        assert!(missing.to_string().contains("saved: lap"), "{missing}");
        let _ = std::fs::remove_dir_all(dir);
    }
}
