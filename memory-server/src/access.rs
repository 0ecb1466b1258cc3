//! Who may use the server: bearer tokens (each for every scene or for a
//! list), and which web pages may use it from a browser (CORS).
//!
//! A token comes in an `Authorization: Bearer TOKEN` header (native
//! clients), in a websocket subprotocol (a browser's `WebSocket` cannot set
//! headers: [`farfield_protocol::auth`]), or, for the address of a page a
//! person opens, an `access_token` query parameter (RFC 6750, section
//! 2.3). No client of ours puts it in a stream's URL, where proxies log
//! it. `/healthz` needs none. Without one:
//! 401 with `WWW-Authenticate: Bearer`; a scene the token does not cover is
//! answered as if it did not exist (404), and `/scenes` lists only what the
//! token covers.
//!
//! Browsers send an `Origin` with cross-origin requests and with every
//! websocket handshake. Same-origin (the page came from this server) is
//! always allowed; other origins only when listed, and then answered with
//! `Access-Control-Allow-Origin`. A request from a page of another origin
//! is refused (403) before it reaches a handler, which matters for
//! websockets: browsers apply no CORS to them, the server must.

use std::collections::{BTreeSet, HashMap};
use std::sync::Arc;

use axum::Json;
use axum::extract::{Request, State};
use axum::http::{HeaderValue, Method, StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use serde_json::json;

use super::AppState;

/// The access policy.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Access {
    /// Token -> the scenes it may see (`None`: every scene). Empty: no
    /// token is needed.
    pub tokens: HashMap<String, Option<BTreeSet<String>>>,
    /// Origins (`scheme://host[:port]`) whose pages may use the server
    /// besides its own; `*` allows any.
    pub allowed_origins: Vec<String>,
    /// Host names the server answers to besides its own addresses, its
    /// loopback names and its certificate's names (a reverse proxy's
    /// public name); `*` answers any (see [`crate::hosts`]).
    pub allowed_hosts: Vec<String>,
}

impl Access {
    /// Reads a tokens file: one token a line, optionally followed by the
    /// scenes it may see (separated by commas or spaces); blank lines and
    /// `#` comments are skipped. A token of a single character is refused:
    /// it is a typo, not a secret.
    pub fn parse_tokens(text: &str) -> Result<HashMap<String, Option<BTreeSet<String>>>, String> {
        let mut tokens = HashMap::new();
        for (i, line) in text.lines().enumerate() {
            let line = line.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let (token, rest) = line.split_once(char::is_whitespace).unwrap_or((line, ""));
            let scenes: BTreeSet<String> = rest
                .split(|c: char| c == ',' || c.is_whitespace())
                .filter(|s| !s.is_empty())
                .map(str::to_owned)
                .collect();
            let scenes = (!scenes.is_empty()).then_some(scenes);
            if token.chars().count() < 2 {
                return Err(format!(
                    "line {}: {token:?} is too short to be a token",
                    i + 1
                ));
            }
            tokens.insert(token.to_owned(), scenes);
        }
        Ok(tokens)
    }

    /// Whether a page of `origin` may use the server, reached as `host`
    /// over `scheme`: the same origin, scheme and all (`http://h` is not
    /// `https://h`), or one listed.
    fn origin_allowed(&self, origin: &str, host: Option<&str>, scheme: &str) -> bool {
        let same = host.is_some_and(|host| {
            origin.split_once("://").is_some_and(|(s, authority)| {
                s.eq_ignore_ascii_case(scheme) && authority.eq_ignore_ascii_case(host)
            })
        });
        same || self
            .allowed_origins
            .iter()
            .any(|o| o == "*" || o.trim_end_matches('/') == origin)
    }
}

/// What a request's token lets it see.
#[derive(Debug, Clone)]
pub(crate) enum Grant {
    All,
    Scenes(Arc<BTreeSet<String>>),
}

impl Grant {
    pub fn allows(&self, scene: &str) -> bool {
        match self {
            Grant::All => true,
            Grant::Scenes(scenes) => scenes.contains(scene),
        }
    }
}

fn refuse(status: StatusCode, message: &str) -> Response {
    (status, Json(json!({ "error": message }))).into_response()
}

/// The token a request carries, if any: in `Authorization: Bearer` (native
/// clients), in a websocket subprotocol (browsers, which cannot set the
/// header; see [`farfield_protocol::auth`]), or as `?access_token=` (a page
/// address a person typed or was given).
fn token_of(request: &Request) -> Option<String> {
    if let Some(value) = request.headers().get(header::AUTHORIZATION)
        && let Ok(value) = value.to_str()
        && let Some(token) = value.strip_prefix("Bearer ")
    {
        return Some(token.trim().to_owned());
    }
    if let Some(token) = request
        .headers()
        .get_all(header::SEC_WEBSOCKET_PROTOCOL)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .find_map(farfield_protocol::auth::token_from_subprotocols)
    {
        return Some(token);
    }
    request.uri().query()?.split('&').find_map(|pair| {
        let value = pair.strip_prefix("access_token=")?;
        Some(farfield_protocol::percent::percent_decode(value))
    })
}

/// The middleware in front of every route: origin, then token.
pub(crate) async fn check(
    State(app): State<Arc<AppState>>,
    mut request: Request,
    next: Next,
) -> Response {
    let access = &app.access;
    let path = request.uri().path();
    // Health is for probes and load balancers, whatever they call the
    // server and wherever they are: always open, and it tells nothing.
    if path == "/healthz" {
        return next.run(request).await;
    }
    let origin = request
        .headers()
        .get(header::ORIGIN)
        .and_then(|o| o.to_str().ok())
        .map(str::to_owned);
    let host = match request.headers().get(header::HOST).map(|h| h.to_str()) {
        None => None,
        Some(Ok(host)) => Some(host),
        Some(Err(_)) => Some(""),
    };
    if !app.hosts.allows(host) {
        let host = super::quote::prefix(host.unwrap_or_default());
        tracing::debug!("refused a request for host {host:?}");
        let mut response = refuse(
            StatusCode::MISDIRECTED_REQUEST,
            &format!(
                "this server does not answer to {host:?} (it answers to {}; add a name with --allowed-host NAME)",
                app.hosts.describe()
            ),
        );
        // Not this connection's server: it is not kept for another request.
        response
            .headers_mut()
            .insert(header::CONNECTION, HeaderValue::from_static("close"));
        return response;
    }
    if let Some(origin) = &origin
        && !access.origin_allowed(origin, host, app.scheme)
    {
        return refuse(
            StatusCode::FORBIDDEN,
            &format!(
                "pages from {} may not use this server (see --allow-origin)",
                super::quote::prefix(origin)
            ),
        );
    }
    if request.method() == Method::OPTIONS && origin.is_some() {
        // A preflight: the origin is allowed; say what it may send.
        let mut response = StatusCode::NO_CONTENT.into_response();
        let h = response.headers_mut();
        h.insert(
            header::ACCESS_CONTROL_ALLOW_METHODS,
            HeaderValue::from_static("GET, OPTIONS"),
        );
        h.insert(
            header::ACCESS_CONTROL_ALLOW_HEADERS,
            HeaderValue::from_static("authorization"),
        );
        h.insert(
            header::ACCESS_CONTROL_MAX_AGE,
            HeaderValue::from_static("600"),
        );
        cors_headers(&mut response, origin.as_deref());
        return response;
    }
    // The viewer's code is public (it holds no scene).
    let open = request.uri().path().starts_with("/web/");
    let grant = if access.tokens.is_empty() || open {
        Grant::All
    } else {
        match token_of(&request).and_then(|t| access.tokens.get(&t)) {
            Some(None) => Grant::All,
            Some(Some(scenes)) => Grant::Scenes(Arc::new(scenes.clone())),
            None => {
                let mut response = refuse(
                    StatusCode::UNAUTHORIZED,
                    "a valid token is needed (--token TOKEN, or Authorization: Bearer TOKEN)",
                );
                response.headers_mut().insert(
                    header::WWW_AUTHENTICATE,
                    HeaderValue::from_static("Bearer realm=\"farfield\""),
                );
                cors_headers(&mut response, origin.as_deref());
                return response;
            }
        }
    };
    request.extensions_mut().insert(grant);
    let mut response = next.run(request).await;
    cors_headers(&mut response, origin.as_deref());
    response
}

/// Tells the browser that `origin` (already allowed) may read the answer.
fn cors_headers(response: &mut Response, origin: Option<&str>) {
    let Some(value) = origin.and_then(|o| HeaderValue::from_str(o).ok()) else {
        return;
    };
    let h = response.headers_mut();
    h.insert(header::ACCESS_CONTROL_ALLOW_ORIGIN, value);
    h.insert(header::VARY, HeaderValue::from_static("origin"));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens_files_name_tokens_and_their_scenes() {
        let tokens = Access::parse_tokens("# comment\nalpha\n\nbeta island, tree # two\n").unwrap();
        assert_eq!(tokens["alpha"], None);
        let beta = tokens["beta"].as_ref().unwrap();
        assert!(beta.contains("island") && beta.contains("tree") && beta.len() == 2);
        let gamma = Access::parse_tokens("gamma a b").unwrap();
        assert_eq!(gamma["gamma"].as_ref().unwrap().len(), 2);
        let short = Access::parse_tokens("ok\nx island").unwrap_err();
        assert!(short.contains("line 2"), "{short}");
    }

    #[test]
    fn origins_are_same_or_listed() {
        let access = Access {
            allowed_origins: vec!["https://viewer.example".into()],
            ..Access::default()
        };
        let host = Some("127.0.0.1:7878");
        assert!(access.origin_allowed("http://127.0.0.1:7878", host, "http"));
        assert!(
            !access.origin_allowed("https://127.0.0.1:7878", host, "http"),
            "another scheme is another origin"
        );
        assert!(!access.origin_allowed("http://127.0.0.1:7878", host, "https"));
        assert!(access.origin_allowed("https://viewer.example", host, "http"));
        assert!(!access.origin_allowed("https://evil.example", host, "http"));
        assert!(!access.origin_allowed("http://127.0.0.1:7878", None, "http"));
    }
}
