//! Where a scene streams from: the one place its URL is spelled.

/// `url` with the access token `token` added as its `access_token` query
/// parameter (percent-encoded), or `url` itself without one.
pub fn with_token(url: &str, token: Option<&str>) -> String {
    let Some(token) = token else {
        return url.to_owned();
    };
    let encoded = farfield_protocol::percent::percent_encode(token);
    let sep = if url.contains('?') { '&' } else { '?' };
    format!("{url}{sep}access_token={encoded}")
}

/// The websocket URL of a scene's stream. `server` is `http://host:port`,
/// `https://host:port`, `ws://...`, `wss://...` or a bare `host:port`.
pub fn stream_url(server: &str, scene: &str) -> String {
    let base = server.trim_end_matches('/');
    let base = base
        .strip_prefix("http://")
        .map(|rest| format!("ws://{rest}"))
        .or_else(|| {
            base.strip_prefix("https://")
                .map(|rest| format!("wss://{rest}"))
        })
        .unwrap_or_else(|| {
            if base.contains("://") {
                base.to_owned()
            } else {
                format!("ws://{base}")
            }
        });
    format!("{base}/scenes/{scene}/stream")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls() {
        assert_eq!(
            with_token("ws://h/s", Some("a b/é")),
            "ws://h/s?access_token=a%20b%2F%C3%A9"
        );
        assert_eq!(
            stream_url("http://127.0.0.1:80/", "a"),
            "ws://127.0.0.1:80/scenes/a/stream"
        );
        assert_eq!(
            stream_url("127.0.0.1:80", "a"),
            "ws://127.0.0.1:80/scenes/a/stream"
        );
        assert_eq!(stream_url("ws://h:1", "b"), "ws://h:1/scenes/b/stream");
    }
}
