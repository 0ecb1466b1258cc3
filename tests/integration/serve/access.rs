//! Tokens and origins on a real server: without a token, 401; a token sees
//! only its scenes (others are 404, as if absent); pages from another origin
//! are refused unless allowed, and allowed ones get CORS headers.

use std::collections::{BTreeSet, HashMap};

use farfield_net::{stream_url, with_token};

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
    let url = with_token(&url, Some("every-scene"));
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
