//! Where a scene streams from: the one place its URL is spelled. (A token
//! never goes in it: see [`crate::Target`].)

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
