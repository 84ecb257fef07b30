//! Experiments as their folders declare them: what the Host offers, what
//! a user defines, which of vl's components a run is made of, and what
//! counts as success.

use std::sync::Arc;

use serde::{Deserialize, Serialize};

use super::definition::{Definition, MAX_WAYPOINTS};

/// An experiment's id: the name of the folder that declares it, and what
/// URLs, recordings, commands and the wire carry (a lowercase word, `-` and
/// `_` allowed).
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub struct ExperimentId(Arc<str>);

/// Why a text cannot be an experiment's id.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "'{0}' is no experiment id: a lowercase word of at most {MAX_ID_CHARS} letters, digits, '-' or '_', starting with a letter"
)]
pub struct BadExperimentId(pub String);

/// The longest id an experiment may have.
const MAX_ID_CHARS: usize = 32;

impl ExperimentId {
    pub fn new(id: &str) -> Result<ExperimentId, BadExperimentId> {
        let word = id.len() <= MAX_ID_CHARS
            && id.starts_with(|c: char| c.is_ascii_lowercase())
            && id
                .chars()
                .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-' || c == '_');
        match word {
            true => Ok(ExperimentId(id.into())),
            false => Err(BadExperimentId(id.chars().take(64).collect())),
        }
    }

    pub fn as_str(&self) -> &str {
        &self.0
    }
}

impl TryFrom<String> for ExperimentId {
    type Error = BadExperimentId;

    fn try_from(id: String) -> Result<Self, Self::Error> {
        ExperimentId::new(&id)
    }
}

impl From<ExperimentId> for String {
    fn from(id: ExperimentId) -> String {
        id.0.as_ref().to_owned()
    }
}

impl std::fmt::Display for ExperimentId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl PartialEq<str> for ExperimentId {
    fn eq(&self, other: &str) -> bool {
        &*self.0 == other
    }
}

impl schemars::JsonSchema for ExperimentId {
    fn schema_name() -> std::borrow::Cow<'static, str> {
        "ExperimentId".into()
    }

    fn json_schema(_: &mut schemars::SchemaGenerator) -> schemars::Schema {
        schemars::json_schema!({
            "type": "string",
            "pattern": "^[a-z][a-z0-9_-]{0,31}$"
        })
    }
}

/// An experiment as its folder declares it (`experiment.toml`): what the
/// user is told, what they define, what a run does and what counts as
/// success. Its charts and controllers are its design (`vl_core::design`);
/// this is what the Host, the Guests and the tools act on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Experiment {
    pub id: ExperimentId,
    /// What the user sees it called.
    pub title: String,
    /// What the user is told to do before a run.
    #[serde(default)]
    pub help: String,
    /// What the user defines before a run.
    #[serde(default)]
    pub define: Vec<DefineKind>,
    /// What a run does, composed from vl's components.
    pub run: RunPlan,
    #[serde(default)]
    pub success: Success,
}

/// Something a user defines before a run, of a kind vl knows how to show,
/// check, forecast and record.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum DefineKind {
    /// A point on the floor, clicked on the view.
    Goal {
        /// Whether a run may start without one.
        #[serde(default)]
        required: bool,
    },
    /// Points to visit in order, clicked on the view: at least `min`, at
    /// most `max`.
    Waypoints { min: usize, max: usize },
    /// A path the robot is to follow, planned by the lab or drawn.
    Path,
    /// Obstacles that exist only in software, drawn on the view.
    Obstacles,
    /// A number the user sets, from `min` to `max`: where the experiment
    /// limits it, a definition that leaves it unset gets `max`.
    Number {
        setting: Setting,
        min: f64,
        max: f64,
    },
    /// The user's own wheel controller, a WebAssembly module
    /// (`docs/controllers.md`), sent before the definition names it.
    Controller,
}

/// The numbers a definition sets that an experiment may bound.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Setting {
    /// The cap on wheel speed, mm/s.
    MaxSpeedMmS,
    /// How long a run may last, s.
    TimeLimitS,
}

impl Setting {
    fn of(self, definition: &mut Definition) -> &mut Option<f64> {
        match self {
            Setting::MaxSpeedMmS => &mut definition.max_speed_mm_s,
            Setting::TimeLimitS => &mut definition.time_limit_s,
        }
    }
}

impl std::fmt::Display for Setting {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Setting::MaxSpeedMmS => "the speed limit (mm/s)",
            Setting::TimeLimitS => "the time limit (s)",
        })
    }
}

/// vl's components a run is composed of, named in `experiment.toml` as
/// in messages.
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Serialize,
    Deserialize,
    strum::IntoStaticStr,
    schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
#[strum(serialize_all = "snake_case")]
pub enum RunComponent {
    /// Plan a path through the defined points on the C-space (the lab's
    /// net hears `path_planned`).
    Plan,
    /// Try the definition on the twin before the robot moves (the net
    /// hears `forecast_passed` or `forecast_failed`).
    Forecast,
    /// Follow the defined path under the safety layer and the leash.
    Follow,
    /// The operator drives by stick, under the safety layer and the leash.
    Teleoperate,
    /// Add the obstacles' potential field to the operator's commands (the
    /// net hears `field_built`).
    Assist,
    /// Feed the field's push back to the operator as a force.
    Force,
    /// Hold the robot still for the run (a measurement, a demonstration):
    /// no command drives it.
    Hold,
    /// The user's controller drives, stepped beside the control loop in
    /// its sandbox, under the safety layer and the leash.
    Controller,
}

impl RunComponent {
    pub const ALL: [RunComponent; 8] = [
        RunComponent::Plan,
        RunComponent::Forecast,
        RunComponent::Follow,
        RunComponent::Teleoperate,
        RunComponent::Assist,
        RunComponent::Force,
        RunComponent::Hold,
        RunComponent::Controller,
    ];

    /// The event the lab fires into the experiment's net when this
    /// component has done its part: the charts must have it, and only
    /// the experiments whose run has the component may.
    pub fn event(self) -> Option<&'static str> {
        match self {
            RunComponent::Plan => Some("path_planned"),
            RunComponent::Forecast => Some("forecast_passed"),
            RunComponent::Assist => Some("field_built"),
            RunComponent::Follow
            | RunComponent::Teleoperate
            | RunComponent::Force
            | RunComponent::Hold
            | RunComponent::Controller => None,
        }
    }
}

impl std::fmt::Display for RunComponent {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.into())
    }
}

/// What a run does: the components it is made of.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RunPlan {
    pub components: Vec<RunComponent>,
}

impl RunPlan {
    pub fn has(&self, component: RunComponent) -> bool {
        self.components.contains(&component)
    }

    /// Why these components do not make a run, if they do not.
    pub fn check(&self, define: &[DefineKind]) -> Result<(), ExperimentError> {
        use RunComponent as C;
        let drives = [C::Follow, C::Teleoperate, C::Hold, C::Controller]
            .into_iter()
            .filter(|&c| self.has(c))
            .count();
        if drives != 1 {
            return Err(ExperimentError::OneDrive);
        }
        for (needs, what) in [
            (C::Plan, C::Follow),
            (C::Assist, C::Teleoperate),
            (C::Force, C::Assist),
        ] {
            if self.has(needs) && !self.has(what) {
                return Err(ExperimentError::Needs { needs, what });
            }
        }
        let defines = |kind: fn(&DefineKind) -> bool| define.iter().any(kind);
        if self.has(C::Forecast) && !self.has(C::Follow) && !self.has(C::Controller) {
            return Err(ExperimentError::Needs {
                needs: C::Forecast,
                what: C::Follow,
            });
        }
        if self.has(C::Follow) && !defines(|d| matches!(d, DefineKind::Path)) {
            return Err(ExperimentError::NoPath);
        }
        if self.has(C::Controller) && !defines(|d| matches!(d, DefineKind::Controller)) {
            return Err(ExperimentError::NoController);
        }
        let points =
            |d: &DefineKind| matches!(d, DefineKind::Goal { .. } | DefineKind::Waypoints { .. });
        if self.has(C::Plan) && !define.iter().any(points) {
            return Err(ExperimentError::NoPoints);
        }
        Ok(())
    }
}

/// What is wrong with what an experiment declares, or with a definition
/// of it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ExperimentError {
    #[error("a run has exactly one of the components follow, teleoperate, hold and controller")]
    OneDrive,
    #[error(
        "the component controller needs a controller to define ([[define]] kind = \"controller\")"
    )]
    NoController,
    #[error("the component {needs} needs {what}")]
    Needs {
        needs: RunComponent,
        what: RunComponent,
    },
    #[error("the component follow needs a path to define ([[define]] kind = \"path\")")]
    NoPath,
    #[error(
        "the component plan needs a goal or waypoints to plan through ([[define]] kind = \"goal\" or \"waypoints\")"
    )]
    NoPoints,
    #[error(
        "[[define]] waypoints: from min to max, 1 ≤ min ≤ max ≤ {MAX_WAYPOINTS}, not {min} to {max}"
    )]
    WaypointBounds { min: usize, max: usize },
    #[error("[success] reach = \"{0}\" needs one to define ([[define]] kind = \"{0}\")")]
    Success(&'static str),
    #[error("this experiment visits {min} to {max} waypoints, and the definition has {n}")]
    WaypointCount { min: usize, max: usize, n: usize },
    #[error("this experiment takes no waypoints")]
    NoWaypoints,
    #[error("[[define]] number: {setting} from {min} to {max} is no range")]
    NumberBounds {
        setting: Setting,
        min: f64,
        max: f64,
    },
    #[error(
        "this experiment allows {setting} from {min} to {max}, and the definition asks {value}"
    )]
    NumberOutside {
        setting: Setting,
        min: f64,
        max: f64,
        value: f64,
    },
}

/// What counts as a run's success.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default, schemars::JsonSchema,
)]
#[serde(deny_unknown_fields)]
pub struct Success {
    /// What the robot must reach; the run ends with success there.
    #[serde(default)]
    pub reach: Reach,
}

/// Where a run ends with success.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default, schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum Reach {
    /// Nowhere: the run ends when the operator stops it or its time is up.
    #[default]
    Nothing,
    /// The defined goal, within its tolerance.
    Goal,
    /// Each defined waypoint, in order, within the goal's tolerance.
    Waypoints,
}

impl Experiment {
    /// Whether the lab follows the defined path by itself.
    pub fn follows(&self) -> bool {
        self.run.has(RunComponent::Follow)
    }

    /// Whether the user's own controller drives a run.
    pub fn runs_a_controller(&self) -> bool {
        self.run.has(RunComponent::Controller)
    }

    /// Whether the operator's commands drive a run of it: not one that
    /// holds the robot, nor one the user's controller drives.
    pub fn takes_commands(&self) -> bool {
        !self.holds() && !self.runs_a_controller()
    }

    /// Whether a run holds the robot still, taking no command.
    pub fn holds(&self) -> bool {
        self.run.has(RunComponent::Hold)
    }

    /// Whether the lab plans the path through the defined points.
    pub fn plans(&self) -> bool {
        self.run.has(RunComponent::Plan)
    }

    /// Whether the lab tries a definition on the twin before a run.
    pub fn forecasts(&self) -> bool {
        self.run.has(RunComponent::Forecast)
    }

    /// Whether the lab adds potential fields to the operator's commands
    /// and feeds the push back as a force.
    pub fn assists_the_operator(&self) -> bool {
        self.run.has(RunComponent::Assist)
    }

    /// Whether a run ends with success where its definition says
    /// ([`Definition::reached`]): at the goal, or its waypoints visited.
    pub fn ends_at_goal(&self) -> bool {
        self.success.reach != Reach::Nothing
    }

    /// Why what it declares makes no experiment, if it does not: its
    /// run's components, the waypoints' bounds, what success needs.
    pub fn check(&self) -> Result<(), ExperimentError> {
        self.run.check(&self.define)?;
        let waypoints = self.waypoint_bounds();
        if let Some((min, max)) = waypoints
            && !(1 <= min && min <= max && max <= MAX_WAYPOINTS)
        {
            return Err(ExperimentError::WaypointBounds { min, max });
        }
        for kind in &self.define {
            if let DefineKind::Number { setting, min, max } = *kind
                && !(min.is_finite() && max.is_finite() && 0.0 < min && min <= max)
            {
                return Err(ExperimentError::NumberBounds { setting, min, max });
            }
        }
        match self.success.reach {
            Reach::Waypoints if waypoints.is_none() => Err(ExperimentError::Success("waypoints")),
            Reach::Goal if !self.defines(DefineKind::Goal { required: false }) => {
                Err(ExperimentError::Success("goal"))
            }
            _ => Ok(()),
        }
    }

    /// How many waypoints a definition of it has, at least and at most;
    /// none when it defines none.
    pub fn waypoint_bounds(&self) -> Option<(usize, usize)> {
        self.define.iter().find_map(|d| match *d {
            DefineKind::Waypoints { min, max } => Some((min, max)),
            _ => None,
        })
    }

    /// `definition` within this experiment's numbers: each it bounds and
    /// the definition leaves unset at its most; or why not, one outside.
    pub fn limited(&self, mut definition: Definition) -> Result<Definition, ExperimentError> {
        for kind in &self.define {
            let DefineKind::Number { setting, min, max } = *kind else {
                continue;
            };
            let value = setting.of(&mut definition);
            match *value {
                None => *value = Some(max),
                Some(v) if (min..=max).contains(&v) => {}
                Some(value) => {
                    return Err(ExperimentError::NumberOutside {
                        setting,
                        min,
                        max,
                        value,
                    });
                }
            }
        }
        self.admits(&definition)?;
        Ok(definition)
    }

    /// Why `definition` is not one of this experiment, if it is not: its
    /// waypoints, when it declares them, are as many as it allows, and
    /// none when it does not.
    fn admits(&self, definition: &Definition) -> Result<(), ExperimentError> {
        let n = definition.waypoints.len();
        match self.waypoint_bounds() {
            Some((min, max)) if !(min..=max).contains(&n) => {
                Err(ExperimentError::WaypointCount { min, max, n })
            }
            None if n > 0 => Err(ExperimentError::NoWaypoints),
            _ => Ok(()),
        }
    }

    /// Whether the user defines something of `kind`'s kind (whatever its
    /// bounds: a goal required or not, any number of waypoints).
    pub fn defines(&self, kind: DefineKind) -> bool {
        self.define
            .iter()
            .any(|d| std::mem::discriminant(d) == std::mem::discriminant(&kind))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn experiments_travel_as_their_ids_and_unknown_ones_name_the_known() {
        let shipped = crate::Experiments::shipped();
        for e in shipped.experiments() {
            assert_eq!(shipped.get(e.id.as_str()).unwrap().experiment(), e);
            let id = serde_json::to_string(&e.id).unwrap();
            assert_eq!(id, format!("\"{}\"", e.id));
            assert_eq!(serde_json::from_str::<ExperimentId>(&id).unwrap(), e.id);
        }
        let e = shipped.get("juggling").unwrap_err();
        let known: Vec<String> = shipped.ids().iter().map(ToString::to_string).collect();
        assert_eq!(
            e.to_string(),
            format!(
                "unknown experiment 'juggling' (known: {})",
                known.join(", ")
            )
        );
        assert!(known.starts_with(&["navigation".to_owned(), "teleoperation".to_owned()]));
        let e = shipped.get("mobile").unwrap_err();
        assert!(
            e.to_string().contains("it is called 'navigation' now"),
            "{e}"
        );
        for bad in ["\"Juggling\"", "\"\"", "\"💥\"", "\"a/b\""] {
            assert!(serde_json::from_str::<ExperimentId>(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn numbers_are_kept_in_their_range_and_unset_ones_get_the_most() {
        let tour = Experiment {
            id: ExperimentId::new("visits").unwrap(),
            title: "Visits".to_owned(),
            help: String::new(),
            define: vec![
                DefineKind::Waypoints { min: 2, max: 8 },
                DefineKind::Path,
                DefineKind::Number {
                    setting: Setting::TimeLimitS,
                    min: 10.0,
                    max: 120.0,
                },
            ],
            run: RunPlan {
                components: vec![RunComponent::Plan, RunComponent::Follow],
            },
            success: Success {
                reach: Reach::Waypoints,
            },
        };
        assert_eq!(tour.check(), Ok(()));
        let two = vec![crate::Point::default(); 2];
        let definition = Definition {
            waypoints: two.clone(),
            ..Definition::default()
        };
        let limited = tour.limited(definition.clone()).unwrap();
        assert_eq!(limited.time_limit_s, Some(120.0));
        let quick = Definition {
            time_limit_s: Some(30.0),
            ..definition.clone()
        };
        assert_eq!(tour.limited(quick).unwrap().time_limit_s, Some(30.0));
        let long = Definition {
            time_limit_s: Some(600.0),
            ..definition
        };
        let e = tour.limited(long).unwrap_err().to_string();
        assert_eq!(
            e,
            "this experiment allows the time limit (s) from 10 to 120, and the definition asks 600"
        );
        let none = Definition::default();
        let e = tour.limited(none).unwrap_err().to_string();
        assert!(
            e.contains("visits 2 to 8 waypoints, and the definition has 0"),
            "{e}"
        );
    }

    #[test]
    fn a_run_is_one_drive_with_what_its_components_need() {
        use RunComponent as C;
        let plan = |components: &[RunComponent]| RunPlan {
            components: components.to_vec(),
        };
        let goal_and_path = [DefineKind::Goal { required: true }, DefineKind::Path];
        assert!(
            plan(&[C::Plan, C::Forecast, C::Follow])
                .check(&goal_and_path)
                .is_ok()
        );
        assert!(
            plan(&[C::Teleoperate, C::Assist, C::Force])
                .check(&[])
                .is_ok()
        );
        for (bad, why) in [
            (plan(&[]), "exactly one"),
            (plan(&[C::Follow, C::Teleoperate]), "exactly one"),
            (plan(&[C::Teleoperate, C::Force]), "force needs assist"),
            (plan(&[C::Teleoperate, C::Plan]), "plan needs follow"),
        ] {
            let e = bad.check(&goal_and_path).unwrap_err().to_string();
            assert!(e.contains(why), "{e}");
        }
        let e = plan(&[C::Follow]).check(&[]).unwrap_err().to_string();
        assert!(e.contains("needs a path to define"), "{e}");
    }
}
