//! `farfield`: the client command line. Parsing and dispatch only; the work
//! is in `farfield_client::commands`.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::Context;
use clap::{Parser, Subcommand, ValueEnum};
use farfield_client::args::{CameraSpec, parse_camera, parse_orbit, parse_size};
use farfield_client::commands::render::{RenderJob, Source, Until};
use farfield_client::net::SessionOptions;
use farfield_client::render::{Kernel, Renderer};
use farfield_protocol::traverse::{TraverseOptions, traverse};

/// Browse farfield scenes, streamed from a memory server or from a file.
#[derive(Debug, Parser)]
#[command(name = "farfield", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Render one view to a PNG, streaming pages from a server or reading a file.
    Render(Box<RenderArgs>),
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
    /// Error against run time: sweep a mode's parameter over cameras, against a reference.
    Bench(Box<BenchArgs>),
    /// One HTML page (plots, tables, machine, the papers' figures) from bench folders.
    Report {
        /// Folders written by `farfield bench --out`.
        #[arg(required = true)]
        dirs: Vec<PathBuf>,
        #[arg(long)]
        out: PathBuf,
    },
    /// Build the default scene, serve it in-process, fly a client through it.
    Demo {
        /// Folder for the scene file, frames, CSV and summary.
        #[arg(long, default_value = "farfield-demo")]
        out: PathBuf,
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
struct SourceArgs {
    /// Memory server, e.g. http://127.0.0.1:7878 (pages then stream).
    #[arg(long, requires = "scene", conflicts_with = "file")]
    server: Option<String>,
    /// Scene name on the server.
    #[arg(long)]
    scene: Option<String>,
    /// Read a paged file directly (everything resident, no server).
    #[arg(long, required_unless_present = "server")]
    file: Option<PathBuf>,
}

impl SourceArgs {
    fn into_source(self) -> anyhow::Result<Source> {
        Ok(match (self.server, self.scene, self.file) {
            (Some(url), Some(scene), None) => Source::Server { url, scene },
            (None, _, Some(path)) => Source::File(path),
            _ => anyhow::bail!("give --server URL --scene NAME, or --file FILE"),
        })
    }
}

#[derive(Debug, clap::Args)]
struct BenchArgs {
    #[command(flatten)]
    source: SourceArgs,
    /// Cameras: the keyframes of this path (JSON); default an orbit at 1.75, 3.5 and 7 radii.
    #[arg(long)]
    path: Option<PathBuf>,
    /// spheres, cubes or geometry.
    #[arg(long)]
    mode: String,
    /// PARAM=v1,v2,...: threshold or kernel (spheres), eps or coverage (cubes), full=all (geometry).
    #[arg(long)]
    sweep: String,
    /// A setting held fixed while sweeping, e.g. kernel=square (repeatable).
    #[arg(long = "set", value_name = "PARAM=VALUE")]
    set: Vec<String>,
    /// The scene's input (files or gen: scenes): the geometry mode's triangles, and the reference.
    #[arg(long = "input")]
    inputs: Vec<String>,
    #[arg(long = "param", value_name = "KEY=VALUE")]
    params: Vec<String>,
    #[arg(long, value_parser = parse_size, default_value = "320x240")]
    size: (u32, u32),
    #[arg(long, default_value_t = 3)]
    repeats: u32,
    /// Folder for bench.csv, progress.csv, meta.json and the plots.
    #[arg(long)]
    out: PathBuf,
    #[arg(long, default_value_t = 120.0)]
    timeout_s: f64,
}

#[derive(Debug, clap::Args)]
struct BenchCubesArgs {
    /// A cube hierarchy (`farfield-server build --kind cubes`).
    #[arg(long)]
    file: PathBuf,
    /// The inputs it was built from: the full-geometry reference.
    #[arg(long = "input", required = true)]
    inputs: Vec<String>,
    /// Generator parameters of the inputs, `key=value`.
    #[arg(long = "param", value_name = "KEY=VALUE")]
    params: Vec<String>,
    /// Eye distances from the scene centre, in scene radii.
    #[arg(long, value_delimiter = ',', default_value = "1.75,3.5,7,14")]
    distances: Vec<f64>,
    /// Degrees off the octree's x axis (the paper: 30 for the tree, 25 for the molecule).
    #[arg(long, default_value_t = 30.0)]
    azimuth: f64,
    #[arg(long, default_value_t = 0.0)]
    elevation: f64,
    /// The paper's images were 124x124.
    #[arg(long, value_parser = parse_size, default_value = "124x124")]
    size: (u32, u32),
    #[arg(long, default_value_t = 1.0)]
    eps: f64,
    #[arg(long, default_value = "alpha")]
    coverage: farfield_client::render::Coverage,
    #[arg(long, default_value_t = 5)]
    repeats: usize,
    /// Write each distance's geometry and hierarchy images here.
    #[arg(long)]
    images: Option<PathBuf>,
    #[arg(long)]
    json: bool,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum KernelArg {
    Square,
    Round,
}

#[derive(Debug, clap::Args)]
struct RenderArgs {
    #[command(flatten)]
    source: SourceArgs,
    /// eye=x,y,z,target=x,y,z,fov=DEG (world units).
    #[arg(long, value_parser = parse_camera, conflicts_with = "orbit")]
    camera: Option<CameraSpec>,
    /// azimuth=DEG,elevation=DEG,distance=R (R in scene radii from the centre).
    #[arg(long, value_parser = parse_orbit)]
    orbit: Option<CameraSpec>,
    #[arg(long, value_parser = parse_size, default_value = "800x600")]
    size: (u32, u32),
    /// The PNG to write; with --path, the folder for frames.csv (and frames).
    #[arg(long)]
    out: PathBuf,
    /// Fly a camera path (JSON keyframes) instead of one camera.
    #[arg(long, conflicts_with_all = ["camera", "orbit"])]
    path: Option<PathBuf>,
    /// Frames per path second, with --path.
    #[arg(long, default_value_t = 10.0)]
    fps: f64,
    /// With --path, also write every frame as a PNG.
    #[arg(long)]
    write_frames: bool,
    /// Stop when refined (default), after N frames, or after T milliseconds.
    #[arg(long, value_parser = ["refined"], conflicts_with_all = ["frames", "ms"])]
    until: Option<String>,
    #[arg(long)]
    frames: Option<u64>,
    #[arg(long)]
    ms: Option<f64>,
    /// Final projected-size threshold in pixels (spheres: splat size;
    /// cubes: eps, see --eps).
    #[arg(long, default_value_t = 1.0)]
    threshold: f64,
    /// Cube hierarchies: draw a cell as its color-cube when its projected
    /// edge is under this many pixels; 0 draws the geometry everywhere (the
    /// reference). The same setting as --threshold.
    #[arg(long, conflicts_with = "threshold")]
    eps: Option<f64>,
    /// Cube hierarchies: `alpha` (coverage is transparency, 1996) or
    /// `threshold[:T]` (faces covered less than T, default 0.5, are
    /// dropped, the rest drawn opaque, 1995).
    #[arg(long, default_value = "alpha")]
    coverage: farfield_client::render::Coverage,
    #[arg(long, value_enum, default_value = "square")]
    kernel: KernelArg,
    /// Client page cache, MiB.
    #[arg(long, default_value_t = 1024)]
    cache_mib: u64,
    /// Let the server push pages it predicts when idle.
    #[arg(long)]
    push: bool,
    /// Give up after this many seconds (the image so far is still written).
    #[arg(long, default_value_t = 120.0)]
    timeout_s: f64,
    #[arg(long)]
    json: bool,
}

fn render(args: RenderArgs) -> anyhow::Result<()> {
    let source = args.source.into_source()?;
    let until = match (args.frames, args.ms) {
        (Some(n), _) => Until::Frames(n.max(1)),
        (_, Some(ms)) => Until::Millis(ms),
        _ => Until::Refined,
    };
    let threshold = args.eps.unwrap_or(args.threshold);
    anyhow::ensure!(
        threshold.is_finite() && threshold >= 0.0,
        "--threshold and --eps must be non-negative numbers"
    );
    anyhow::ensure!(
        args.timeout_s.is_finite() && args.timeout_s > 0.0,
        "--timeout-s must be positive"
    );
    let job = RenderJob {
        source,
        camera: args.camera.or(args.orbit).unwrap_or_default(),
        width: args.size.0,
        height: args.size.1,
        out: Some(args.out),
        until,
        threshold_px: threshold,
        kernel: match args.kernel {
            KernelArg::Square => Kernel::Square,
            KernelArg::Round => Kernel::Round,
        },
        coverage: args.coverage,
        session: SessionOptions {
            allow_push: args.push,
            ..SessionOptions::default()
        },
        cache_bytes: (args.cache_mib.max(1) << 20) as usize,
        timeout: Duration::from_secs_f64(args.timeout_s),
    };
    let mut renderer =
        Renderer::new_headless(job.width, job.height).context("starting the renderer")?;
    if let Some(path) = args.path {
        return fly_path(
            &job,
            &path,
            args.fps,
            args.write_frames,
            &mut renderer,
            args.json,
        );
    }
    let rendered = farfield_client::commands::render::run(&job, &mut renderer, false)?;
    let r = &rendered.report;
    if args.json {
        println!("{}", serde_json::to_string(r)?);
    } else {
        println!(
            "{}: {} frames, first image {:.1} ms, refined {}, {} nodes drawn at {} px, {} bytes in {} pages, overfetch {}, on {}",
            job.out
                .as_deref()
                .map(|p| p.display().to_string())
                .unwrap_or_default(),
            r.frames,
            r.time_to_first_image_ms.unwrap_or(f64::NAN),
            r.time_to_refined_ms
                .map_or("no".to_owned(), |t| format!("in {t:.1} ms")),
            r.nodes_drawn,
            r.threshold_px,
            r.net.bytes_received,
            r.net.pages_received,
            r.overfetch_ratio
                .map_or("-".to_owned(), |o| format!("{o:.2}")),
            r.adapter
        );
    }
    render_outcome(r, until == Until::Refined)
}

/// The error a finished render exits with, if any: pages given up on (the
/// image is written, with their parts drawn coarser) and, when the job was
/// to refine, not having refined.
fn render_outcome(
    r: &farfield_client::commands::render::RenderReport,
    until_refined: bool,
) -> anyhow::Result<()> {
    let mut problems = Vec::new();
    if !r.pages_failed.is_empty() {
        let pages: Vec<u32> = r.pages_failed.iter().map(|f| f.page).collect();
        let reasons: Vec<&str> = r.pages_failed.iter().map(|f| f.reason.as_str()).collect();
        problems.push(format!(
            "pages {pages:?} could not be loaded, their parts are drawn coarser ({})",
            reasons.join("; ")
        ));
    }
    if !r.refined && until_refined {
        problems.push(r.last_error.clone().unwrap_or_else(|| "not refined".into()));
    }
    anyhow::ensure!(problems.is_empty(), "{}", problems.join("; "));
    Ok(())
}

/// `render --path`: a flythrough with per-frame stats.
fn fly_path(
    job: &RenderJob,
    path: &std::path::Path,
    fps: f64,
    write_frames: bool,
    renderer: &mut Renderer,
    json: bool,
) -> anyhow::Result<()> {
    use farfield_client::commands::fly::{FlyJob, fly, write_csv};
    use farfield_client::render::SplatStyle;
    anyhow::ensure!(fps.is_finite() && fps > 0.0, "--fps must be positive");
    let out = job.out.clone().unwrap_or_default();
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let started = Instant::now();
    let mut viewer = farfield_client::commands::render::open_viewer(job)?;
    let fly_job = FlyJob {
        path: farfield_client::path::CameraPath::load(path)?,
        fps,
        width: job.width,
        height: job.height,
        final_threshold_px: job.threshold_px,
        target_frame_ms: 100.0,
        style: SplatStyle {
            kernel: job.kernel,
            coverage: job.coverage,
            ..SplatStyle::default()
        },
        frames_dir: write_frames.then(|| out.join("frames")),
        settle: true,
        timeout: job.timeout,
    };
    let (stats, settle) = fly(&mut viewer, renderer, &fly_job, started)?;
    write_csv(&out.join("frames.csv"), &stats)?;
    let report = settle.report(
        &viewer,
        renderer,
        matches!(job.source, Source::Server { .. }),
    );
    if json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        println!(
            "{}: {} frames, {} bytes received; per-frame stats in frames.csv",
            out.display(),
            stats.len(),
            report.net.bytes_received
        );
    }
    render_outcome(&report, false)
}

/// `farfield compare A B`: the error of image B against reference A.
fn compare(a: PathBuf, b: PathBuf, tolerance: u8, json: bool) -> anyhow::Result<()> {
    let c = farfield_client::eval::compare_files(&a, &b, tolerance)?;
    if json {
        println!("{}", c.metrics.to_json(c.width, c.height));
    } else {
        let (w, h, m) = (c.width, c.height, c.metrics);
        println!("{} vs {} ({w}x{h}): {m}", a.display(), b.display());
    }
    Ok(())
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Compare {
            a,
            b,
            tolerance,
            json,
        } => compare(a, b, tolerance, json),
        Command::Render(args) => render(*args),
        Command::Bench(args) => {
            let source = args.source.into_source()?;
            let (param, values) = args
                .sweep
                .split_once('=')
                .context("--sweep must be PARAM=v1,v2,...")?;
            let values: Vec<String> = values
                .split(',')
                .map(str::to_owned)
                .filter(|v| !v.is_empty())
                .collect();
            anyhow::ensure!(!values.is_empty(), "--sweep {param}= has no values");
            let job = farfield_client::bench::BenchJob {
                source,
                path: args
                    .path
                    .as_deref()
                    .map(farfield_client::path::CameraPath::load)
                    .transpose()?,
                mode: args.mode,
                param: param.to_owned(),
                values,
                fixed: args
                    .set
                    .iter()
                    .map(|s| {
                        s.split_once('=')
                            .map(|(k, v)| (k.to_owned(), v.to_owned()))
                            .with_context(|| format!("--set {s} is not PARAM=VALUE"))
                    })
                    .collect::<anyhow::Result<_>>()?,
                inputs: args.inputs,
                input_params: args.params,
                width: args.size.0,
                height: args.size.1,
                repeats: args.repeats,
                out: args.out,
                timeout: Duration::from_secs_f64(args.timeout_s.max(1.0)),
            };
            let mut renderer =
                Renderer::new_headless(job.width, job.height).context("starting the renderer")?;
            let (rows, progress) = farfield_client::bench::run(&job, &mut renderer)?;
            println!(
                "{}: {} rows, {} progress frames; bench.csv, progress.csv, meta.json and plots written",
                job.out.display(),
                rows.len(),
                progress.len()
            );
            Ok(())
        }
        Command::Report { dirs, out } => {
            let page = farfield_client::bench::report::write_report(&dirs, &out)?;
            println!("{}", page.display());
            Ok(())
        }
        Command::BenchCubes(args) => {
            use farfield_client::commands::bench_cubes::{CubeBenchJob, format_table, run};
            anyhow::ensure!(
                args.eps.is_finite() && args.eps >= 0.0,
                "--eps must be a non-negative number"
            );
            let job = CubeBenchJob {
                file: args.file,
                inputs: args.inputs,
                params: args.params,
                distances: args.distances,
                azimuth_deg: args.azimuth,
                elevation_deg: args.elevation,
                width: args.size.0,
                height: args.size.1,
                eps_px: args.eps,
                coverage: args.coverage,
                repeats: args.repeats,
                images: args.images,
            };
            let mut renderer =
                Renderer::new_headless(job.width, job.height).context("starting the renderer")?;
            let report = run(&job, &mut renderer)?;
            if args.json {
                println!("{}", serde_json::to_string(&report)?);
            } else {
                print!("{}", format_table(&report));
            }
            Ok(())
        }
        Command::BenchStream {
            scene,
            clients,
            seconds,
            cache_mib,
            repeats,
            json,
        } => {
            use farfield_client::commands::bench_stream::{default_job, describe, run_bench};
            anyhow::ensure!(
                seconds.is_finite() && seconds > 0.0,
                "--seconds must be positive"
            );
            let job = farfield_client::commands::bench_stream::BenchStreamJob {
                clients,
                seconds,
                cache_bytes: cache_mib.max(1) << 20,
                repeats,
                ..default_job(&scene)
            };
            let report = run_bench(&job)?;
            if json {
                println!("{}", serde_json::to_string(&report)?);
            } else {
                print!("{}", describe(&report));
            }
            Ok(())
        }
        Command::Demo { out } => {
            let summary =
                farfield_client::commands::demo::run(&farfield_client::commands::demo::DemoJob {
                    out,
                    ..Default::default()
                })?;
            print!("{}", summary.text);
            Ok(())
        }
        Command::Traverse {
            file,
            orbit,
            size,
            threshold,
            json,
        } => {
            anyhow::ensure!(
                threshold.is_finite() && threshold >= 0.0,
                "threshold must be a non-negative number"
            );
            let hierarchy = farfield_client::local::load_file(&file)?;
            let camera = orbit.resolve(&hierarchy.header, size.0, size.1);
            let started = Instant::now();
            let cut = traverse(
                &hierarchy,
                &camera,
                &TraverseOptions {
                    threshold_px: threshold,
                    ..Default::default()
                },
            );
            let ms = started.elapsed().as_secs_f64() * 1e3;
            if json {
                let j = serde_json::json!({
                    "splats": cut.splats.len(), "visited": cut.visited, "frustum_culled": cut.frustum_culled,
                    "backface_culled": cut.backface_culled, "traverse_ms": ms,
                });
                println!("{j}");
            } else {
                println!(
                    "{}: {} splats from {} nodes visited ({} frustum-culled, {} backface-culled) in {ms:.2} ms",
                    file.display(),
                    cut.splats.len(),
                    cut.visited,
                    cut.frustum_culled,
                    cut.backface_culled
                );
            }
            Ok(())
        }
    }
}

/// The demo builds its scene in-process: large build arrays on huge pages,
/// as in `farfield-server` (see [`farfield_server::allocator`]).
#[global_allocator]
static ALLOCATOR: farfield_server::allocator::HugePageAlloc =
    farfield_server::allocator::HugePageAlloc;

fn main() -> ExitCode {
    // SAFETY: first thing in `main`, before any thread is started.
    unsafe { farfield_client::render::quiet_device_select_when_headless() };
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::from_default_env())
        .with_writer(std::io::stderr)
        .init();
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            // `farfield compare` on images of different sizes.
            let compare = e.downcast_ref::<farfield_client::eval::CompareError>();
            if compare.is_some_and(|c| c.is_size_mismatch()) {
                return ExitCode::from(2);
            }
            ExitCode::FAILURE
        }
    }
}
