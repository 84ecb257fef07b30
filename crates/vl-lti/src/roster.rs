//! The instructor's roster (NRPS): the course's members as the platform
//! lists them, each beside the runs they graded here.

use std::sync::Arc;

use serde_json::Value;

use super::grades::Graded;
use super::launch::{context_role, user_name};
use super::sessions::Launch;
use super::{Lti, LtiError};

/// A member of the course and their runs at the lab.
pub(crate) struct RosterRow {
    pub name: String,
    pub roles: String,
    pub runs: Vec<Graded>,
}

impl Lti {
    /// The course of `launch`: its members and their runs here.
    pub(crate) async fn roster_rows(
        &self,
        launch: &Arc<Launch>,
    ) -> Result<Vec<RosterRow>, LtiError> {
        let memberships = launch.memberships.as_deref().ok_or_else(|| {
            LtiError::Platform("the launch offers no roster (Names and Role Provisioning)".into())
        })?;
        let platform = self
            .platforms()?
            .find(&launch.issuer, Some(&launch.client_id))
            .cloned()
            .ok_or_else(|| LtiError::Platform("no longer registered".into()))?;
        let members = self.members(&platform, memberships).await?;
        Ok(members
            .iter()
            .filter_map(|member| {
                let id = member.get("user_id").and_then(Value::as_str)?;
                let name = member
                    .get("name")
                    .and_then(Value::as_str)
                    .unwrap_or(id)
                    .chars()
                    .take(128)
                    .collect();
                Some(RosterRow {
                    name,
                    roles: short_roles(member),
                    runs: self.grades.runs_of(&user_name(id, &platform)),
                })
            })
            .collect())
    }
}

/// The roles of a roster member, short.
fn short_roles(member: &Value) -> String {
    member
        .get("roles")
        .and_then(Value::as_array)
        .map(|roles| {
            roles
                .iter()
                .filter_map(Value::as_str)
                .filter_map(context_role)
                .collect::<Vec<_>>()
                .join(", ")
        })
        .unwrap_or_default()
}
