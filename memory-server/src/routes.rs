//! The HTTP surface: the browser's pages (`pages.rs`, `web_assets.rs`),
//! scene listing, one scene, health, metrics, and the websocket upgrade
//! that starts a session (`session.rs`).
//!
//! Unknown scenes and paths answer 404 with a JSON `{"error": ...}` body, so
//! scripts and the client can print the reason.

use std::net::SocketAddr;
use std::sync::Arc;

use axum::Router;
use axum::extract::ws::rejection::WebSocketUpgradeRejection;
use axum::extract::ws::{WebSocket, WebSocketUpgrade};
use axum::extract::{ConnectInfo, Path, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::{Extension, Json};
use farfield_protocol::codec::MAX_CONTROL_BYTES;
use serde_json::{Value, json};

use super::AppState;
use super::access::{self, Grant};
use super::catalog::ServedScene;
use super::limits::{WRITE_BUFFER_BYTES, WRITE_BUFFER_SLACK_BYTES};
use super::{pages, session, web_assets};

/// Largest websocket message a client may send: one control message plus
/// its kind byte, with room to spare. Anything larger is refused by the
/// websocket layer before it is buffered.
const MAX_CLIENT_MESSAGE: usize = 2 * MAX_CONTROL_BYTES;

pub(crate) fn router(state: Arc<AppState>) -> Router {
    Router::new()
        .route("/", get(pages::index))
        .route("/view/{name}", get(pages::viewer))
        .route("/web/{file}", get(web_assets::serve))
        .route("/healthz", get(healthz))
        .route("/metrics", get(metrics))
        .route("/scenes", get(list))
        .route("/sessions", get(sessions))
        .route("/scenes/{name}", get(one))
        .route("/scenes/{name}/stream", get(stream))
        .fallback(fallback)
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            access::check,
        ))
        .layer(axum::middleware::map_response(json_errors))
        .with_state(state)
}

/// Every error status leaves with a JSON `{"error": ...}` body, whoever
/// made it (a handler, a rejected extractor, the router's 405): scripts and
/// the client read one shape. The original text becomes the message.
async fn json_errors(response: Response) -> Response {
    let status = response.status();
    // JSON stays as it is, and so do the pages a browser shows a person.
    let keep = response
        .headers()
        .get(header::CONTENT_TYPE)
        .is_some_and(|v| {
            v.as_bytes().starts_with(b"application/json") || v.as_bytes().starts_with(b"text/html")
        });
    if !(status.is_client_error() || status.is_server_error()) || keep {
        return response;
    }
    let (parts, body) = response.into_parts();
    let text = axum::body::to_bytes(body, 4096)
        .await
        .map(|b| String::from_utf8_lossy(&b).trim().to_owned())
        .unwrap_or_default();
    let message = if text.is_empty() {
        status
            .canonical_reason()
            .unwrap_or("error")
            .to_ascii_lowercase()
    } else {
        text
    };
    let mut json = (status, Json(json!({ "error": message }))).into_response();
    // Headers that say more (Allow on a 405, WWW-Authenticate on a 401).
    for (name, value) in &parts.headers {
        if name != header::CONTENT_TYPE && name != header::CONTENT_LENGTH {
            json.headers_mut().insert(name, value.clone());
        }
    }
    json
}

fn not_found(message: String) -> Response {
    (StatusCode::NOT_FOUND, Json(json!({ "error": message }))).into_response()
}

fn unknown_scene(name: &str) -> Response {
    not_found(format!("no scene named {:?}", super::quote::prefix(name)))
}

async fn healthz() -> &'static str {
    "ok"
}

/// The server's counters, and the demo sessions' series of the scenes the
/// request's token covers (a session's name may say more than its scene's:
/// "secret-board-meeting").
async fn metrics(State(app): State<Arc<AppState>>, Extension(grant): Extension<Grant>) -> Response {
    let mut text = app.metrics.render();
    app.demo
        .render_metrics(&mut text, |scene| grant.allows(scene));
    ([(header::CONTENT_TYPE, "text/plain; version=0.0.4")], text).into_response()
}

/// The demo sessions of the scenes the request's token covers.
async fn sessions(
    State(app): State<Arc<AppState>>,
    Extension(grant): Extension<Grant>,
) -> Json<Value> {
    Json(
        serde_json::to_value(
            app.demo
                .list()
                .into_iter()
                .filter(|s| grant.allows(&s.scene))
                .collect::<Vec<_>>(),
        )
        .unwrap_or(Value::Null),
    )
}

async fn list(State(app): State<Arc<AppState>>, Extension(grant): Extension<Grant>) -> Json<Value> {
    Json(Value::Array(
        app.catalog
            .list()
            .iter()
            .filter(|s| grant.allows(&s.name))
            .map(|s| s.summary())
            .collect(),
    ))
}

/// The scene `name`, if it is served and the request's token covers it (a
/// scene it does not cover is not told apart from one that does not exist).
fn granted(app: &AppState, grant: &Grant, name: &str) -> Option<Arc<ServedScene>> {
    app.catalog.get(name).filter(|_| grant.allows(name))
}

async fn one(
    State(app): State<Arc<AppState>>,
    Extension(grant): Extension<Grant>,
    Path(name): Path<String>,
) -> Response {
    match granted(&app, &grant, &name) {
        Some(scene) => Json(scene.details()).into_response(),
        None => unknown_scene(&name),
    }
}

async fn stream(
    State(app): State<Arc<AppState>>,
    Extension(grant): Extension<Grant>,
    Path(name): Path<String>,
    ConnectInfo(peer): ConnectInfo<SocketAddr>,
    ws: Result<WebSocketUpgrade, WebSocketUpgradeRejection>,
) -> Response {
    let Some(scene) = granted(&app, &grant, &name) else {
        return unknown_scene(&name);
    };
    let ws = match ws {
        Ok(ws) => ws,
        Err(rejection) => return rejection.into_response(),
    };
    // The write buffer holds one frame (a header part or the largest page)
    // beyond its usual size, and room for pongs: a client that pings and
    // never reads costs this much, not more (tungstenite's default is
    // unbounded). Its memory stays at the most it ever held.
    let largest_frame = scene.largest_header_frame().max(scene.largest_page()) + 16;
    // A browser that offers the token's subprotocol must be answered with
    // one it offered, or it drops the connection.
    ws.protocols([farfield_protocol::auth::SUBPROTOCOL])
        .max_message_size(MAX_CLIENT_MESSAGE)
        .max_frame_size(MAX_CLIENT_MESSAGE)
        .write_buffer_size(WRITE_BUFFER_BYTES)
        .max_write_buffer_size(WRITE_BUFFER_BYTES + largest_frame + WRITE_BUFFER_SLACK_BYTES)
        .on_upgrade(move |socket: WebSocket| session::run(socket, scene, app, peer))
}

async fn fallback() -> Response {
    not_found("no such endpoint (try /, /scenes, /sessions, /healthz or /metrics)".into())
}
