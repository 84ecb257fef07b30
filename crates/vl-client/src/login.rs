//! Who a Guest says it is: an account's name and password, a lab's token,
//! or no one; and the hello that says it.

use vl_core::{GuestMessage, PROTOCOL_VERSION, Role, Secret};

/// A Guest's credentials. `Debug` shows who, never the secrets.
#[derive(Clone, Default, PartialEq, Eq)]
pub struct Login {
    pub user: Option<String>,
    pub password: Option<String>,
    /// A lab's operator token (for scripts, at labs without accounts).
    pub token: Option<String>,
}

impl std::fmt::Debug for Login {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Login")
            .field("user", &self.user)
            .field("password", &self.password.as_ref().map(|_| "…"))
            .field("token", &self.token.as_ref().map(|_| "…"))
            .finish()
    }
}

impl Login {
    /// Only a token (none: no one).
    pub fn token(token: Option<String>) -> Login {
        Login {
            token,
            ..Login::default()
        }
    }

    /// An account.
    pub fn user(user: impl Into<String>, password: impl Into<String>) -> Login {
        Login {
            user: Some(user.into()),
            password: Some(password.into()),
            token: None,
        }
    }

    /// The hello that asks for `role` as this Guest.
    pub fn hello(&self, role: Role) -> GuestMessage {
        GuestMessage::Hello {
            protocol: PROTOCOL_VERSION,
            role,
            token: self.token.clone(),
            resume: None,
            user: self.user.clone(),
            password: self.password.clone().map(Secret),
            session: None,
        }
    }
}
