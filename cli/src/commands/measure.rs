//! The measuring subcommands, whose work is in `farfield-tools`:
//! `bench`, `report`, `bench-cubes`, `bench-plp`, `bench-stream` and `loadtest`.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::Context;
use farfield_client::path::CameraPath;
use farfield_render::Renderer;
use farfield_tools::bench::BenchJob;
use farfield_tools::bench_cubes::{CubeBenchJob, format_table};
use farfield_tools::bench_stream::{BenchStreamJob, default_job, describe, run_bench};

use crate::cli::{BenchArgs, BenchCubesArgs, BenchPlpArgs};

/// `farfield bench`: error against run time over a swept parameter.
pub fn bench(args: BenchArgs) -> anyhow::Result<()> {
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
    let job = BenchJob {
        source,
        path: args.path.as_deref().map(CameraPath::load).transpose()?,
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
    let (rows, progress) = farfield_tools::bench::run(&job, &mut renderer)?;
    println!(
        "{}: {} rows, {} progress frames; bench.csv, progress.csv, meta.json and plots written",
        job.out.display(),
        rows.len(),
        progress.len()
    );
    Ok(())
}

/// `farfield report`: one HTML page from bench folders.
pub fn report(dirs: &[PathBuf], out: &Path) -> anyhow::Result<()> {
    let page = farfield_tools::bench::report::write_report(dirs, out)?;
    println!("{}", page.display());
    Ok(())
}

/// `farfield bench-cubes`: the color-cube paper's Table 2.
pub fn bench_cubes(args: BenchCubesArgs) -> anyhow::Result<()> {
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
    let report = farfield_tools::bench_cubes::run(&job, &mut renderer)?;
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print!("{}", format_table(&report));
    }
    Ok(())
}

/// `farfield bench-plp`: PLP's Table 1 and per-frame curves.
pub fn bench_plp(args: BenchPlpArgs) -> anyhow::Result<()> {
    use farfield_tools::bench_plp::{
        PaperRow, PlpBenchJob, format_table, frames_csv, write_figures,
    };
    let job = PlpBenchJob {
        file: args.file,
        path: farfield_client::path::CameraPath::load(&args.path)?,
        budgets: args.budgets,
        centroid_budget: args.centroid,
        width: args.size.0,
        height: args.size.1,
        repeats: args.repeats,
        stride: args.stride,
        star_penalty: args.star_penalty,
        solidity: args.solidity,
        paper: match args.paper.as_deref() {
            Some("city") => Some(PaperRow::city()),
            Some("cars") => Some(PaperRow::cars()),
            _ => None,
        },
    };
    let mut renderer =
        Renderer::new_headless(job.width, job.height).context("starting the renderer")?;
    let report = farfield_tools::bench_plp::run(&job, &mut renderer)?;
    let table = format_table(&report);
    if let Some(out) = &args.out {
        std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
        std::fs::write(out.join("frames.csv"), frames_csv(&report))?;
        std::fs::write(out.join("table.md"), &table)?;
        std::fs::write(
            out.join("report.json"),
            serde_json::to_string_pretty(&report)?,
        )?;
        write_figures(&report, out)?;
    }
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print!("{table}");
    }
    Ok(())
}

/// `farfield bench-stream`: the memory server on loopback.
pub fn bench_stream(
    scene: &Path,
    clients: Vec<usize>,
    seconds: f64,
    cache_mib: u64,
    repeats: usize,
    json: bool,
) -> anyhow::Result<()> {
    anyhow::ensure!(
        seconds.is_finite() && seconds > 0.0,
        "--seconds must be positive"
    );
    let job = BenchStreamJob {
        clients,
        seconds,
        cache_bytes: cache_mib.max(1) << 20,
        repeats,
        ..default_job(scene)
    };
    let report = run_bench(&job)?;
    if json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print!("{}", describe(&report));
    }
    Ok(())
}

/// `farfield loadtest`: many headless clients against one server.
pub fn loadtest(args: crate::cli::LoadtestArgs) -> anyhow::Result<()> {
    let seconds = |name: &str, s: f64| {
        std::time::Duration::try_from_secs_f64(s)
            .map_err(|_| anyhow::anyhow!("--{name} must be a number of seconds, at least 0"))
    };
    let job = farfield_tools::loadtest::LoadJob {
        ramp: seconds("ramp", args.ramp)?,
        path: args.path,
        width: args.size.0,
        height: args.size.1,
        threshold_px: args.threshold,
        fps: args.fps,
        client_cache_bytes: args.client_cache_mib.max(1) << 20,
        token: args.token,
        session: args.session,
        push: args.push,
        static_files: args.static_files,
        max_outstanding: args.max_outstanding.map(|n| n as usize),
        ..farfield_tools::loadtest::LoadJob::new(
            &args.server,
            &args.scene,
            args.clients,
            seconds("duration", args.duration)?,
            args.out,
        )
    };
    let report = farfield_tools::loadtest::run(&job)?;
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print!("{}", farfield_tools::loadtest::describe(&report));
        println!("wrote {}", job.out.join("index.html").display());
    }
    Ok(())
}
