//! The `farfield-server` command line, as a library so tests run the same
//! code in-process. Each subcommand has its own module and returns a
//! [`Report`]: a JSON value (printed with `--json`), a human summary, and
//! an exit code. `main.rs` only parses, prints and exits.

mod build;
mod cert;
mod export;
mod health;
mod inspect;
mod lidar_tiles;
mod merge;
mod publish;
mod remote;
mod serve;

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use farfield_memory_server::limits::Limits;

use clap::{Parser, Subcommand};

/// Import, build and inspect farfield hierarchies.
#[derive(Debug, Parser)]
#[command(name = "farfield-server", version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Build a paged hierarchy file from one or more inputs (merged into one scene).
    Build(BuildArgs),
    /// Print a file's counts and verify every page checksum.
    Inspect(InspectArgs),
    /// Measure build throughput or traversal rate.
    #[command(subcommand)]
    Bench(BenchCommand),
    /// Serve every `*.ff` scene in a folder to streaming clients until SIGINT or SIGTERM.
    Serve(ServeArgs),
    /// Write a scene's header and pages as plain files (`OUT/NAME/header`,
    /// `OUT/NAME/pages/N`, exactly as stored), for a static file server:
    /// what the load test's `--static` fetches, to compare with this server.
    Export(ExportArgs),
    /// Upload a built scene file to S3-compatible object storage
    /// (`s3://bucket/key.ff`), checked first and stored in one multipart
    /// upload, so a reader never sees half of it.
    Publish(PublishArgs),
    /// Exit 0 when the server at URL (`http://host:port`) answers /healthz
    /// (the container images' healthcheck).
    Health(HealthArgs),
    /// Write a private key and a self-signed certificate for `serve
    /// --tls-cert/--tls-key` (`DIR/key.pem`, `DIR/cert.pem`): a server
    /// certificate (not an authority), for the names given, that the
    /// client takes with `--ca-cert DIR/cert.pem` and a browser after an
    /// exception.
    Cert(CertArgs),
    /// Join the N parts of a build on many machines (`build --subset I/N`),
    /// in any order, into one scene file: the whole build, byte for byte.
    Merge(MergeArgs),
    /// Write generated lidar for benchmarks: a terrain of `--points`
    /// random points with RGB and intensity, as a `--grid` x `--grid`
    /// square of LAS tiles in `--out`, each with its own offset (as surveys
    /// are delivered). Deterministic for a seed; memory does not grow with
    /// the point count.
    LidarTiles(LidarTilesArgs),
}

#[derive(Debug, clap::Args)]
pub struct MergeArgs {
    /// The parts' folders, or their prefixes in a store
    /// (`s3://bucket/parts/1`, downloaded under `--tmp` first).
    #[arg(required = true)]
    pub parts: Vec<PathBuf>,
    /// The scene file to write, or `s3://bucket/key.ff` to publish it to
    /// object storage.
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub store: StoreArgs,
    /// Where the merge's temporary files go (default: the output's folder).
    #[arg(long)]
    pub tmp: Option<PathBuf>,
    /// Upper bound on a page's bytes (default 16 KiB).
    #[arg(long)]
    pub page_bytes: Option<usize>,
    /// Print one JSON summary object on stdout and no progress bar.
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, clap::Args)]
pub struct LidarTilesArgs {
    #[arg(long)]
    pub points: u64,
    #[arg(long, default_value_t = 1)]
    pub grid: u32,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    #[arg(long)]
    pub out: PathBuf,
}

#[derive(Debug, clap::Args)]
pub struct CertArgs {
    /// A host name or address the certificate is for; repeatable
    /// (`localhost` and `127.0.0.1` when none is given).
    #[arg(long = "name", value_name = "HOST")]
    pub names: Vec<String>,
    /// The folder to write `key.pem` and `cert.pem` into.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, clap::Args)]
pub struct HealthArgs {
    pub url: String,
}

#[derive(Debug, clap::Args)]
pub struct PublishArgs {
    /// The scene file.
    pub file: PathBuf,
    /// Where to put it: `s3://bucket/key.ff`.
    pub to: String,
    #[command(flatten)]
    pub store: StoreArgs,
    #[arg(long)]
    pub json: bool,
}

/// How to reach an object store. Its endpoint, region and credentials
/// come from the environment, as the AWS tools read them:
/// `AWS_ENDPOINT_URL` (an `http://` one is allowed plain), `AWS_REGION`,
/// `AWS_ACCESS_KEY_ID`, `AWS_SECRET_ACCESS_KEY`.
#[derive(Debug, Clone, clap::Args)]
pub struct StoreArgs {
    /// Seconds one request to the object store may take before it counts
    /// as failed.
    #[arg(long, default_value_t = 10.0, value_parser = seconds)]
    pub store_timeout: f64,
    /// Neighbouring pages (read ahead together) come in one range request
    /// while their span is at most this many bytes; 0 asks for each alone.
    #[arg(long, default_value_t = farfield_objects::DEFAULT_COALESCE_BYTES)]
    pub store_coalesce_bytes: u64,
    /// A local-disk second tier under the page cache: a folder (emptied at
    /// start) that keeps pages read from the store, up to
    /// --store-tier-bytes.
    #[arg(long)]
    pub store_tier_dir: Option<PathBuf>,
    /// The second tier's bound in bytes.
    #[arg(long, default_value_t = 4 << 30)]
    pub store_tier_bytes: u64,
}

/// The folder a file is written in (`.` for a bare name): where a
/// command's temporary files go by default, on the output's file system.
pub(crate) fn folder_of(path: &std::path::Path) -> PathBuf {
    path.parent()
        .filter(|p| !p.as_os_str().is_empty())
        .map_or_else(|| PathBuf::from("."), std::path::Path::to_owned)
}

/// Publishes the scene written to `local` as `target`'s object, removing
/// `local` either way; the bytes published.
pub(crate) fn publish_and_remove(
    local: &std::path::Path,
    (bucket, url): &(
        std::sync::Arc<farfield_objects::Bucket>,
        farfield_objects::StoreUrl,
    ),
) -> anyhow::Result<u64> {
    let published = farfield_objects::publish(local, bucket, &url.key);
    let _ = std::fs::remove_file(local);
    Ok(published?)
}

impl StoreArgs {
    /// Where a command that writes a scene publishes it: `None` for a
    /// local `out`, else the store's bucket and the object's address, the
    /// store reached first so that a wrong address fails before the work.
    pub fn publish_target(
        &self,
        out: &std::path::Path,
    ) -> anyhow::Result<
        Option<(
            std::sync::Arc<farfield_objects::Bucket>,
            farfield_objects::StoreUrl,
        )>,
    > {
        let Some(url) = out.to_str().filter(|o| farfield_objects::is_store_url(o)) else {
            return Ok(None);
        };
        let (bucket, url) = self.bucket(url, Default::default())?;
        anyhow::ensure!(
            !url.key.is_empty(),
            "{url}: name the object to write (s3://bucket/key.ff)"
        );
        match bucket.head(&url.key) {
            Ok(_) | Err(farfield_objects::RemoteError::NotFound(_)) => {}
            Err(e) => anyhow::bail!("cannot reach the store: {e}"),
        }
        Ok(Some((bucket, url)))
    }

    /// The bucket of `url` (`s3://bucket/...`), and the key or prefix.
    pub fn bucket(
        &self,
        url: &str,
        stats: std::sync::Arc<farfield_store::RemoteStats>,
    ) -> anyhow::Result<(
        std::sync::Arc<farfield_objects::Bucket>,
        farfield_objects::StoreUrl,
    )> {
        let url = farfield_objects::StoreUrl::parse(url).map_err(anyhow::Error::msg)?;
        anyhow::ensure!(
            self.store_timeout > 0.0,
            "--store-timeout must be more than 0 seconds"
        );
        let options = farfield_objects::BucketOptions {
            timeout: Duration::from_secs_f64(self.store_timeout),
            coalesce_bytes: self.store_coalesce_bytes,
            tier: self
                .store_tier_dir
                .clone()
                .map(|dir| (dir, self.store_tier_bytes)),
            ..Default::default()
        };
        let bucket = farfield_objects::Bucket::open(&url, &options, stats)?;
        Ok((std::sync::Arc::new(bucket), url))
    }
}

#[derive(Debug, clap::Args)]
pub struct ExportArgs {
    /// The scene file.
    pub file: PathBuf,
    /// The folder to write into (the scene's files go in OUT/NAME).
    #[arg(long)]
    pub out: PathBuf,
    /// The scene's name (the file's name without `.ff` if not given).
    #[arg(long)]
    pub name: Option<String>,
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, clap::Args)]
pub struct BuildArgs {
    /// Input files (.obj .ply .off .las .laz .pdb), folders of them (a survey's tiles), generated scenes (gen:island, gen:tree),
    /// or objects in a store (`s3://bucket/tile.las`, or `s3://bucket/survey/` for every readable object under it; downloaded under `--tmp` first).
    #[arg(required = true)]
    pub inputs: Vec<String>,
    /// The file to write (written to a temporary file, then renamed), or
    /// `s3://bucket/key.ff` to publish it to object storage.
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub store: StoreArgs,
    /// Generator parameters, `key=value` (e.g. trees=64, seed=3).
    #[arg(long = "param", value_name = "KEY=VALUE")]
    pub params: Vec<String>,
    /// The inputs' up axis, turned to +Z so the scene opens upright:
    /// `auto` (Y for OBJ, OFF and PLY meshes, Z for the rest), `x`, `y`
    /// or `z`. LAS/LAZ are Z-up whatever it says.
    #[arg(long, default_value = "auto")]
    pub up: farfield_builder::import::up::Up,
    /// Upper bound on a page's bytes (default: 16 KiB for spheres, 64 KiB
    /// for cubes, 32 KiB for plp).
    #[arg(long)]
    pub page_bytes: Option<usize>,
    /// Which hierarchy (each kind's builder says what it is in `--help`).
    #[arg(long, default_value = "spheres", value_parser = kind_names())]
    pub kind: String,
    /// Spheres: the memory the build may use (4G, 512M, bytes); point
    /// clouds and meshes whose build needs more are built out of core, in chunks
    /// spilled under `--tmp` (default: half the machine's or the memory
    /// cgroup's memory).
    #[arg(long, value_parser = farfield_builder::out_of_core::parse_bytes)]
    pub memory: Option<u64>,
    /// Spheres: build part I of N (`I/N`, I from 1 to N) of a point cloud,
    /// into the folder `--out` (or under the store prefix
    /// `s3://bucket/parts/I`), for a build on many machines: each part
    /// reads all the inputs but sizes only its own region; `merge` joins
    /// the N parts into the scene.
    #[arg(long, value_name = "I/N")]
    pub subset: Option<farfield_builder::out_of_core::Subset>,
    /// Spheres: the folder an out-of-core build's temporary files go under
    /// (default: the output's folder; for `s3://` outputs, the system's
    /// temporary folder). They are removed when the build ends.
    #[arg(long)]
    pub tmp: Option<PathBuf>,
    /// Cubes: samples per cube-face edge (16 = 4 x 4 pixels of 4 x 4 samples).
    #[arg(long, default_value_t = 16)]
    pub face_samples: usize,
    /// Cubes: k x k x k color-cubes per cell (1, 2, 4, 8 or 16).
    #[arg(long, default_value_t = 1)]
    pub cluster: u8,
    /// Cubes: deepest octree level.
    #[arg(long, default_value_t = 32)]
    pub max_depth: u32,
    /// Cubes: how children's faces combine, `disjoint` (1995: opaque stays
    /// opaque) or `over` (1996).
    #[arg(long, default_value = "disjoint")]
    pub composite: farfield_builder::cubes::Composite,
    /// Cubes: what one cube costs to draw, in triangles (the subdivision
    /// criterion; larger means larger leaves).
    #[arg(long, default_value_t = farfield_builder::cubes::octree::CUBE_COST)]
    pub cube_cost: f64,
    /// PLP: octree leaves stop once their side is under this fraction of
    /// the bounding box's longest side (the paper's 5 %).
    #[arg(long, default_value_t = 0.05)]
    pub leaf_fraction: f64,
    /// PLP: the seed of the leaf centres' random perturbation.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// BSP: splitting directions, evenly around the up axis (+Z); 2 makes
    /// every region an axis-aligned box (the paper's island).
    #[arg(long, default_value_t = 2)]
    pub bsp_directions: u32,
    /// BSP: each leaf also stores the geometry inside its region grown by
    /// this fraction (the paper's 17 %), so neighbouring caches overlap.
    #[arg(long, default_value_t = 0.17)]
    pub inflation: f64,
    /// BSP: a node with at most one instance and at most this many other
    /// triangles is a leaf.
    #[arg(long, default_value_t = 4096)]
    pub leaf_triangles: u64,
    /// Print one JSON summary object on stdout and no progress bar.
    #[arg(long)]
    pub json: bool,
}

/// The kinds `build` makes: the builder registry's names.
fn kind_names() -> clap::builder::PossibleValuesParser {
    farfield_builder::kinds::BUILDERS
        .iter()
        .map(|b| clap::builder::PossibleValue::new(b.name()).help(b.about))
        .collect::<Vec<_>>()
        .into()
}

#[derive(Debug, clap::Args)]
pub struct InspectArgs {
    pub file: PathBuf,
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, clap::Args)]
pub struct ServeArgs {
    /// Folder of scene files (`*.ff`; each is served under its file stem;
    /// a path or a `file://` URL), or `s3://bucket/prefix`: the `*.ff`
    /// objects under a prefix in S3-compatible object storage, read by
    /// range requests.
    #[arg(long)]
    pub scenes: String,
    #[command(flatten)]
    pub store: StoreArgs,
    /// Address to listen on (port 0 picks a free port; the first line of
    /// output says which).
    #[arg(long, default_value = "127.0.0.1:7878")]
    pub listen: SocketAddr,
    /// Bound on the shared page cache, in bytes.
    #[arg(long, default_value_t = farfield_memory_server::DEFAULT_CACHE_BYTES)]
    pub cache_bytes: u64,
    /// Seconds between looks at the scenes folder for scene files added,
    /// replaced, changed or deleted while serving (0: never look again).
    #[arg(long, default_value_t = farfield_memory_server::rescan::DEFAULT_RESCAN_INTERVAL.as_secs_f64(), value_parser = seconds)]
    pub rescan_seconds: f64,
    #[command(flatten)]
    pub limits: LimitArgs,
    /// A token clients must present (`Authorization: Bearer TOKEN`, or
    /// `?access_token=TOKEN`) to see every scene; repeatable. Visible to
    /// other users in the process list: prefer --tokens-file.
    #[arg(long = "token", value_name = "TOKEN")]
    pub tokens: Vec<String>,
    /// A file of tokens: one a line, optionally followed by the
    /// comma-separated scenes it may see (`#` starts a comment).
    #[arg(long, value_name = "FILE")]
    pub tokens_file: Option<PathBuf>,
    /// An origin (`https://host:port`) whose web pages may use this server
    /// besides its own pages; `*` allows any. Repeatable.
    #[arg(long = "allow-origin", value_name = "ORIGIN")]
    pub allowed_origins: Vec<String>,
    /// A host name requests may be for besides the server's own addresses,
    /// `localhost` (on loopback or every interface) and its certificate's
    /// names: a reverse proxy's public name, or this machine's name on a
    /// network. Requests for other names are refused (421), so a page on a
    /// domain rebound to this address reads nothing. `*` answers any.
    /// Repeatable.
    #[arg(long = "allowed-host", value_name = "NAME")]
    pub allowed_hosts: Vec<String>,
    /// Serve HTTPS and wss:// with this certificate chain (PEM).
    #[arg(long, value_name = "PEM", requires = "tls_key")]
    pub tls_cert: Option<PathBuf>,
    /// The certificate's private key (PEM).
    #[arg(long, value_name = "PEM", requires = "tls_cert")]
    pub tls_key: Option<PathBuf>,
    /// The browser viewer's built files (default: $FARFIELD_WEB_DIR,
    /// ./web/dist, or web/dist of the checkout this binary was built in).
    #[arg(long, value_name = "DIR")]
    pub web: Option<PathBuf>,
    /// Print the final counters as one JSON object on shutdown.
    #[arg(long)]
    pub json: bool,
}

/// What one client may cost and how long it may take (defaults suit a
/// public server; see `farfield_memory_server::limits`).
#[derive(Debug, clap::Args)]
pub struct LimitArgs {
    /// Connections open at once, all clients together (past it: 503).
    #[arg(long, default_value_t = Limits::default().max_connections)]
    pub max_connections: usize,
    /// Connections open at once from one IP address (past it: 429).
    #[arg(long, default_value_t = Limits::default().max_connections_per_address)]
    pub max_connections_per_address: usize,
    /// Seconds a connection has to send its request headers (also the
    /// longest a kept-alive HTTP connection may sit idle).
    #[arg(long, default_value_t = Limits::default().header_timeout.as_secs_f64(), value_parser = seconds)]
    pub header_timeout: f64,
    /// Seconds a websocket client has to say hello.
    #[arg(long, default_value_t = Limits::default().hello_timeout.as_secs_f64(), value_parser = seconds)]
    pub hello_timeout: f64,
    /// Seconds a session may go without a message or a pong, or without
    /// taking bytes, before it is closed.
    #[arg(long, default_value_t = Limits::default().idle_timeout.as_secs_f64(), value_parser = seconds)]
    pub idle_timeout: f64,
    /// Websocket messages (pings included) a session may send per second.
    #[arg(long, default_value_t = Limits::default().max_messages_per_second)]
    pub max_messages_per_second: u32,
    /// Seconds a demo session whose presenter left waits for a presenter
    /// before it closes.
    #[arg(long, default_value_t = Limits::default().session_grace.as_secs_f64(), value_parser = seconds)]
    pub session_grace: f64,
    /// Demo sessions open at once.
    #[arg(long, default_value_t = Limits::default().max_sessions)]
    pub max_sessions: usize,
}

impl LimitArgs {
    pub fn limits(&self) -> Limits {
        Limits {
            max_connections: self.max_connections,
            max_connections_per_address: self.max_connections_per_address,
            header_timeout: Duration::from_secs_f64(self.header_timeout),
            hello_timeout: Duration::from_secs_f64(self.hello_timeout),
            idle_timeout: Duration::from_secs_f64(self.idle_timeout),
            max_messages_per_second: self.max_messages_per_second,
            session_grace: Duration::from_secs_f64(self.session_grace),
            max_sessions: self.max_sessions,
            ..Limits::default()
        }
        .sane()
    }
}

/// A non-negative, finite number of seconds.
fn seconds(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(s) if (0.0..1e9).contains(&s) => Ok(s),
        _ => Err(format!(
            "expected a number of seconds, at least 0, got {text:?}"
        )),
    }
}

#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Import and build inputs repeatedly (nothing written); median throughput and peak memory.
    Build {
        #[arg(required = true)]
        inputs: Vec<String>,
        #[arg(long = "param", value_name = "KEY=VALUE")]
        params: Vec<String>,
        #[arg(long, default_value_t = 3)]
        repeats: usize,
        #[arg(long)]
        json: bool,
    },
    /// Store built files' pages with each candidate page codec on one core: ratio, bytes per input, median encode and decode rates.
    Codecs {
        #[arg(required = true)]
        files: Vec<PathBuf>,
        #[arg(long, default_value_t = 5)]
        repeats: usize,
        #[arg(long)]
        json: bool,
    },
    /// Traverse a whole file at a 1-pixel threshold on one core; median nodes per second.
    Traverse {
        file: PathBuf,
        #[arg(long, default_value_t = 9)]
        repeats: usize,
        #[arg(long)]
        json: bool,
    },
}

/// What a command produced.
#[derive(Debug)]
pub struct Report {
    pub json: serde_json::Value,
    pub text: String,
    pub exit_code: u8,
    /// Whether the caller asked for JSON on stdout.
    pub as_json: bool,
}

/// Runs one parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<Report> {
    match cli.command {
        Command::Build(args) => build::run(&args),
        Command::Inspect(args) => inspect::run(&args),
        Command::Bench(BenchCommand::Build {
            inputs,
            params,
            repeats,
            json,
        }) => measured(
            farfield_tools::bench_build::build(&inputs, &params, repeats)?,
            json,
        ),
        Command::Bench(BenchCommand::Codecs {
            files,
            repeats,
            json,
        }) => measured(farfield_tools::bench_codecs::codecs(&files, repeats)?, json),
        Command::Bench(BenchCommand::Traverse {
            file,
            repeats,
            json,
        }) => measured(
            farfield_tools::bench_build::traverse_file(&file, repeats)?,
            json,
        ),
        Command::Serve(args) => serve::run(&args),
        Command::Export(args) => export::run(&args),
        Command::Publish(args) => publish::run(&args),
        Command::Health(args) => health::run(&args),
        Command::Cert(args) => cert::run(&args),
        Command::LidarTiles(args) => lidar_tiles::run(&args),
        Command::Merge(args) => merge::run(&args),
    }
}

/// `n` and a noun in the right number: "1 level", "11 levels".
pub fn counted(n: impl Into<u64>, one: &str, many: &str) -> String {
    let n = n.into();
    format!("{n} {}", if n == 1 { one } else { many })
}

/// A benchmark's figures as a command's report.
fn measured(m: farfield_tools::Measured, as_json: bool) -> anyhow::Result<Report> {
    Ok(Report {
        json: m.json,
        text: m.text,
        exit_code: 0,
        as_json,
    })
}
