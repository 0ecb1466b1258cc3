//! A load test's files: `seconds.csv` (a row a second), `clients.csv` (a
//! row a client), `loadtest.json` (the summary), the plots (SVG), and its
//! section of the HTML report (`farfield report`, which the load test
//! runs on its own folder).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use anyhow::Context;

use super::client::ClientRow;
use super::{LoadReport, SecondRow};
use crate::bench::plots::write_line_chart;
use crate::bench::report::esc;
use crate::bench::rows;

/// The summary's file name; a folder holding it is a load test's.
pub const SUMMARY: &str = "loadtest.json";
pub const SECONDS: &str = "seconds.csv";
pub const CLIENTS: &str = "clients.csv";

/// Writes every file of a run, the HTML page last.
pub fn write_all(
    dir: &Path,
    report: &LoadReport,
    seconds: &[SecondRow],
    clients: &[ClientRow],
) -> anyhow::Result<()> {
    rows::write(&dir.join(SECONDS), seconds)?;
    rows::write(&dir.join(CLIENTS), clients)?;
    let json = serde_json::to_string_pretty(report)?;
    let summary = dir.join(SUMMARY);
    std::fs::write(&summary, json).with_context(|| format!("writing {}", summary.display()))?;
    crate::bench::report::write_report(&[dir.to_owned()], dir)?;
    Ok(())
}

/// One series of `seconds.csv` against time, skipping seconds without a value.
fn series(seconds: &[SecondRow], f: impl Fn(&SecondRow) -> Option<f64>) -> Vec<(f64, f64)> {
    seconds
        .iter()
        .filter_map(|r| Some((r.t_s, f(r)?)))
        .filter(|(_, v)| v.is_finite())
        .collect()
}

/// The plots of one run, named with `prefix`; returns (file, title).
fn write_plots(
    seconds: &[SecondRow],
    out: &Path,
    prefix: &str,
) -> anyhow::Result<Vec<(String, &'static str)>> {
    type Pick = fn(&SecondRow) -> Option<f64>;
    /// File name, title, y axis, and the lines: label and value.
    type Chart<'a> = (&'a str, &'static str, &'a str, &'a [(&'a str, Pick)]);
    let charts: [Chart; 4] = [
        (
            "latency",
            "Request latency (request to page arrival)",
            "latency, ms",
            &[
                ("p50", |r| r.latency_p50_ms),
                ("p95", |r| r.latency_p95_ms),
                ("p99", |r| r.latency_p99_ms),
                ("max", |r| r.latency_max_ms),
            ],
        ),
        (
            "throughput",
            "Throughput",
            "pages/s, MB/s",
            &[
                ("pages/s", |r| Some(r.pages_per_s)),
                ("MB/s", |r| Some(r.mb_per_s)),
            ],
        ),
        (
            "server",
            "The server over the run",
            "MiB, pages",
            &[
                ("resident MiB", |r| r.server_resident_mib),
                ("queue depth", |r| r.server_queue_depth),
                ("disk reads", |r| r.server_disk_reads),
            ],
        ),
        (
            "clients",
            "Clients connected, errors and reconnects",
            "count",
            &[
                ("connected", |r| Some(r.clients_connected as f64)),
                ("server's count", |r| r.server_connections),
                ("errors", |r| Some(r.errors as f64)),
                ("reconnects", |r| Some(r.reconnects as f64)),
            ],
        ),
    ];
    let mut written = Vec::new();
    for (name, title, y, picks) in charts {
        let mut lines = BTreeMap::new();
        for (label, pick) in picks {
            let s = series(seconds, pick);
            if !s.is_empty() {
                lines.insert((*label).to_owned(), s);
            }
        }
        if lines.is_empty() {
            continue;
        }
        let file = format!("{prefix}{name}.svg");
        write_line_chart(&out.join(&file), title, "seconds since start", y, &lines)?;
        written.push((file, title));
    }
    Ok(written)
}

/// Appends load test `dir`'s section to a report page in `out`: its
/// summary, its plots (drawn into `out`), and its clients.
pub fn html_section(dir: &Path, out: &Path, index: usize, html: &mut String) -> anyhow::Result<()> {
    let summary = dir.join(SUMMARY);
    let text =
        std::fs::read_to_string(&summary).with_context(|| format!("{}", summary.display()))?;
    let r: LoadReport =
        serde_json::from_str(&text).with_context(|| format!("{}", summary.display()))?;
    let seconds: Vec<SecondRow> = rows::read(&dir.join(SECONDS))?;
    let clients: Vec<ClientRow> = rows::read(&dir.join(CLIENTS))?;
    let ms = |v: Option<f64>| v.map_or("-".into(), |v| format!("{v:.1}"));
    let _ = writeln!(
        html,
        "<h1>Load test: {} clients, {} on {}</h1>\n<ul>\n<li>{:.0} s (ramp {:.0} s), path {}; CPU {} ({} cores)</li>",
        r.clients,
        esc(&r.scene),
        esc(&r.server),
        r.seconds,
        r.ramp_s,
        esc(&r.path),
        esc(&r.cpu),
        r.cores,
    );
    for line in super::describe(&r).lines() {
        let _ = writeln!(html, "<li>{}</li>", esc(line));
    }
    html.push_str("</ul>\n");
    for (file, title) in write_plots(&seconds, out, &format!("load{index}-"))? {
        let _ = writeln!(
            html,
            "<h2>{title}</h2>\n<img src=\"{file}\" alt=\"{title}\">"
        );
    }
    html.push_str("<h2>Clients</h2>\n<table><tr><th>client</th><th>started s</th><th>first image ms</th><th>refined ms</th><th>pages</th><th>bytes</th><th>errors</th><th>reconnects</th><th>restarts</th><th>last error</th></tr>\n");
    for c in &clients {
        let _ = writeln!(
            html,
            "<tr><td>{}</td><td>{:.1}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            c.client,
            c.started_s,
            ms(c.first_image_ms),
            ms(c.refined_ms),
            c.pages,
            c.bytes,
            c.errors,
            c.reconnects,
            c.restarts,
            esc(&c.last_error)
        );
    }
    html.push_str("</table>\n");
    Ok(())
}
