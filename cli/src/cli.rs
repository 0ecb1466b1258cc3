//! The `farfield` command line's arguments, and the dispatch to
//! [`crate::commands`]. `main.rs` only parses, runs and exits.

use std::path::PathBuf;

use clap::{Parser, Subcommand, ValueEnum};
use farfield_client::camera_spec::{CameraSpec, parse_camera, parse_orbit, parse_size};
use farfield_client::render_job::Source;

use crate::commands;

/// Browse farfield scenes, streamed from a memory server or from a file.
#[derive(Debug, Parser)]
#[command(name = "farfield", version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Render one view to a PNG, streaming pages from a server or reading a file.
    Render(Box<RenderArgs>),
    /// Open the viewer in a window: orbit, pan, zoom and fly while pages stream.
    View(Box<ViewArgs>),
    /// Measure the memory server on loopback: time to first image, overfetch,
    /// throughput with 1 and N clients next to plain TCP, memory while streaming.
    BenchStream {
        /// A paged file to serve (the server runs in this process).
        scene: PathBuf,
        /// Client counts to measure, e.g. 1,16.
        #[arg(long, value_delimiter = ',', default_value = "1,16")]
        clients: Vec<usize>,
        /// Seconds of streaming per client count.
        #[arg(long, default_value_t = 5.0)]
        seconds: f64,
        /// Server page cache, MiB (smaller than the scene shows memory stays flat).
        #[arg(long, default_value_t = 16)]
        cache_mib: u64,
        /// Repeats of the time-to-first-image measurement.
        #[arg(long, default_value_t = 9)]
        repeats: usize,
        #[arg(long)]
        json: bool,
    },
    /// The color-cube paper's Table 2: full geometry against the cube
    /// hierarchy at several distances, with speedups and image error.
    BenchCubes(Box<BenchCubesArgs>),
    /// PLP's Table 1 and Figures 8 and 9: visible coverage, wrong pixels
    /// and frame time at several budgets along a camera path, next to the
    /// paper's numbers.
    BenchPlp(Box<BenchPlpArgs>),
    /// Error against run time: sweep a mode's parameter over cameras, against a reference.
    Bench(Box<BenchArgs>),
    /// Many headless clients against one memory server: request latency
    /// quantiles, throughput, errors and reconnects, time to first image
    /// and to refined, and the server's metrics over the run.
    Loadtest(Box<LoadtestArgs>),
    /// An emulated wide-area network (Linux, root): namespaces NAME-server
    /// and NAME-client joined by a link with a round trip, a rate and
    /// random loss, until interrupted (SIGINT, SIGTERM). Run the
    /// server in one with `ip netns exec NAME-server ...`, clients in the
    /// other.
    Wan(WanArgs),
    /// One HTML page (plots, tables, machine, the papers' figures) from
    /// bench and load-test folders.
    Report {
        /// Folders written by `farfield bench --out` or `farfield loadtest --out`.
        #[arg(required = true)]
        dirs: Vec<PathBuf>,
        #[arg(long)]
        out: PathBuf,
    },
    /// Build the default scene, serve it in-process with the browser
    /// viewer, fly a client through it and write what it measured; then
    /// keep serving (and open the window viewer where there is a display)
    /// until the window closes or Ctrl-C.
    Demo {
        /// Folder for the scene file, frames, CSV and summary.
        #[arg(long, default_value = "farfield-demo")]
        out: PathBuf,
        /// Address to serve on (a port already taken: another, printed).
        #[arg(long, default_value = "127.0.0.1:7878")]
        listen: std::net::SocketAddr,
        /// Stop once the files are written (for scripts).
        #[arg(long)]
        exit: bool,
        /// Do not open the window viewer (the browser's is still served).
        #[arg(long)]
        no_window: bool,
    },
    /// Compare two PNGs: RMSE, PSNR and wrong-pixel fraction (exit 2 if sizes differ).
    Compare {
        /// The reference image.
        a: PathBuf,
        /// The image to measure against it.
        b: PathBuf,
        /// A pixel is wrong when any RGB channel differs by more than this.
        #[arg(long, default_value_t = 8)]
        tolerance: u8,
        /// Print JSON; an infinite PSNR (identical images) is the string "inf".
        #[arg(long)]
        json: bool,
    },
    /// Write a generated scene's camera path (gen:city, gen:cars) as JSON keyframes.
    Path {
        /// The scene, gen:NAME.
        input: String,
        /// Generator parameters, `key=value`, as for the scene.
        #[arg(long = "param", value_name = "KEY=VALUE")]
        params: Vec<String>,
        /// The JSON file to write.
        #[arg(long)]
        out: PathBuf,
    },
    /// Run the reference traversal on a paged file and report the cut.
    Traverse {
        #[arg(long)]
        file: PathBuf,
        #[arg(long, value_parser = parse_orbit, default_value = "azimuth=30,elevation=25,distance=2.5")]
        orbit: CameraSpec,
        #[arg(long, value_parser = parse_size, default_value = "1024x768")]
        size: (u32, u32),
        #[arg(long, default_value_t = 1.0)]
        threshold: f64,
        #[arg(long)]
        json: bool,
    },
}

/// Where a scene comes from: a memory server, or a file.
#[derive(Debug, clap::Args)]
pub struct SourceArgs {
    /// Memory server, e.g. http://127.0.0.1:7878 (pages then stream).
    #[arg(long, requires = "scene", conflicts_with = "file")]
    pub server: Option<String>,
    /// Scene name on the server.
    #[arg(long)]
    pub scene: Option<String>,
    /// Read a paged file directly (everything resident, no server).
    #[arg(long, required_unless_present = "server")]
    pub file: Option<PathBuf>,
}

impl SourceArgs {
    pub fn into_source(self) -> anyhow::Result<Source> {
        Ok(match (self.server, self.scene, self.file) {
            (Some(url), Some(scene), None) => Source::Server { url, scene },
            (None, _, Some(path)) => Source::File(path),
            _ => anyhow::bail!("give --server URL --scene NAME, or --file FILE"),
        })
    }
}

/// Where to look from: an eye and a target, or an orbit of the scene.
#[derive(Debug, clap::Args)]
pub struct CameraArgs {
    /// eye=x,y,z,target=x,y,z[,fov=DEG] (world units).
    #[arg(long, value_parser = parse_camera, conflicts_with = "orbit")]
    pub camera: Option<CameraSpec>,
    /// azimuth=DEG,elevation=DEG,distance=R (R in scene radii from the centre).
    #[arg(long, value_parser = parse_orbit)]
    pub orbit: Option<CameraSpec>,
}

impl CameraArgs {
    /// The camera given, if any.
    pub fn spec(&self) -> Option<CameraSpec> {
        self.camera.or(self.orbit)
    }
}

/// How a client proves itself to a server, and which server it trusts.
#[derive(Debug, clap::Args)]
pub struct AccessArgs {
    /// The server's access token (see `farfield-server serve --token`).
    #[arg(long, value_name = "TOKEN")]
    pub token: Option<String>,
    /// Trust this certificate authority (PEM) for an https:// server, in
    /// place of the public roots: a private or self-signed server.
    #[arg(long, value_name = "PEM")]
    pub ca_cert: Option<std::path::PathBuf>,
}

#[derive(Debug, clap::Args)]
pub struct ViewArgs {
    #[command(flatten)]
    pub source: SourceArgs,
    #[command(flatten)]
    pub camera: CameraArgs,
    /// The window's inner size.
    #[arg(long, value_parser = parse_size, default_value = "1280x800")]
    pub size: (u32, u32),
    /// The threshold a resting view refines to (spheres: pixels; cubes: eps).
    #[arg(long, default_value_t = 1.0)]
    pub threshold: f64,
    #[command(flatten)]
    pub splats: SplatArgs,
    /// Most nodes a frame draws (0: no budget).
    #[arg(long, default_value_t = 0)]
    pub budget: u64,
    /// PLP files: the share of the triangles a frame may draw, percent.
    #[arg(long, default_value_t = 100.0)]
    pub plp_budget: f64,
    /// PLP files: a frame time in milliseconds to hold instead (the
    /// triangle budget follows the measured draw rate; 0: off).
    #[arg(long, default_value_t = 0.0)]
    pub plp_budget_ms: f64,
    /// BSP files (image caching): the error a cached image may show, in
    /// pixels; 0 never caches.
    #[arg(long, default_value_t = 1.0, value_parser = parse_epsilon_px)]
    pub epsilon_px: f64,
    /// BSP files: outline each cached image.
    #[arg(long)]
    pub outlines: bool,
    /// Resident pages kept, MiB.
    #[arg(long, default_value_t = 512)]
    pub cache_mib: u64,
    /// Start with the panel hidden (Tab shows it).
    #[arg(long)]
    pub no_panel: bool,
    #[command(flatten)]
    pub access: AccessArgs,
    /// Save the window here whenever the resting view becomes refined, and
    /// print the camera (for scripts and tests).
    #[arg(long, value_name = "PNG")]
    pub screenshot_when_refined: Option<PathBuf>,
    /// Fly the benchmark's path (orbit and zoom) this many seconds, print
    /// the frame times as `flight <JSON>`, and close.
    #[arg(long, value_name = "SECONDS")]
    pub flight: Option<f64>,
    /// Join this demo session at start (see --present, --follow; the
    /// panel can also make, join, leave and hand over sessions).
    #[arg(long, value_name = "NAME", requires = "view_role")]
    pub session: Option<String>,
    /// Present: followers see this window's camera.
    #[arg(long, group = "view_role", requires = "session")]
    pub present: bool,
    /// Follow the presenter (moving the camera looks around; "follow
    /// again" in the panel returns).
    #[arg(long, group = "view_role", requires = "session")]
    pub follow: bool,
}

#[derive(Debug, clap::Args)]
pub struct BenchArgs {
    #[command(flatten)]
    pub source: SourceArgs,
    /// Cameras: the keyframes of this path (JSON); default an orbit at 1.75, 3.5 and 7 radii.
    #[arg(long)]
    pub path: Option<PathBuf>,
    /// A traversal kind (spheres, cubes, plp, centroid: PLP's nearest-first baseline) or geometry.
    #[arg(long)]
    pub mode: String,
    /// PARAM=v1,v2,...: threshold or kernel (spheres), eps or coverage (cubes), budget (plp, centroid: 5%, a count or all), full=all (geometry).
    #[arg(long)]
    pub sweep: String,
    /// A setting held fixed while sweeping, e.g. kernel=square (repeatable).
    #[arg(long = "set", value_name = "PARAM=VALUE")]
    pub set: Vec<String>,
    /// The scene's input (files or gen: scenes): the geometry mode's triangles, and the reference.
    #[arg(long = "input")]
    pub inputs: Vec<String>,
    #[arg(long = "param", value_name = "KEY=VALUE")]
    pub params: Vec<String>,
    #[arg(long, value_parser = parse_size, default_value = "320x240")]
    pub size: (u32, u32),
    #[arg(long, default_value_t = 3)]
    pub repeats: u32,
    /// Folder for bench.csv, progress.csv, meta.json and the plots.
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long, default_value_t = 120.0)]
    pub timeout_s: f64,
}

#[derive(Debug, clap::Args)]
pub struct BenchCubesArgs {
    /// A cube hierarchy (`farfield-server build --kind cubes`).
    #[arg(long)]
    pub file: PathBuf,
    /// The inputs it was built from: the full-geometry reference.
    #[arg(long = "input", required = true)]
    pub inputs: Vec<String>,
    /// Generator parameters of the inputs, `key=value`.
    #[arg(long = "param", value_name = "KEY=VALUE")]
    pub params: Vec<String>,
    /// Eye distances from the scene centre, in scene radii.
    #[arg(long, value_delimiter = ',', default_value = "1.75,3.5,7,14")]
    pub distances: Vec<f64>,
    /// Degrees off the octree's x axis (the paper: 30 for the tree, 25 for the molecule).
    #[arg(long, default_value_t = 30.0)]
    pub azimuth: f64,
    #[arg(long, default_value_t = 0.0)]
    pub elevation: f64,
    /// The paper's images were 124x124.
    #[arg(long, value_parser = parse_size, default_value = "124x124")]
    pub size: (u32, u32),
    #[arg(long, default_value_t = 1.0)]
    pub eps: f64,
    #[arg(long, default_value = "alpha")]
    pub coverage: farfield_render::Coverage,
    #[arg(long, default_value_t = 5)]
    pub repeats: usize,
    /// Write each distance's geometry and hierarchy images here.
    #[arg(long)]
    pub images: Option<PathBuf>,
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, clap::Args)]
pub struct LoadtestArgs {
    /// The memory server (http://host:port); every connection goes here.
    #[arg(long)]
    pub server: String,
    /// The scene's name on the server.
    #[arg(long)]
    pub scene: String,
    /// Clients to run (at most 4096).
    #[arg(long)]
    pub clients: usize,
    /// Seconds to run (at most 3600).
    #[arg(long)]
    pub duration: f64,
    /// Seconds over which the clients start, evenly.
    #[arg(long, default_value_t = 0.0)]
    pub ramp: f64,
    /// A camera path (JSON keyframes, see `farfield path`); each client
    /// flies it back and forth from its own phase. The demo's flight if not given.
    #[arg(long)]
    pub path: Option<PathBuf>,
    /// Folder for seconds.csv, clients.csv, loadtest.json, plots, index.html.
    #[arg(long)]
    pub out: PathBuf,
    /// Each client's view, WIDTHxHEIGHT.
    #[arg(long, default_value = "800x600", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Each client's threshold in pixels.
    #[arg(long, default_value_t = 1.0)]
    pub threshold: f64,
    /// Traversals a second per client.
    #[arg(long, default_value_t = 10.0)]
    pub fps: f64,
    /// Each client's resident pages, MiB.
    #[arg(long, default_value_t = 64)]
    pub client_cache_mib: usize,
    /// The server's access token.
    #[arg(long, value_name = "TOKEN")]
    pub token: Option<String>,
    /// Run the clients as a demo session of this name: client 0 presents
    /// (flies the path), the others follow; their lag is measured.
    #[arg(long, value_name = "NAME")]
    pub session: Option<String>,
    /// Let the server push pages the clients have not asked for yet,
    /// when their queues are empty.
    #[arg(long)]
    pub push: bool,
    /// --server is a static file server (nginx, say) holding the scene as
    /// `farfield-server export` writes it: the clients GET its pages, on
    /// 4 keep-alive connections each. The comparison with a plain file server.
    #[arg(long = "static")]
    pub static_files: bool,
    /// Pages each client has asked for and not yet received, at most; the
    /// rest are asked for as pages arrive, most urgent first (every wanted
    /// page at once if not given).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub max_outstanding: Option<u32>,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, clap::Args)]
pub struct WanArgs {
    /// Names the namespaces (1 to 8 of a-z, 0-9).
    #[arg(long, default_value = "ffwan")]
    pub name: String,
    /// Round trip, milliseconds (half each way).
    #[arg(long, default_value_t = 40.0)]
    pub rtt_ms: f64,
    /// The link's rate each way, megabits a second (unlimited if not given).
    #[arg(long)]
    pub rate_mbit: Option<f64>,
    /// Packets lost at random each way, percent.
    #[arg(long, default_value_t = 0.0)]
    pub loss_percent: f64,
}

#[derive(Debug, clap::Args)]
pub struct BenchPlpArgs {
    /// A PLP file (`farfield-server build --kind plp`).
    #[arg(long)]
    pub file: PathBuf,
    /// Its camera path (`farfield path gen:city --out city-path.json`):
    /// one frame per keyframe.
    #[arg(long)]
    pub path: PathBuf,
    /// PLP's budgets.
    #[arg(long, value_delimiter = ',', default_value = "1%,2%,5%,10%")]
    pub budgets: Vec<farfield_traverse::Budget>,
    /// The centroid-sorted baseline's budget.
    #[arg(long, default_value = "10%")]
    pub centroid: farfield_traverse::Budget,
    #[arg(long, value_parser = parse_size, default_value = "640x480")]
    pub size: (u32, u32),
    #[arg(long, default_value_t = 3)]
    pub repeats: usize,
    /// Every Nth keyframe of the path.
    #[arg(long, default_value_t = 1)]
    pub stride: usize,
    /// PLP's non-star-shaped penalty, in full cells of solidity.
    #[arg(long, default_value_t = farfield_traverse::plp::DEFAULT_STAR_PENALTY)]
    pub star_penalty: f64,
    /// What a projected cell passes on: `coverage` (its triangles' area
    /// over its cross-section, the default) or `count` (the paper's
    /// |A| / ρmax).
    #[arg(long, default_value = "coverage")]
    pub solidity: farfield_traverse::plp::Solidity,
    /// Print the paper's Table 1 row beside ours: `city` or `cars`.
    #[arg(long, value_parser = ["city", "cars"])]
    pub paper: Option<String>,
    /// Folder for frames.csv (the per-frame curves), visible.svg and
    /// frame_time.svg (Figures 8 and 9, a and b), table.md and report.json.
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[arg(long)]
    pub json: bool,
}

/// How splats look: what `view` and `render` share, so a window and its
/// headless reference draw alike.
#[derive(Debug, Clone, Copy, clap::Args)]
pub struct SplatArgs {
    #[arg(long, value_enum, default_value = "square")]
    pub kernel: KernelArg,
    #[command(flatten)]
    pub edl: EdlArgs,
    /// What colors splats: `rgb`, or `elevation` (a height ramp over the
    /// scene's bounds).
    #[arg(long, value_parser = parse_color_by, default_value = "rgb")]
    pub color: farfield_render::ColorBy,
    #[command(flatten)]
    pub clip: ClipArgs,
}

/// Eye-dome lighting over splats (Potree's point-cloud shading).
#[derive(Debug, Clone, Copy, clap::Args)]
pub struct EdlArgs {
    /// Shade splats with eye-dome lighting: depth steps darkened,
    /// silhouettes outlined.
    #[arg(long)]
    pub edl: bool,
    /// Its strength (implies --edl).
    #[arg(long, value_parser = parse_non_negative)]
    pub edl_strength: Option<f32>,
    /// How far, in pixels, it looks for neighbours in front (implies --edl).
    #[arg(long, value_parser = parse_non_negative)]
    pub edl_radius: Option<f32>,
}

impl EdlArgs {
    pub fn edl(self) -> Option<farfield_render::Edl> {
        let on = self.edl || self.edl_strength.is_some() || self.edl_radius.is_some();
        let default = farfield_render::Edl::default();
        on.then(|| farfield_render::Edl {
            strength: self.edl_strength.unwrap_or(default.strength),
            radius_px: self.edl_radius.unwrap_or(default.radius_px),
        })
    }
}

/// The clipping box over splats (Potree's).
#[derive(Debug, Clone, Copy, clap::Args)]
pub struct ClipArgs {
    /// Draw only the splats inside the clipping box, or only those outside.
    #[arg(long, value_enum)]
    pub clip: Option<KeepArg>,
    /// The box as shares of the scene's bounds: x0,y0,z0,x1,y1,z1, each 0
    /// to 1 (default: the whole scene).
    #[arg(long, value_parser = farfield_render::clip::parse_box, requires = "clip")]
    pub clip_box: Option<[f64; 6]>,
}

impl ClipArgs {
    pub fn clip(self) -> Option<farfield_render::Clip> {
        let keep = match self.clip? {
            KeepArg::Inside => farfield_render::Keep::Inside,
            KeepArg::Outside => farfield_render::Keep::Outside,
        };
        let corners = self.clip_box.unwrap_or([0.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
        Some(farfield_render::Clip::from_corners(corners, keep))
    }
}

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum KeepArg {
    Inside,
    Outside,
}

/// A splat colouring by name.
fn parse_color_by(s: &str) -> Result<farfield_render::ColorBy, String> {
    farfield_render::ColorBy::from_name(s).ok_or_else(|| format!("{s} is not rgb or elevation"))
}

/// A finite number, 0 or more.
fn parse_non_negative(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(format!("{s} is not a number of 0 or more")),
    }
}

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum KernelArg {
    Square,
    Round,
    Paraboloid,
}

impl From<KernelArg> for farfield_render::Kernel {
    fn from(k: KernelArg) -> Self {
        match k {
            KernelArg::Square => Self::Square,
            KernelArg::Round => Self::Round,
            KernelArg::Paraboloid => Self::Paraboloid,
        }
    }
}

#[derive(Debug, clap::Args)]
pub struct RenderArgs {
    #[command(flatten)]
    pub source: SourceArgs,
    #[command(flatten)]
    pub camera: CameraArgs,
    #[arg(long, value_parser = parse_size, default_value = "800x600")]
    pub size: (u32, u32),
    /// The PNG to write; with --path, the folder for frames.csv (and frames).
    #[arg(long)]
    pub out: PathBuf,
    /// Fly a camera path (JSON keyframes) instead of one camera.
    #[arg(long, conflicts_with_all = ["camera", "orbit"])]
    pub path: Option<PathBuf>,
    /// Frames per path second, with --path.
    #[arg(long, default_value_t = 10.0)]
    pub fps: f64,
    /// With --path, also write every frame as a PNG.
    #[arg(long)]
    pub write_frames: bool,
    /// With --path: image caching counts each cache's life span along the
    /// path, known in advance (the paper's offline estimate), instead of
    /// extrapolating the viewer's motion.
    #[arg(long, requires = "path")]
    pub known_path: bool,
    /// Join this demo session of the server (see --present, --follow).
    #[arg(long, value_name = "NAME", requires = "role", conflicts_with = "path")]
    pub session: Option<String>,
    /// Present: show this render's camera, threshold and kernel to the
    /// session's followers (the session is made if it does not exist).
    #[arg(long, group = "role", requires = "session")]
    pub present: bool,
    /// Follow: render the session presenter's view, with its threshold and kernel.
    #[arg(long, group = "role", requires = "session")]
    pub follow: bool,
    /// Stop when refined (default), after N frames, or after T milliseconds.
    #[arg(long, value_parser = ["refined"], conflicts_with_all = ["frames", "ms"])]
    pub until: Option<String>,
    #[arg(long)]
    pub frames: Option<u64>,
    #[arg(long)]
    pub ms: Option<f64>,
    /// Final projected-size threshold in pixels (spheres: splat size;
    /// cubes: eps, see --eps).
    #[arg(long, default_value_t = 1.0)]
    pub threshold: f64,
    /// Cube hierarchies: draw a cell as its color-cube when its projected
    /// edge is under this many pixels; 0 draws the geometry everywhere (the
    /// reference). The same setting as --threshold.
    #[arg(long, conflicts_with = "threshold")]
    pub eps: Option<f64>,
    /// BSP files (image caching): the error a cached image may show, in
    /// pixels; 0 never caches. The same setting as --threshold.
    #[arg(long, conflicts_with_all = ["threshold", "eps"])]
    pub epsilon_px: Option<f64>,
    /// Draw with this registered kind where the file's hierarchy has
    /// several: `culling` (a BSP file as geometry, the impostors'
    /// baseline), `centroid` (PLP's baseline); default, the file's first.
    #[arg(long)]
    pub mode: Option<String>,
    /// Cube hierarchies: `alpha` (coverage is transparency, 1996) or
    /// `threshold[:T]` (faces covered less than T, default 0.5, are
    /// dropped, the rest drawn opaque, 1995).
    #[arg(long, default_value = "alpha")]
    pub coverage: farfield_render::Coverage,
    #[command(flatten)]
    pub splats: SplatArgs,
    /// PLP files: the triangles a frame may draw, as a share of the scene
    /// (`5%`) or a count (`20000`); `all` draws everything.
    #[arg(long, default_value = "all")]
    pub budget: farfield_traverse::Budget,
    /// PLP files: a frame time in milliseconds instead (time-critical: the
    /// triangle budget follows the measured draw rate).
    #[arg(long, conflicts_with = "budget", value_parser = parse_positive_ms)]
    pub budget_ms: Option<f64>,
    /// Client page cache, MiB.
    #[arg(long, default_value_t = 1024)]
    pub cache_mib: u64,
    /// Let the server push pages it predicts when idle.
    #[arg(long)]
    pub push: bool,
    #[command(flatten)]
    pub access: AccessArgs,
    /// Give up after this many seconds (the image so far is still written).
    #[arg(long, default_value_t = 120.0)]
    pub timeout_s: f64,
    #[arg(long)]
    pub json: bool,
}

/// Runs one parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Compare {
            a,
            b,
            tolerance,
            json,
        } => commands::compare::run(&a, &b, tolerance, json),
        Command::Render(args) => commands::render::run(*args),
        Command::View(args) => commands::view::run(view_job(*args)?),
        Command::Bench(args) => commands::measure::bench(*args),
        Command::Loadtest(args) => commands::measure::loadtest(*args),
        Command::Wan(args) => commands::wan::run(&args),
        Command::Report { dirs, out } => commands::measure::report(&dirs, &out),
        Command::BenchCubes(args) => commands::measure::bench_cubes(*args),
        Command::BenchPlp(args) => commands::measure::bench_plp(*args),
        Command::BenchStream {
            scene,
            clients,
            seconds,
            cache_mib,
            repeats,
            json,
        } => commands::measure::bench_stream(&scene, clients, seconds, cache_mib, repeats, json),
        Command::Demo {
            out,
            listen,
            exit,
            no_window,
        } => {
            let after = if exit {
                commands::demo::AfterDemo::Exit
            } else {
                commands::demo::AfterDemo::Serve { window: !no_window }
            };
            commands::demo::print(out, listen, after, |url| {
                let args = ["view", "--server", url, "--scene", "island"];
                let Cli {
                    command: Command::View(args),
                } = Cli::try_parse_from(std::iter::once("farfield").chain(args))?
                else {
                    anyhow::bail!("not a view command");
                };
                view_job(*args)
            })
        }
        Command::Path { input, params, out } => commands::path::run(&input, &params, &out),
        Command::Traverse {
            file,
            orbit,
            size,
            threshold,
            json,
        } => commands::traverse::run(&file, orbit, size, threshold, json),
    }
}

fn view_job(args: ViewArgs) -> anyhow::Result<commands::view::ViewJob> {
    let settings = farfield_viewer::panel::Settings {
        threshold: args.threshold,
        kernel: args.splats.kernel.into(),
        edl: args.splats.edl.edl(),
        color_by: args.splats.color,
        clip: args.splats.clip.clip(),
        node_budget: args.budget,
        cache_mib: args.cache_mib.max(1),
        plp_budget_percent: args.plp_budget.clamp(0.0, 100.0),
        plp_budget_ms: if args.plp_budget_ms.is_finite() {
            args.plp_budget_ms.max(0.0)
        } else {
            0.0
        },
        epsilon_px: args.epsilon_px,
        outline_caches: args.outlines,
        ..Default::default()
    };
    Ok(commands::view::ViewJob {
        source: args.source.into_source()?,
        camera: args.camera.spec(),
        size: args.size,
        settings,
        show_panel: !args.no_panel,
        token: args.access.token,
        ca_cert: args.access.ca_cert,
        screenshot_when_refined: args.screenshot_when_refined,
        demo: args
            .session
            .map(|session| farfield_client::render_job::DemoRole {
                session,
                present: args.present,
            }),
        flight_seconds: args.flight,
    })
}

/// An image-cache error bound in pixels: finite and not negative.
fn parse_epsilon_px(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(eps) if eps.is_finite() && eps >= 0.0 => Ok(eps),
        _ => Err(format!(
            "{s} is not an error in pixels (a number, 0 or more)"
        )),
    }
}

/// A frame time in milliseconds: finite and above 0 (a 0 ms budget would
/// draw nothing, silently).
fn parse_positive_ms(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(ms) if ms.is_finite() && ms > 0.0 => Ok(ms),
        _ => Err(format!("{s} is not a positive number of milliseconds")),
    }
}
