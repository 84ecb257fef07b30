//! Which Foxglove protocol a client asks for, by its WebSocket subprotocol.

/// The protocol's two names: Foxglove's SDK and foxglove_bridge 3.x ask
/// for the first only, older clients and Lichtblick before 2026 for the
/// second.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Subprotocol {
    Sdk,
    Websocket,
}

impl Subprotocol {
    pub(crate) fn name(self) -> &'static str {
        match self {
            Subprotocol::Sdk => "foxglove.sdk.v1",
            Subprotocol::Websocket => "foxglove.websocket.v1",
        }
    }

    /// The one to answer a client offering `offered` (a
    /// `Sec-WebSocket-Protocol` header) with, the current name first.
    pub(crate) fn chosen(offered: &str) -> Option<Subprotocol> {
        let offers: Vec<&str> = offered.split(',').map(str::trim).collect();
        [Subprotocol::Sdk, Subprotocol::Websocket]
            .into_iter()
            .find(|s| offers.contains(&s.name()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_current_name_is_chosen_first_and_others_are_not_foxglove() {
        assert_eq!(
            Subprotocol::chosen("foxglove.websocket.v1, foxglove.sdk.v1"),
            Some(Subprotocol::Sdk)
        );
        assert_eq!(
            Subprotocol::chosen("foxglove.websocket.v1"),
            Some(Subprotocol::Websocket)
        );
        assert_eq!(Subprotocol::chosen("vl.v1"), None);
        assert_eq!(Subprotocol::chosen(""), None);
    }
}
