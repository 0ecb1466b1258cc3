//! The pages a browser opens: `/`, the scenes as a list, and
//! `/view/{scene}`, the viewer (the `farfield-web` crate, whose built
//! assets `web_assets` serves under `/web/`).
//!
//! A token given as `?access_token=` stays in every link, so a shared link
//! with a token opens the list and the viewer alike. An unknown scene gets
//! a page that says so, with a link back to the list (a browser's
//! websocket would only see a failed connection).

use std::collections::HashMap;
use std::sync::Arc;

use axum::Extension;
use axum::extract::{Path, Query, State};
use axum::http::StatusCode;
use axum::response::{Html, IntoResponse, Response};
use farfield_protocol::percent::percent_encode;

use super::AppState;
use super::access::Grant;
use super::web_assets;

/// `&`, `<`, `>`, `"` and `'` as HTML entities: scene names are file names.
fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

const STYLE: &str = "body{margin:0;background:#111;color:#ddd;font:15px system-ui,sans-serif}\
main{max-width:56em;margin:2em auto;padding:0 1em}a{color:#8cf}\
table{border-collapse:collapse;width:100%}td,th{text-align:left;padding:.4em .8em;border-bottom:1px solid #333}\
td.n{text-align:right;font-variant-numeric:tabular-nums}";

fn page(title: &str, body: &str) -> String {
    format!(
        "<!doctype html><html lang=\"en\"><head><meta charset=\"utf-8\">\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\
         <title>{}</title><style>{STYLE}</style></head><body><main>{body}</main></body></html>",
        escape(title)
    )
}

/// The query to carry in links: the token, when the request had one.
fn token_query(query: &HashMap<String, String>) -> String {
    query
        .get("access_token")
        .map(|t| format!("?access_token={}", percent_encode(t)))
        .unwrap_or_default()
}

/// `GET /`: the scenes this request may see, each linked to its viewer.
pub(crate) async fn index(
    State(app): State<Arc<AppState>>,
    Extension(grant): Extension<Grant>,
    Query(query): Query<HashMap<String, String>>,
) -> Html<String> {
    let carry = token_query(&query);
    let mut rows = String::new();
    for scene in app.catalog.list().iter().filter(|s| grant.allows(&s.name)) {
        let h = scene.source.header();
        rows.push_str(&format!(
            "<tr><td><a href=\"/view/{}{carry}\">{}</a></td><td>{}</td>\
             <td class=\"n\">{}</td><td class=\"n\">{:.1} MB</td></tr>",
            percent_encode(&scene.name),
            escape(&scene.name),
            h.kind.name(),
            h.nodes,
            scene.source.stored_len() as f64 / 1e6,
        ));
    }
    let body = if rows.is_empty() {
        "<h1>farfield</h1><p>No scenes are served here yet: put <code>.ff</code> files \
         (made by <code>farfield-server build</code>) in the scenes folder; they appear \
         without a restart.</p>"
            .to_owned()
    } else {
        format!(
            "<h1>farfield</h1><p>Scenes streamed by this server. Open one to browse it: drag to \
             orbit, right-drag to pan, scroll to zoom, F to fly.</p><table><thead><tr>\
             <th>scene</th><th>kind</th><th class=\"n\">nodes</th><th class=\"n\">size</th>\
             </tr></thead><tbody>{rows}</tbody></table>"
        )
    };
    Html(page("farfield scenes", &body))
}

/// `GET /view/{name}`: the viewer of one scene, or a page that says why not.
pub(crate) async fn viewer(
    State(app): State<Arc<AppState>>,
    Extension(grant): Extension<Grant>,
    Path(name): Path<String>,
    Query(query): Query<HashMap<String, String>>,
) -> Response {
    let back = format!(
        "<a href=\"/{}\">the scenes this server has</a>",
        token_query(&query)
    );
    if app
        .catalog
        .get(&name)
        .filter(|_| grant.allows(&name))
        .is_none()
    {
        let body = format!(
            "<h1>No scene named “{}”</h1><p>This server has no such scene (or your token does \
             not cover it). See {back}.</p>",
            escape(&name)
        );
        return (
            StatusCode::NOT_FOUND,
            Html(page("no such scene · farfield", &body)),
        )
            .into_response();
    }
    if let Err(why) = web_assets::ready(app.web.as_ref()) {
        let body = format!(
            "<h1>The browser viewer is not built</h1><p>{}</p><p>A server built with the \
             wasm32 target carries it (<code>rustup target add wasm32-unknown-unknown</code>, \
             then build the server again); or build it with <code>web/build</code> in the \
             farfield checkout, or start the server with <code>--web DIR</code>. Back to \
             {back}.</p>",
            escape(&why)
        );
        return (
            StatusCode::SERVICE_UNAVAILABLE,
            Html(page("viewer not built · farfield", &body)),
        )
            .into_response();
    }
    Html(viewer_page(&name, &back)).into_response()
}

/// The viewer's page: a canvas the size of the window, the wasm started
/// on it, and a clear message when it cannot start.
fn viewer_page(name: &str, back: &str) -> String {
    format!(
        r#"<!doctype html><html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{title} · farfield</title>
<style>html,body{{margin:0;height:100%;overflow:hidden;background:#000;color:#ddd;font:15px system-ui,sans-serif}}
#farfield{{position:absolute;inset:0;width:100%;height:100%;outline:none;touch-action:none}}
#message{{position:absolute;inset:0;display:none;align-items:center;justify-content:center;text-align:center;padding:2em;background:#111}}
a{{color:#8cf}}</style></head>
<body><canvas id="farfield"></canvas><div id="message"></div>
<script type="module">
const show = (text) => {{
  const m = document.getElementById("message");
  m.innerHTML = `<p>${{text}}<br><br>Back to {back}.</p>`;
  m.style.display = "flex";
  document.body.dataset.failed = "true";
}};
const webgl2 = !!document.createElement("canvas").getContext("webgl2");
// navigator.gpu can be there with no adapter behind it: ask for one.
const webgpu = navigator.gpu ? !!(await navigator.gpu.requestAdapter().catch(() => null)) : false;
if (!webgpu && !webgl2) {{
  show("This browser can draw with neither WebGPU nor WebGL2, and the viewer needs one of them. " +
       "Try a current Chrome, Edge, Firefox or Safari, with hardware acceleration on.");
}} else {{
  try {{
    const viewer = await import("/web/farfield_web.js");
    await viewer.default();
    window.farfield = viewer;  // for scripts: farfield.capture_canvas()
    await viewer.start("farfield");
  }} catch (e) {{
    const text = String(e).replace(/[&<>]/g, (c) => ({{"&": "&amp;", "<": "&lt;", ">": "&gt;"}})[c]);
    show(`The viewer could not start: ${{text}}`);
  }}
}}
</script></body></html>"#,
        title = escape(name),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_escaped() {
        assert_eq!(
            escape("<a href='x'>&\"</a>"),
            "&lt;a href=&#39;x&#39;&gt;&amp;&quot;&lt;/a&gt;"
        );
    }
}
