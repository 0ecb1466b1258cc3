//! How a client proves itself to the server without putting its token in a
//! URL (where every proxy's log keeps it): a native client sends
//! `Authorization: Bearer TOKEN`; a browser, whose `WebSocket` cannot set
//! headers, offers the subprotocols [`SUBPROTOCOL`] and
//! `farfield.token.<percent-encoded token>` (the field Kubernetes' API
//! server reads its browsers' tokens from), and the server answers with
//! [`SUBPROTOCOL`] alone.

use crate::percent::{percent_decode, percent_encode};

/// The websocket subprotocol the server speaks, and answers with.
pub const SUBPROTOCOL: &str = "farfield";
/// What the subprotocol carrying a token starts with.
pub const TOKEN_SUBPROTOCOL_PREFIX: &str = "farfield.token.";

/// The subprotocol that carries `token`: percent-encoding leaves only
/// characters a subprotocol may hold (RFC 6455 and RFC 7230's `token`).
pub fn token_subprotocol(token: &str) -> String {
    format!("{TOKEN_SUBPROTOCOL_PREFIX}{}", percent_encode(token))
}

/// The token in a `Sec-WebSocket-Protocol` header's comma-separated list,
/// if one carries it.
pub fn token_from_subprotocols(header: &str) -> Option<String> {
    header
        .split(',')
        .find_map(|p| p.trim().strip_prefix(TOKEN_SUBPROTOCOL_PREFIX))
        .map(percent_decode)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_token_round_trips_through_the_subprotocol_list() {
        let token = "s3cret/é +x";
        let offered = format!("{SUBPROTOCOL}, {}", token_subprotocol(token));
        assert!(
            token_subprotocol(token)
                .bytes()
                .all(|b| b.is_ascii_alphanumeric() || b"-._~%".contains(&b)),
            "only token characters"
        );
        assert_eq!(token_from_subprotocols(&offered).as_deref(), Some(token));
        assert_eq!(token_from_subprotocols(SUBPROTOCOL), None);
    }
}
