//! `farfield report DIR... --out DIR`: one HTML page from bench folders.
//!
//! The tables of every folder are merged (so modes measured in separate
//! runs share the plots), the plots redrawn over all of them, and the page
//! says where they were measured (CPU, cores, wgpu adapter) and places the
//! papers' own figures beside ours, labelled as measured on their
//! 1995-2000 hardware.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context;

use super::BenchMeta;
use super::plots::{self, QSPLAT_FIGURE_1};
use super::rows::{self, ProgressRow, Row};

/// The CPU model, from `/proc/cpuinfo` where there is one.
pub fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_owned())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_owned())
}

/// The 1996 color-cube paper's Table 2 speedups (Onyx RealityEngine2).
const CUBES_TABLE_2: [(f64, f64, f64); 4] = [
    (1.75, 0.4, 0.5),
    (3.5, 0.5, 4.6),
    (7.0, 1.3, 25.9),
    (14.0, 5.4, 136.3),
];

/// Reads bench folders (`bench.csv`) and load-test folders
/// (`loadtest.json`) and writes `index.html` and the plots into `out`.
/// Returns the page's path.
pub fn write_report(dirs: &[PathBuf], out: &Path) -> anyhow::Result<PathBuf> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let (mut benches, mut loads) = (Vec::new(), Vec::new());
    for d in dirs {
        if d.join("bench.csv").exists() {
            benches.push(d.clone());
        } else if d.join(crate::loadtest::output::SUMMARY).exists() {
            loads.push(d.clone());
        } else {
            anyhow::bail!(
                "{} has neither bench.csv nor {} (run farfield bench --out {} or farfield loadtest --out {} first)",
                d.display(),
                crate::loadtest::output::SUMMARY,
                d.display(),
                d.display()
            );
        }
    }
    let mut html = String::new();
    html.push_str("<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>farfield: measurements</title>\n<style>body{font-family:sans-serif;max-width:1000px;margin:2em auto}table{border-collapse:collapse;font-size:13px}td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}th{background:#eee}.paper{background:#fff8e0}</style></head><body>\n");
    if !benches.is_empty() {
        bench_sections(&benches, out, &mut html)?;
    }
    for (i, d) in loads.iter().enumerate() {
        crate::loadtest::output::html_section(d, out, i, &mut html)?;
    }
    html.push_str("</body></html>\n");
    let page = out.join("index.html");
    std::fs::write(&page, html).with_context(|| format!("writing {}", page.display()))?;
    Ok(page)
}

/// Escapes text for HTML.
pub fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The bench folders' part of the page: plots, every row, the papers'
/// figures.
fn bench_sections(dirs: &[PathBuf], out: &Path, html: &mut String) -> anyhow::Result<()> {
    let (mut all_rows, mut all_progress, mut metas) =
        (Vec::<Row>::new(), Vec::<ProgressRow>::new(), Vec::new());
    for d in dirs {
        let bench = d.join("bench.csv");
        anyhow::ensure!(
            bench.exists(),
            "{} has no bench.csv (run farfield bench --out {} first)",
            d.display(),
            d.display()
        );
        all_rows.extend(rows::read::<Row>(&bench)?);
        all_progress.extend(rows::read::<ProgressRow>(&d.join("progress.csv"))?);
        let meta = d.join("meta.json");
        if meta.exists() {
            let text = std::fs::read_to_string(&meta)?;
            metas.push(
                serde_json::from_str::<BenchMeta>(&text)
                    .with_context(|| format!("{}", meta.display()))?,
            );
        }
    }
    let plotted = plots::write_all(out, &all_rows, &all_progress)?;
    html.push_str("<h1>Error against run time</h1>\n");
    html.push_str("<h2>Where this was measured</h2>\n<ul>\n");
    let _ = writeln!(
        html,
        "<li>CPU: {} ({} cores)</li>",
        esc(&cpu_model()),
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    for m in &metas {
        let fixed = if m.fixed.is_empty() {
            "defaults".to_owned()
        } else {
            let pairs: Vec<String> = m.fixed.iter().map(|(k, v)| format!("{k}={v}")).collect();
            pairs.join(", ")
        };
        let _ = writeln!(
            html,
            "<li>{} mode {} sweeping {} = {} with {}, {}x{}, {} repeats, {} cameras, reference: {}; adapter: {}; CPU {} ({} cores)</li>",
            esc(&m.scene),
            esc(&m.mode),
            esc(&m.param),
            esc(&m.values.join(", ")),
            esc(&fixed),
            m.width,
            m.height,
            m.repeats,
            m.cameras,
            esc(&m.reference),
            esc(&m.adapter),
            esc(&m.cpu),
            m.cores
        );
    }
    html.push_str("</ul>\n<p>Times are medians of repeats taken in one run; the tables give their spread. Compare ratios, not milliseconds, across machines.</p>\n");
    for (file, title) in plotted {
        let _ = writeln!(
            html,
            "<h2>{}</h2>\n<img src=\"{file}\" alt=\"{}\">",
            esc(title),
            esc(title)
        );
        let png = file.replace(".svg", ".png");
        let _ = writeln!(html, "<p><a href=\"{png}\">{png}</a></p>");
    }
    html.push_str("<h2>All measurements</h2>\n<table><tr><th>scene</th><th>mode</th><th>setting</th><th>camera</th><th>PSNR dB</th><th>RMSE</th><th>wrong %</th><th>frame ms (min..max)</th><th>traverse</th><th>upload</th><th>draw</th><th>drawn</th><th>bytes</th><th>coverage ε %</th><th>note</th></tr>\n");
    for r in &all_rows {
        let psnr = if r.psnr_db.is_finite() {
            format!("{:.2}", r.psnr_db)
        } else {
            "inf (identical)".into()
        };
        let note = if r.reference_empty {
            "reference empty: nothing in view"
        } else {
            ""
        };
        let coverage = r
            .coverage
            .map_or_else(String::new, |c| format!("{:.1}", c * 100.0));
        let _ = writeln!(
            html,
            "<tr><td>{}</td><td>{}</td><td>{}={}</td><td>{}</td><td>{psnr}</td><td>{:.3}</td><td>{:.2}</td><td>{:.2} ({:.2}..{:.2})</td><td>{:.2}</td><td>{:.2}</td><td>{:.2}</td><td>{}</td><td>{}</td><td>{coverage}</td><td>{note}</td></tr>",
            esc(&r.scene),
            esc(&r.mode),
            esc(&r.param),
            esc(&r.value),
            r.camera,
            r.rmse,
            r.wrong_fraction * 100.0,
            r.frame_ms,
            r.frame_ms_min,
            r.frame_ms_max,
            r.traverse_ms,
            r.upload_ms,
            r.draw_ms,
            r.drawn,
            r.bytes
        );
    }
    html.push_str(
        "</table>\n<h2>The papers' own figures (measured on their 1995-2000 hardware)</h2>\n",
    );
    html.push_str("<h3 class=\"paper\">QSplat, Figure 1: St. Matthew, 127 million samples, 1280x1024, SGI Onyx2 InfiniteReality (2000)</h3>\n<table class=\"paper\"><tr><th>cutoff px</th><th>points drawn</th><th>ms</th></tr>\n");
    for (c, p, ms) in QSPLAT_FIGURE_1 {
        let _ = writeln!(html, "<tr><td>{c}</td><td>{p}</td><td>{ms}</td></tr>");
    }
    html.push_str("</table>\n<h3 class=\"paper\">QSplat, Figure 6: typical rendering, 1280x1024, SGI Onyx2 (2000)</h3>\n<table class=\"paper\"><tr><th>model</th><th>interactive ms</th><th>points</th><th>static ms</th><th>points</th></tr>\n<tr><td>2.0 M points</td><td>120</td><td>125,183</td><td>838</td><td>931,093</td></tr>\n<tr><td>4.3 M points</td><td>109</td><td>267,542</td><td>1051</td><td>2,026,496</td></tr>\n<tr><td>St. Matthew, 127 M points</td><td>110</td><td>263,915</td><td>3149</td><td>8,110,665</td></tr>\n</table>\n");
    html.push_str("<h3 class=\"paper\">Color-cube hierarchy (1996), Table 2: speedup of the hierarchy over geometry, 124x124, SGI Onyx RealityEngine2</h3>\n<table class=\"paper\"><tr><th>distance (radii)</th><th>tree (52,470 triangles)</th><th>molecule (5.2 M triangles)</th></tr>\n");
    for (d, tree, molecule) in CUBES_TABLE_2 {
        let _ = writeln!(
            html,
            "<tr><td>{d}</td><td>{tree}</td><td>{molecule}</td></tr>"
        );
    }
    html.push_str("</table>\n<p>Ours, on this project's scenes: docs/experiments.md and <code>farfield bench-cubes</code>.</p>\n");
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_report_from_a_tiny_bench_has_every_plot_it_names() {
        let dir = std::env::temp_dir().join(format!("ff-report-{}", std::process::id()));
        let (bench, out) = (dir.join("bench"), dir.join("report"));
        std::fs::create_dir_all(&bench).unwrap();
        let row = |value: &str, ms: f64, psnr: f64, empty: bool| Row {
            scene: "tiny".into(),
            mode: "spheres".into(),
            param: "threshold".into(),
            value: value.into(),
            camera: 0,
            rmse: 1.0,
            psnr_db: psnr,
            wrong_fraction: 0.01,
            frame_ms: ms,
            frame_ms_min: ms,
            frame_ms_max: ms,
            traverse_ms: 1.0,
            upload_ms: 1.0,
            draw_ms: 1.0,
            drawn: 10,
            bytes: 1000,
            reference: "spheres at 1 px".into(),
            reference_empty: empty,
            width: 8,
            height: 8,
            repeats: 1,
            coverage: None,
        };
        let rows = vec![
            row("1", 20.0, f64::INFINITY, false),
            row("4", 5.0, 31.0, false),
            row("8", 3.0, 20.0, true),
        ];
        rows::write(&bench.join("bench.csv"), &rows).unwrap();
        let progress = vec![ProgressRow {
            mode: "spheres".into(),
            param: "threshold".into(),
            value: "1".into(),
            camera: 0,
            frame: 0,
            ms_since_connect: 12.0,
            bytes: 500,
            rmse: 3.0,
            psnr_db: 38.0,
            wrong_fraction: 0.02,
            coverage: None,
        }];
        rows::write(&bench.join("progress.csv"), &progress).unwrap();
        let page = write_report(std::slice::from_ref(&bench), &out).unwrap();
        let html = std::fs::read_to_string(&page).unwrap();
        for (file, title) in plots::ALL {
            assert!(
                html.contains(&format!("src=\"{file}\"")),
                "{file} not in the page"
            );
            assert!(html.contains(title));
            let svg = std::fs::read_to_string(out.join(file)).unwrap();
            assert!(
                svg.starts_with("<svg") && svg.contains("</svg>") && svg.contains("<polyline"),
                "{file}: {}",
                &svg[..svg.len().min(200)]
            );
        }
        assert!(html.contains("inf (identical)") && html.contains("reference empty"));
        // Every plot also as a PNG, linked from the page.
        for (file, _) in plots::ALL {
            let png = file.replace(".svg", ".png");
            assert!(
                html.contains(&format!("href=\"{png}\"")),
                "{png} not linked"
            );
            let (w, h, rgba) = farfield_image::read_png(out.join(&png)).unwrap();
            assert_eq!((w, h), (760, 480));
            let dark = rgba.chunks_exact(4).filter(|p| p[0] < 128).count();
            assert!(
                dark > 500,
                "{png}: hardly anything drawn ({dark} dark pixels)"
            );
        }
        assert!(html.contains("QSplat, Figure 1") && html.contains("8308"));
        // A folder without a bench is a clear error.
        let e = write_report(&[dir.join("nothing")], &out).unwrap_err();
        assert!(
            e.to_string()
                .contains("neither bench.csv nor loadtest.json"),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
