//! Image caching in the tools: `farfield render --path P --mode impostors
//! --epsilon-px 2` beside `--mode culling` (its baseline) from the command
//! line, and `bench --mode impostors --sweep epsilon=1,2,4,8` beside the
//! culling bench, on one report.

use std::time::Duration;

use clap::Parser;
use farfield_cli::cli::{Cli, run};
use farfield_client::render_job::Source;
use farfield_render::headless_or_skip;
use farfield_store::write_atomic;
use farfield_tests::scratch;
use farfield_tools::bench::{BenchJob, report};

use crate::impostors::island_file;

/// The island's generator parameters in `island_file`.
const ISLAND: [&str; 3] = ["trees=24", "size=49", "tree_triangles=1000"];

fn cli(args: &[&str]) -> anyhow::Result<()> {
    run(Cli::try_parse_from(
        std::iter::once("farfield").chain(args.iter().copied()),
    )?)
}

/// frames.csv's column `name`, summed.
fn column_sum(csv: &str, name: &str) -> u64 {
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().expect("a header").split(',').collect();
    let at = header.iter().position(|h| *h == name).expect("the column");
    lines
        .map(|l| {
            l.split(',')
                .nth(at)
                .expect("a value")
                .parse::<u64>()
                .expect("a count")
        })
        .sum()
}

#[test]
fn render_flies_the_islands_path_with_caches_and_with_culling() {
    if headless_or_skip(16, 16).unwrap().is_none() {
        return;
    }
    let dir = scratch("impostor-cli");
    let file = dir.join("island.ff");
    write_atomic(&file, &island_file()).unwrap();
    let path = dir.join("island-path.json");
    let mut args = vec!["path", "gen:island", "--out", path.to_str().unwrap()];
    for p in ISLAND {
        args.extend(["--param", p]);
    }
    cli(&args).expect("farfield path");
    let fly = |mode: &str, out: &str, extra: &[&str]| {
        let out = dir.join(out);
        let mut args = vec![
            "render",
            "--file",
            file.to_str().unwrap(),
            "--path",
            path.to_str().unwrap(),
            // 1200 frames at 30 fps over 40 s; 3 a second is 121 of them.
            "--fps",
            "3",
            "--size",
            "160x120",
            "--mode",
            mode,
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend(extra);
        cli(&args).unwrap_or_else(|e| panic!("render --mode {mode}: {e:#}"));
        std::fs::read_to_string(out.join("frames.csv")).expect("frames.csv")
    };
    let cached = fly(
        "impostors",
        "cached",
        &["--epsilon-px", "2", "--known-path"],
    );
    let culled = fly("culling", "culled", &[]);
    let made = column_sum(&cached, "caches_made");
    let drawn = column_sum(&cached, "caches_drawn");
    assert!(made > 0 && drawn > made, "made {made}, drawn {drawn}");
    assert!(column_sum(&cached, "texture_bytes") > 0);
    assert_eq!(column_sum(&culled, "caches_made"), 0);
    assert_eq!(column_sum(&culled, "caches_drawn"), 0);
    assert_eq!(cached.lines().count(), culled.lines().count());
    // A bad ε, and a known path with no path, are refused before anything
    // runs.
    let png = dir.join("refused.png");
    let refused = |extra: &str| {
        let args = [
            "render",
            "--file",
            file.to_str().unwrap(),
            "--out",
            png.to_str().unwrap(),
            extra,
        ];
        let e = cli(&args).expect_err(extra);
        assert!(!png.exists(), "{extra}: {e:#}");
    };
    refused("--epsilon-px=-1");
    refused("--known-path");
}

#[test]
fn bench_sweeps_epsilon_beside_the_culling_baseline() {
    let Some(mut renderer) = headless_or_skip(96, 72).unwrap() else {
        return;
    };
    let dir = scratch("impostor-bench");
    let file = dir.join("island.ff");
    write_atomic(&file, &island_file()).unwrap();
    let job = |mode: &str, param: &str, values: &[&str]| BenchJob {
        source: Source::File(file.clone()),
        path: None,
        mode: mode.into(),
        param: param.into(),
        values: values.iter().map(|v| v.to_string()).collect(),
        fixed: Vec::new(),
        inputs: Vec::new(),
        input_params: Vec::new(),
        width: 96,
        height: 72,
        repeats: 1,
        out: dir.join(mode),
        timeout: Duration::from_secs(60),
    };
    let sweep = job("impostors", "epsilon", &["1", "2", "4", "8"]);
    let (table, _) = farfield_tools::bench::run(&sweep, &mut renderer).unwrap();
    // Four values x three built-in cameras, each against the culling
    // image (ε = 0), close to it.
    assert_eq!(table.len(), 12);
    for r in &table {
        assert!(!r.reference_empty && r.frame_ms > 0.0, "{r:?}");
        assert!(r.psnr_db > 25.0, "{r:?}");
    }
    let baseline = job("culling", "threshold", &["0"]);
    let (culled, _) = farfield_tools::bench::run(&baseline, &mut renderer).unwrap();
    assert_eq!(culled.len(), 3);
    for r in &culled {
        // The culling baseline is the reference's own image.
        assert!(r.psnr_db.is_infinite() && r.wrong_fraction == 0.0, "{r:?}");
    }
    let page = report::write_report(&[sweep.out, baseline.out], &dir.join("report")).unwrap();
    let html = std::fs::read_to_string(page).unwrap();
    assert!(html.contains("impostors") && html.contains("culling"));
}
