//! The Guest's settings (thesis F.6, its Settings/Tasks Database): what a
//! user tunes for their runs, kept between sessions as TOML in their
//! configuration directory (`$XDG_CONFIG_HOME/vl/settings.toml`, else
//! `~/.config/vl/settings.toml`).

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use vl_core::LOOKAHEAD_MM;

/// What a user tunes. Every figure is kept within its range on loading,
/// whatever the file says.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Settings {
    /// How far ahead on the path the Host's follower aims, mm.
    pub lookahead_mm: f64,
    /// A cap on the robot's wheel speeds in runs, mm/s; none: the robot's own.
    pub max_speed_mm_s: Option<f64>,
    /// Room planning keeps between the robot's body and mapped obstacles
    /// where the passages allow, mm.
    pub margin_mm: f64,
}

/// The ranges the settings panel offers.
pub const MAX_SPEED_MM_S: std::ops::RangeInclusive<f64> = 20.0..=1000.0;
pub const MARGIN_MM: std::ops::RangeInclusive<f64> = 0.0..=60.0;

impl Default for Settings {
    fn default() -> Self {
        Settings {
            lookahead_mm: 30.0,
            max_speed_mm_s: None,
            margin_mm: 25.0,
        }
    }
}

/// Why the settings could not be kept.
#[derive(Debug, thiserror::Error)]
pub enum SettingsError {
    #[error("cannot write the settings to {0}: {1}")]
    Write(PathBuf, std::io::Error),
    #[error("cannot write the settings as TOML: {0}")]
    Encode(#[from] toml::ser::Error),
}

/// vl's folder in this user's configuration directory (settings, tasks).
pub(crate) fn config_dir() -> Option<PathBuf> {
    let config = std::env::var_os("XDG_CONFIG_HOME")
        .map(PathBuf::from)
        .filter(|p| p.is_absolute())
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".config")))
        .or_else(|| std::env::var_os("APPDATA").map(PathBuf::from))?;
    Some(config.join("vl"))
}

impl Settings {
    /// Where they are kept for this user, if there is a home to keep them in.
    pub fn default_path() -> Option<PathBuf> {
        Some(config_dir()?.join("settings.toml"))
    }

    /// The settings in `path`; the defaults where it is missing, and (said
    /// in the log) where it does not read as settings.
    pub fn load(path: &Path) -> Settings {
        match std::fs::read_to_string(path) {
            Ok(text) => match toml::from_str::<Settings>(&text) {
                Ok(settings) => settings.bounded(),
                Err(e) => {
                    tracing::warn!(
                        "{} is not vl's settings ({e}); using the defaults",
                        path.display()
                    );
                    Settings::default()
                }
            },
            Err(_) => Settings::default(),
        }
    }

    pub fn save(&self, path: &Path) -> Result<(), SettingsError> {
        let text = toml::to_string(self)?;
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).map_err(|e| SettingsError::Write(path.to_owned(), e))?;
        }
        std::fs::write(path, text).map_err(|e| SettingsError::Write(path.to_owned(), e))
    }

    /// Each figure within its range; a number that is not one gets the default.
    pub fn bounded(self) -> Settings {
        let default = Settings::default();
        let within = |v: f64, range: &std::ops::RangeInclusive<f64>, fallback: f64| {
            if v.is_finite() {
                v.clamp(*range.start(), *range.end())
            } else {
                fallback
            }
        };
        Settings {
            lookahead_mm: within(self.lookahead_mm, &LOOKAHEAD_MM, default.lookahead_mm),
            max_speed_mm_s: self
                .max_speed_mm_s
                .filter(|v| v.is_finite())
                .map(|v| v.clamp(*MAX_SPEED_MM_S.start(), *MAX_SPEED_MM_S.end())),
            margin_mm: within(self.margin_mm, &MARGIN_MM, default.margin_mm),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_survive_a_round_trip_and_nonsense_is_bounded() {
        let dir = std::env::temp_dir().join(format!("vl-settings-{}", std::process::id()));
        let path = dir.join("vl").join("settings.toml");
        assert_eq!(
            Settings::load(&path),
            Settings::default(),
            "no file: the defaults"
        );
        let mine = Settings {
            lookahead_mm: 45.0,
            max_speed_mm_s: Some(150.0),
            margin_mm: 10.0,
        };
        mine.save(&path).unwrap();
        assert_eq!(Settings::load(&path), mine);
        std::fs::write(
            &path,
            "lookahead_mm = 1e9\nmargin_mm = -3.0\nmax_speed_mm_s = 5.0\n",
        )
        .unwrap();
        let bounded = Settings::load(&path);
        assert_eq!(bounded.lookahead_mm, *LOOKAHEAD_MM.end());
        assert_eq!(bounded.margin_mm, 0.0);
        assert_eq!(bounded.max_speed_mm_s, Some(*MAX_SPEED_MM_S.start()));
        std::fs::write(&path, "lookahead_mm = \"far\"\n").unwrap();
        assert_eq!(
            Settings::load(&path),
            Settings::default(),
            "not settings: the defaults"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
