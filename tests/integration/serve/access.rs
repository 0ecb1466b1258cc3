//! Tokens and origins on a real server: without a token, 401; a token sees
//! only its scenes (others are 404, as if absent); pages from another origin
//! are refused unless allowed, and allowed ones get CORS headers.

use std::collections::{BTreeSet, HashMap};

use farfield_net::stream_url;

use super::support::*;

/// `GET path` with extra header lines; the whole response.
async fn get(addr: std::net::SocketAddr, path: &str, headers: &str) -> String {
    let head = format!("GET {path} HTTP/1.1\r\nHost: {addr}\r\n{headers}Connection: close\r\n\r\n");
    raw_request(addr, &head).await
}

fn status(answer: &str) -> &str {
    answer.split(' ').nth(1).unwrap_or("")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_token_is_needed_and_sees_only_its_scenes() {
    let dir = scenes_dir("access-tokens");
    let mut tokens = HashMap::new();
    tokens.insert("every-scene".to_owned(), None);
    tokens.insert(
        "tree-only".to_owned(),
        Some(BTreeSet::from(["tree".to_owned()])),
    );
    let server = serve_with(&dir, |c| c.access.tokens = tokens).await;
    let addr = server.local_addr();

    let answer = get(addr, "/scenes", "").await;
    assert_eq!(status(&answer), "401", "{answer}");
    assert!(
        answer
            .to_ascii_lowercase()
            .contains("www-authenticate: bearer"),
        "{answer}"
    );
    assert!(answer.contains("\"error\""), "{answer}");
    let answer = get(addr, "/scenes", "Authorization: Bearer wrong\r\n").await;
    assert_eq!(status(&answer), "401", "{answer}");
    assert_eq!(
        status(&get(addr, "/healthz", "").await),
        "200",
        "health needs no token"
    );

    let answer = get(addr, "/scenes", "Authorization: Bearer tree-only\r\n").await;
    assert_eq!(status(&answer), "200", "{answer}");
    assert!(
        answer.contains("\"tree\"") && !answer.contains("\"island\""),
        "{answer}"
    );
    let answer = get(addr, "/scenes/island?access_token=tree-only", "").await;
    assert_eq!(status(&answer), "404", "{answer}");
    let answer = get(addr, "/scenes/island?access_token=every-scene", "").await;
    assert_eq!(status(&answer), "200", "{answer}");

    // Websockets: refused without a token, served with one.
    let url = stream_url(&addr.to_string(), "island");
    let refused = tokio_tungstenite::connect_async(url.clone()).await;
    let Err(tokio_tungstenite::tungstenite::Error::Http(response)) = refused else {
        panic!("connected without a token: {refused:?}");
    };
    assert_eq!(response.status(), 401);
    // A page address a person was given may carry it in its query.
    let url = format!("{url}?access_token=every-scene");
    let (ws, _) = tokio_tungstenite::connect_async(url)
        .await
        .expect("connect with the token");
    let mut c = Client::over(ws);
    c.send(&farfield_protocol::messages::ClientMessage::Hello {
        protocol_version: farfield_protocol::messages::PROTOCOL_VERSION,
        max_in_flight_bytes: MIN_WINDOW,
        allow_push: false,
    })
    .await;
    assert!(
        matches!(c.recv().await, In::Control(_)),
        "the server's hello"
    );
    server.shutdown().await.expect("shutdown");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pages_of_other_origins_are_refused_unless_allowed() {
    let dir = scenes_dir("access-origins");
    let server = serve_with(&dir, |c| {
        c.access.allowed_origins = vec!["https://viewer.example".into()];
    })
    .await;
    let addr = server.local_addr();
    let answer = get(addr, "/scenes", "Origin: https://evil.example\r\n").await;
    assert_eq!(status(&answer), "403", "{answer}");
    assert!(answer.contains("evil.example"), "{answer}");
    let answer = get(addr, "/scenes", "Origin: https://viewer.example\r\n").await;
    assert_eq!(status(&answer), "200", "{answer}");
    assert!(
        answer
            .to_ascii_lowercase()
            .contains("access-control-allow-origin: https://viewer.example"),
        "{answer}"
    );
    let same = format!("Origin: http://{addr}\r\n");
    assert_eq!(
        status(&get(addr, "/scenes", &same).await),
        "200",
        "same origin"
    );
    // A websocket from another origin is refused before the upgrade.
    let mut request =
        tokio_tungstenite::tungstenite::client::IntoClientRequest::into_client_request(stream_url(
            &addr.to_string(),
            "island",
        ))
        .expect("request");
    request
        .headers_mut()
        .insert("origin", "https://evil.example".parse().expect("header"));
    let refused = tokio_tungstenite::connect_async(request).await;
    let Err(tokio_tungstenite::tungstenite::Error::Http(response)) = refused else {
        panic!("a page of another origin connected: {refused:?}");
    };
    assert_eq!(response.status(), 403);
    server.shutdown().await.expect("shutdown");
}

/// DNS rebinding: a page on `evil.example` whose name resolves to the
/// server sends `Host` and `Origin` of its own name, which agree. Both the
/// list and the stream are refused (421) unless the name is allowed.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn requests_for_a_rebound_name_are_refused_with_421() {
    let dir = scenes_dir("access-rebinding");
    let server = serve(&dir).await;
    let addr = server.local_addr();
    let port = addr.port();
    let rebound = |path: &str, extra: &str| {
        format!(
            "GET {path} HTTP/1.1\r\nHost: evil.example:{port}\r\nOrigin: http://evil.example:{port}\r\n{extra}Connection: close\r\n\r\n"
        )
    };
    let answer = raw_request(addr, &rebound("/scenes", "")).await;
    assert_eq!(status(&answer), "421", "{answer}");
    assert!(answer.contains("--allowed-host"), "{answer}");
    assert!(
        !answer
            .to_ascii_lowercase()
            .contains("access-control-allow-origin"),
        "{answer}"
    );
    let upgrade = "Upgrade: websocket\r\nSec-WebSocket-Version: 13\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n";
    let answer = raw_request(
        addr,
        &rebound("/scenes/island/stream", upgrade)
            .replace("Connection: close", "Connection: Upgrade"),
    )
    .await;
    assert_eq!(status(&answer), "421", "{answer}");
    // Its own names are answered, the health check whatever it is called.
    let local = format!(
        "GET /scenes HTTP/1.1\r\nHost: localhost:{port}\r\nOrigin: http://localhost:{port}\r\nConnection: close\r\n\r\n"
    );
    assert_eq!(status(&raw_request(addr, &local).await), "200");
    let health = rebound("/healthz", "");
    assert_eq!(status(&raw_request(addr, &health).await), "200");
    server.shutdown().await.expect("shutdown");

    // A reverse proxy's name, allowed by the operator, is answered.
    let server = serve_with(&dir, |c| {
        c.access.allowed_hosts = vec!["Evil.Example".into()]
    })
    .await;
    let answer = raw_request(
        server.local_addr(),
        &rebound("/scenes", "").replace(&port.to_string(), &server.local_addr().port().to_string()),
    )
    .await;
    assert_eq!(status(&answer), "200", "{answer}");
    server.shutdown().await.expect("shutdown");
}

/// An origin is a scheme, a host and a port: a page of `https://H` is not
/// the server's own on `http://H`; and health is open to pages of any
/// origin, as the README says.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn origins_are_compared_scheme_and_all_and_health_is_open_to_any() {
    let dir = scenes_dir("access-origin-scheme");
    let server = serve(&dir).await;
    let addr = server.local_addr();
    let answer = get(addr, "/scenes", &format!("Origin: https://{addr}\r\n")).await;
    assert_eq!(status(&answer), "403", "{answer}");
    let answer = get(addr, "/scenes", &format!("Origin: http://{addr}\r\n")).await;
    assert_eq!(status(&answer), "200", "{answer}");
    let answer = get(addr, "/healthz", "Origin: https://evil.example\r\n").await;
    assert_eq!(status(&answer), "200", "{answer}");
    server.shutdown().await.expect("shutdown");
}

/// `/metrics` shows a demo session's series only to a token that covers
/// its scene: a session's name may say more than the scene's.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn metrics_show_only_the_sessions_of_a_tokens_scenes() {
    use farfield_protocol::messages::{ClientMessage, PROTOCOL_VERSION};
    use tokio_tungstenite::tungstenite::client::IntoClientRequest;
    let dir = scenes_dir("access-metrics");
    let mut tokens = HashMap::new();
    tokens.insert("operator".to_owned(), None);
    tokens.insert(
        "tree-only".to_owned(),
        Some(BTreeSet::from(["tree".to_owned()])),
    );
    let server = serve_with(&dir, |c| c.access.tokens = tokens).await;
    let addr = server.local_addr();
    let mut request = stream_url(&addr.to_string(), "island")
        .into_client_request()
        .expect("request");
    request
        .headers_mut()
        .insert("authorization", "Bearer operator".parse().expect("header"));
    let (ws, _) = tokio_tungstenite::connect_async(request)
        .await
        .expect("connect");
    let mut c = Client::over(ws);
    c.send(&ClientMessage::Hello {
        protocol_version: PROTOCOL_VERSION,
        max_in_flight_bytes: MIN_WINDOW,
        allow_push: false,
    })
    .await;
    c.send(&ClientMessage::Join {
        session: "secret-board-meeting".into(),
        present: true,
    })
    .await;
    eventually("the session is listed", || {
        server
            .sessions()
            .iter()
            .any(|s| s.name == "secret-board-meeting")
    })
    .await;
    let operator = get(addr, "/metrics", "Authorization: Bearer operator\r\n").await;
    assert!(
        operator.contains("session=\"secret-board-meeting\""),
        "{operator}"
    );
    let scoped = get(addr, "/metrics", "Authorization: Bearer tree-only\r\n").await;
    assert_eq!(status(&scoped), "200", "{scoped}");
    assert!(!scoped.contains("secret-board-meeting"), "{scoped}");
    assert!(scoped.contains("farfield_sessions 0"), "{scoped}");
    server.shutdown().await.expect("shutdown");
}
