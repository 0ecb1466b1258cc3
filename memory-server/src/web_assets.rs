//! The browser viewer's files, served under `/web/`: the copy built into
//! this binary (`farfield-web-assets`), or a folder of them (`web/build`
//! writes `web/dist`).
//!
//! A folder given (`--web DIR`, else `$FARFIELD_WEB_DIR`) comes first, so
//! a viewer developer serves a fresh `web/build` without rebuilding the
//! server; then the embedded copy; then, for a server built without one
//! (`FARFIELD_WEB_EMBED=0`), `./web/dist` and `web/dist` of the checkout
//! the binary was built in (`target/<profile>/../../web/dist`). A folder
//! is read at each request, so a rebuilt viewer is served without a
//! restart.

use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

use axum::Json;
use axum::extract::{Path as UrlPath, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Response};
pub use farfield_web_assets::Viewer;
use serde_json::json;

use super::AppState;

/// The files a built viewer has; the page loads the first, which loads the second.
pub const FILES: [&str; 2] = ["farfield_web.js", "farfield_web_bg.wasm"];

/// Where the browser viewer's files come from.
#[derive(Debug, Clone)]
pub enum WebViewer {
    /// A folder of built files.
    Folder(PathBuf),
    /// The copy built into this binary.
    Embedded(Viewer),
}

impl WebViewer {
    /// What the server's log says it serves.
    pub fn describe(&self) -> String {
        match self {
            Self::Folder(dir) => format!("the browser viewer from {}", dir.display()),
            Self::Embedded(viewer) => format!(
                "the browser viewer built into this binary ({} KiB of wasm, {} KiB gzipped)",
                viewer.wasm.len() >> 10,
                viewer.wasm_gzip.len() >> 10
            ),
        }
    }
}

/// The viewer to serve when no folder is given: see the module's docs.
pub fn find() -> Option<WebViewer> {
    if let Some(dir) = std::env::var_os("FARFIELD_WEB_DIR") {
        return Some(WebViewer::Folder(PathBuf::from(dir)));
    }
    if let Some(viewer) = farfield_web_assets::VIEWER {
        return Some(WebViewer::Embedded(viewer));
    }
    let mut candidates = vec![PathBuf::from("web/dist")];
    if let Ok(exe) = std::env::current_exe()
        && let Some(profile_dir) = exe.parent()
    {
        candidates.push(profile_dir.join("../../web/dist"));
    }
    candidates
        .into_iter()
        .find(|d| d.join(FILES[0]).is_file())
        .map(WebViewer::Folder)
}

/// The viewer built into this binary, if it could be built.
pub fn embedded() -> Option<Viewer> {
    farfield_web_assets::VIEWER
}

/// Why this binary carries no viewer (empty when it does).
pub fn not_embedded() -> &'static str {
    farfield_web_assets::MISSING
}

/// Whether `viewer` can be served; why not, if it cannot. The reason
/// names the missing file, never the folder: it is shown to clients.
pub fn ready(viewer: Option<&WebViewer>) -> Result<(), String> {
    match viewer {
        None => Err("this server has no browser viewer".into()),
        Some(WebViewer::Embedded(_)) => Ok(()),
        Some(WebViewer::Folder(dir)) => {
            for file in FILES {
                if !dir.join(file).is_file() {
                    tracing::warn!(folder = %dir.display(), "the viewer's folder has no {file}");
                    return Err(format!("the viewer's folder has no {file}"));
                }
            }
            Ok(())
        }
    }
}

/// `GET /web/{file}`: one of [`FILES`], with its content type; the
/// embedded wasm gzipped where the browser takes it, and with an entity
/// tag, so a page opened again does not download it again.
pub(crate) async fn serve(
    State(app): State<Arc<AppState>>,
    UrlPath(file): UrlPath<String>,
    request: HeaderMap,
) -> Response {
    // Only the known names: never a path the request spells.
    let Some(&name) = FILES.iter().find(|f| **f == file) else {
        return not_found(&file);
    };
    let kind = if name.ends_with(".wasm") {
        "application/wasm"
    } else {
        "text/javascript; charset=utf-8"
    };
    match app.web.as_ref() {
        None => not_found(&file),
        Some(WebViewer::Embedded(viewer)) => from_binary(viewer, name, kind, &request),
        Some(WebViewer::Folder(dir)) => from_folder(dir, name, kind).await,
    }
}

fn from_binary(viewer: &Viewer, name: &str, kind: &'static str, request: &HeaderMap) -> Response {
    let tag = entity_tag(viewer);
    let matches = request
        .get(header::IF_NONE_MATCH)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.split(',').any(|t| t.trim() == tag));
    let headers = [
        (header::CACHE_CONTROL, "no-cache"),
        (header::ETAG, tag),
        (header::VARY, "accept-encoding"),
    ];
    if matches {
        return (StatusCode::NOT_MODIFIED, headers).into_response();
    }
    let gzip = request
        .get(header::ACCEPT_ENCODING)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.split(',').any(|e| e.trim().starts_with("gzip")));
    if name == FILES[0] {
        return (headers, [(header::CONTENT_TYPE, kind)], viewer.js).into_response();
    }
    if gzip {
        let encoding = [
            (header::CONTENT_TYPE, kind),
            (header::CONTENT_ENCODING, "gzip"),
        ];
        return (headers, encoding, viewer.wasm_gzip).into_response();
    }
    (headers, [(header::CONTENT_TYPE, kind)], viewer.wasm).into_response()
}

/// The embedded viewer's entity tag: its wasm's CRC-32 and length, one
/// for both files (they are built together).
fn entity_tag(viewer: &Viewer) -> &'static str {
    static TAG: OnceLock<String> = OnceLock::new();
    TAG.get_or_init(|| {
        let crc = crc32fast::hash(viewer.wasm);
        format!("\"{crc:08x}-{:x}\"", viewer.wasm.len())
    })
}

async fn from_folder(dir: &Path, name: &str, kind: &'static str) -> Response {
    let path = dir.join(name);
    match tokio::fs::read(&path).await {
        Ok(bytes) => (
            [
                (header::CONTENT_TYPE, kind),
                (header::CACHE_CONTROL, "no-cache"),
            ],
            bytes,
        )
            .into_response(),
        Err(e) => {
            // The operator reads where it looked; a client learns nothing
            // of the server's file system.
            tracing::warn!(path = %path.display(), "cannot serve the viewer's {name}: {e}");
            (
                StatusCode::NOT_FOUND,
                Json(json!({ "error": format!("this server has no {name} (its viewer is not built)") })),
            )
                .into_response()
        }
    }
}

fn not_found(file: &str) -> Response {
    (
        StatusCode::NOT_FOUND,
        Json(json!({ "error": format!("no viewer file named {:?}", crate::quote::prefix(file)) })),
    )
        .into_response()
}
