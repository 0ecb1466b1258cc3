//! The browser viewer's built files (`web/build` writes them to
//! `web/dist`), served under `/web/`.
//!
//! They are read from a folder at each request rather than embedded, so
//! the server builds without the wasm toolchain and a rebuilt viewer is
//! served without a restart. The folder is `--web DIR`, else the first
//! of `$FARFIELD_WEB_DIR`, `./web/dist` and `web/dist` of the checkout
//! the server binary was built in (`target/<profile>/../../web/dist`).

use std::path::{Path, PathBuf};

use axum::Json;
use axum::extract::{Path as UrlPath, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde_json::json;
use std::sync::Arc;

use super::AppState;

/// The files a built viewer has; the page loads the first, which loads the second.
pub const FILES: [&str; 2] = ["farfield_web.js", "farfield_web_bg.wasm"];

/// Where the viewer's files are when no folder is given.
pub fn find_dir() -> Option<PathBuf> {
    let mut candidates = Vec::new();
    if let Some(dir) = std::env::var_os("FARFIELD_WEB_DIR") {
        candidates.push(PathBuf::from(dir));
    }
    candidates.push(PathBuf::from("web/dist"));
    if let Ok(exe) = std::env::current_exe()
        && let Some(profile_dir) = exe.parent()
    {
        candidates.push(profile_dir.join("../../web/dist"));
    }
    candidates.into_iter().find(|d| d.join(FILES[0]).is_file())
}

/// Whether `dir` holds a built viewer; why not, if it does not. The reason
/// names the missing file, never the folder: it is shown to clients.
pub fn ready(dir: Option<&Path>) -> Result<(), String> {
    let Some(dir) = dir else {
        return Err("no folder with the viewer's files was found".into());
    };
    for file in FILES {
        if !dir.join(file).is_file() {
            tracing::warn!(folder = %dir.display(), "the viewer's folder has no {file}");
            return Err(format!("the viewer's folder has no {file}"));
        }
    }
    Ok(())
}

/// `GET /web/{file}`: one of [`FILES`], with its content type.
pub(crate) async fn serve(
    State(app): State<Arc<AppState>>,
    UrlPath(file): UrlPath<String>,
) -> Response {
    // Only the known names: never a path the request spells.
    let Some(name) = FILES.iter().find(|f| **f == file) else {
        return not_found(&file);
    };
    let Some(dir) = app.web_dir.as_deref() else {
        return not_found(&file);
    };
    let path = dir.join(name);
    match tokio::fs::read(&path).await {
        Ok(bytes) => {
            let kind = if name.ends_with(".wasm") {
                "application/wasm"
            } else {
                "text/javascript; charset=utf-8"
            };
            (
                [
                    (header::CONTENT_TYPE, kind),
                    (header::CACHE_CONTROL, "no-cache"),
                ],
                bytes,
            )
                .into_response()
        }
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
