//! The viewer's options from the page's query string:
//! `?panel=0&backend=webgl&kernel=round&color=elevation&clip=inside&clip_box=X0,Y0,Z0,X1,Y1,Z1&edl=1&edl_strength=S&edl_radius=PX&threshold=2&budget=N&plp_budget=P&plp_budget_ms=MS&epsilon_px=E&outlines=1&cache_mib=M&access_token=T`,
//! `flight=SECONDS` (the benchmark's scripted flight), and
//! `session=NAME&role=follow|present` (a demo session), and
//! `fallback=webgpu-lost` (set by the page itself: see [`WEBGPU_LOST`]).

use farfield_render::Kernel;
use farfield_viewer::AppOptions;
use web_sys::UrlSearchParams;

/// `fallback=` of a page started again on WebGL2 after WebGPU's device
/// was lost.
pub const WEBGPU_LOST: &str = "webgpu-lost";

/// Which of the browser's graphics APIs to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Backend {
    /// WebGPU where the browser has it, WebGL2 otherwise.
    Auto,
    WebGl,
}

/// What the query asks for.
#[derive(Debug)]
pub struct Query {
    pub options: AppOptions,
    pub backend: Backend,
    pub token: Option<String>,
}

/// Reads `search` (with or without `?`); a bad value is an error naming it.
pub fn parse(search: &str) -> Result<Query, String> {
    let params = UrlSearchParams::new_with_str(search).map_err(|_| "bad query".to_owned())?;
    let mut options = AppOptions::default();
    let number = |key: &str| -> Result<Option<f64>, String> {
        params
            .get(key)
            .map(|v| {
                v.parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite() && *x >= 0.0)
                    .ok_or_else(|| format!("{key}={v} is not a number of at least 0"))
            })
            .transpose()
    };
    if let Some(v) = params.get("panel") {
        options.show_panel = !matches!(v.as_str(), "0" | "false" | "no");
    }
    if let Some(t) = number("threshold")? {
        options.settings.threshold = t;
    }
    if let Some(b) = number("budget")? {
        options.settings.node_budget = b as u64;
    }
    if let Some(p) = number("plp_budget")? {
        options.settings.plp_budget_percent = p.clamp(0.0, 100.0);
    }
    if let Some(ms) = number("plp_budget_ms")? {
        options.settings.plp_budget_ms = ms;
    }
    if let Some(eps) = number("epsilon_px")? {
        options.settings.epsilon_px = eps;
    }
    if let Some(v) = params.get("outlines") {
        options.settings.outline_caches = !matches!(v.as_str(), "0" | "false" | "no");
    }
    options.flight_seconds = number("flight")?;
    if let Some(m) = number("cache_mib")? {
        options.settings.cache_mib = (m as u64).max(1);
    }
    let strength = number("edl_strength")?;
    let radius = number("edl_radius")?;
    let edl_asked = match params.get("edl").as_deref() {
        None => strength.is_some() || radius.is_some(),
        Some("1" | "true" | "yes" | "on") => true,
        Some("0" | "false" | "no" | "off") => false,
        Some(other) => return Err(format!("edl={other} is not 1 or 0")),
    };
    let default = farfield_render::Edl::default();
    options.settings.edl = edl_asked.then(|| farfield_render::Edl {
        strength: strength.map_or(default.strength, |v| v as f32),
        radius_px: radius.map_or(default.radius_px, |v| v as f32),
    });
    if let Some(keep) = params.get("clip") {
        let keep = match keep.as_str() {
            "inside" => Some(farfield_render::Keep::Inside),
            "outside" => Some(farfield_render::Keep::Outside),
            "off" => None,
            other => return Err(format!("clip={other} is not inside, outside or off")),
        };
        let corners = match params.get("clip_box") {
            None => [0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
            Some(text) => farfield_render::clip::parse_box(&text)?,
        };
        options.settings.clip = keep.map(|keep| farfield_render::Clip::from_corners(corners, keep));
    }
    if let Some(name) = params.get("color") {
        options.settings.color_by = farfield_render::ColorBy::from_name(&name)
            .ok_or_else(|| format!("color={name} is not rgb or elevation"))?;
    }
    options.settings.kernel = match params.get("kernel") {
        None => Kernel::Square,
        Some(name) => Kernel::from_name(&name)
            .ok_or_else(|| format!("kernel={name} is not square, round or paraboloid"))?,
    };
    if let Some(session) = params.get("session") {
        let present = match params.get("role").as_deref() {
            None | Some("follow") => false,
            Some("present") => true,
            Some(other) => return Err(format!("role={other} is not follow or present")),
        };
        options.demo = Some(farfield_client::render_job::DemoRole { session, present });
    }
    if params.get("fallback").as_deref() == Some(WEBGPU_LOST) {
        options.notice = Some("WebGPU's device was lost: drawing with WebGL2 instead".to_owned());
    }
    let backend = match params.get("backend").as_deref() {
        None | Some("auto") | Some("webgpu") => Backend::Auto,
        Some("webgl") | Some("webgl2") => Backend::WebGl,
        Some(other) => return Err(format!("backend={other} is not webgpu or webgl")),
    };
    Ok(Query {
        options,
        backend,
        token: params.get("access_token"),
    })
}
