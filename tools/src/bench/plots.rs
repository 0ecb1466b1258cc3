//! The bench's plots, SVG, drawn with plotters.
//!
//! - [`FRONTIER`]: error (PSNR) against frame time, one curve per mode:
//!   the trade-off frontier.
//! - [`BYTES`]: error against bytes received.
//! - [`PROGRESS`]: error against time since connect while a streamed view
//!   refines, one curve per mode and setting (first camera).
//! - [`THRESHOLD`]: frame time by splat threshold next to QSplat's
//!   Figure 1 (St. Matthew on an SGI Onyx2, 2000).
//! - [`COVERAGE_BYTES`] and [`COVERAGE_TIME`], only when the kind draws
//!   triangles (PLP, its centroid baseline): the visible coverage ratio
//!   against bytes received and against time since connect while a
//!   streamed view refines, one curve per mode and setting (first camera).
//!
//! Each is written as `NAME.svg` and `NAME.png`.
//!
//! Each point of the first two is a setting: the median frame time (or
//! bytes) over the cameras and the mean PSNR over the cameras whose
//! reference is not empty. Identical images have infinite PSNR; they are
//! drawn at [`PSNR_CAP`] and the axis says so.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::anyhow;
use plotters::coord::Shift;
use plotters::prelude::*;

use super::median;
use super::rows::{ProgressRow, Row};

/// Where an infinite PSNR (identical images) is drawn.
pub const PSNR_CAP: f64 = 60.0;

pub const FRONTIER: &str = "frontier.svg";
pub const BYTES: &str = "bytes.svg";
pub const PROGRESS: &str = "progress.svg";
pub const THRESHOLD: &str = "threshold.svg";
pub const COVERAGE_BYTES: &str = "coverage_bytes.svg";
pub const COVERAGE_TIME: &str = "coverage_time.svg";
/// The plots of triangle kinds, written when some progress row has a
/// coverage.
pub const COVERAGE: [(&str, &str); 2] = [
    (
        COVERAGE_BYTES,
        "Visible coverage against bytes received (streamed)",
    ),
    (
        COVERAGE_TIME,
        "Visible coverage against time since connect (streamed)",
    ),
];
/// Every plot [`write_all`] writes, with its title.
pub const ALL: [(&str, &str); 4] = [
    (
        FRONTIER,
        "Error against frame time (the trade-off frontier)",
    ),
    (BYTES, "Error against bytes received"),
    (
        PROGRESS,
        "Error against time since connect (progressive streaming)",
    ),
    (
        THRESHOLD,
        "Frame time by splat threshold, beside QSplat's Figure 1",
    ),
];

/// QSplat's Figure 1: (cutoff px, points drawn, ms) for St. Matthew at
/// 1280 x 1024 on an SGI Onyx2 with InfiniteReality graphics (2000).
pub const QSPLAT_FIGURE_1: [(f64, u64, f64); 4] = [
    (15.0, 130_712, 132.0),
    (10.0, 259_975, 215.0),
    (5.0, 1_017_149, 722.0),
    (1.0, 14_835_967, 8308.0),
];

fn capped(psnr: f64) -> f64 {
    if psnr.is_finite() {
        psnr.min(PSNR_CAP)
    } else {
        PSNR_CAP
    }
}

/// (mode, value) -> (median of `x`, mean capped PSNR), per mode sorted by x.
fn per_setting(rows: &[Row], x: impl Fn(&Row) -> f64) -> BTreeMap<String, Vec<(f64, f64)>> {
    let mut groups: BTreeMap<(String, String), Vec<&Row>> = BTreeMap::new();
    for r in rows.iter().filter(|r| !r.reference_empty) {
        groups
            .entry((r.mode.clone(), r.value.clone()))
            .or_default()
            .push(r);
    }
    let mut out: BTreeMap<String, Vec<(f64, f64)>> = BTreeMap::new();
    for ((mode, _), g) in groups {
        let xs: Vec<f64> = g.iter().map(|r| x(r)).collect();
        let y = g.iter().map(|r| capped(r.psnr_db)).sum::<f64>() / g.len() as f64;
        out.entry(mode).or_default().push((median(&xs), y));
    }
    for pts in out.values_mut() {
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    out
}

/// Draws `series` (name -> points) as lines with dots and a legend on a
/// chart built by `$chart` (a `build_cartesian_2d` result), with axis
/// descriptions; errors go through `$err`.
macro_rules! draw_lines {
    ($chart:expr, $x_desc:expr, $y_desc:expr, $series:expr, $err:expr) => {{
        let err = $err;
        let mut chart = $chart.map_err(|e| err(&e))?;
        chart
            .configure_mesh()
            .x_desc($x_desc)
            .y_desc($y_desc)
            .draw()
            .map_err(|e| err(&e))?;
        for (i, (name, pts)) in $series.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            chart
                .draw_series(LineSeries::new(pts.iter().copied(), color.stroke_width(2)))
                .map_err(|e| err(&e))?
                .label(name.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
            chart
                .draw_series(pts.iter().map(|p| Circle::new(*p, 3, color.filled())))
                .map_err(|e| err(&e))?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(|e| err(&e))?;
    }};
}

/// One chart of named series; `log_x` for times and bytes.
fn chart<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    x_desc: &str,
    y_desc: &str,
    series: &BTreeMap<String, Vec<(f64, f64)>>,
    log_x: bool,
) -> anyhow::Result<()> {
    let points: Vec<(f64, f64)> = series.values().flatten().copied().collect();
    let (mut x0, mut x1) = points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p.0), b.max(p.0))
        });
    let (mut y0, mut y1) = points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p.1), b.max(p.1))
        });
    if !(x0.is_finite() && x1.is_finite()) {
        (x0, x1, y0, y1) = (1.0, 10.0, 0.0, PSNR_CAP);
    }
    if log_x {
        x0 = (x0 * 0.8).max(1e-3);
        x1 = (x1 * 1.25).max(x0 * 10.0);
    } else {
        let pad = ((x1 - x0) * 0.05).max(1e-3 * x1.abs().max(1.0));
        (x0, x1) = (x0 - pad, x1 + pad);
    }
    let (y0, y1) = ((y0 - 2.0).floor(), (y1 + 2.0).ceil().max(y0 + 5.0));
    let err = |e: &dyn std::fmt::Display| anyhow!("plotting {title}: {e}");
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut builder = ChartBuilder::on(root);
    builder
        .caption(title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(42)
        .y_label_area_size(56);
    if log_x {
        draw_lines!(
            builder.build_cartesian_2d((x0..x1).log_scale(), y0..y1),
            x_desc,
            y_desc,
            series,
            err
        );
    } else {
        draw_lines!(
            builder.build_cartesian_2d(x0..x1, y0..y1),
            x_desc,
            y_desc,
            series,
            err
        );
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// Plot size in pixels.
const SIZE: (u32, u32) = (760, 480);

/// One chart of named series written as an SVG file (the other benches'
/// figures: PLP's per-frame curves).
pub fn write_line_chart(
    path: &Path,
    title: &str,
    x_desc: &str,
    y_desc: &str,
    series: &BTreeMap<String, Vec<(f64, f64)>>,
) -> anyhow::Result<()> {
    label_font()?;
    let root = SVGBackend::new(path, SIZE).into_drawing_area();
    chart(&root, title, x_desc, y_desc, series, false)
}

/// Writes every plot of [`ALL`] into `dir`, as SVG and as PNG, and those
/// of [`COVERAGE`] when there is a coverage to plot; returns the plots
/// written, with their titles.
pub fn write_all(
    dir: &Path,
    rows: &[Row],
    progress: &[ProgressRow],
) -> anyhow::Result<Vec<(&'static str, &'static str)>> {
    label_font()?;
    let psnr = format!("PSNR, dB (identical images drawn at {PSNR_CAP})");
    let frontier = per_setting(rows, |r| r.frame_ms);
    let bytes = per_setting(rows, |r| (r.bytes as f64).max(1.0));
    let mut streams: BTreeMap<String, Vec<(f64, f64)>> = BTreeMap::new();
    for p in progress.iter().filter(|p| p.camera == 0) {
        streams
            .entry(format!("{} {}={}", p.mode, p.param, p.value))
            .or_default()
            .push((p.ms_since_connect, capped(p.psnr_db)));
    }
    let (mut by_bytes, mut by_time) = (BTreeMap::new(), BTreeMap::new());
    for p in progress.iter().filter(|p| p.camera == 0) {
        let Some(c) = p.coverage else { continue };
        let name = format!("{} {}={}", p.mode, p.param, p.value);
        let percent = c * 100.0;
        by_bytes
            .entry(name.clone())
            .or_insert_with(Vec::new)
            .push((p.bytes as f64 / 1e6, percent));
        by_time
            .entry(name)
            .or_insert_with(Vec::new)
            .push((p.ms_since_connect, percent));
    }
    let coverage = "visible coverage ε, % of the visible triangles drawn";
    // Frame time by threshold: ours and QSplat's Figure 1.
    let mut ours: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    for r in rows
        .iter()
        .filter(|r| r.param == "threshold" || r.param == "eps")
    {
        ours.entry(r.value.clone()).or_default().push(r.frame_ms);
    }
    let mut pts: Vec<(f64, f64)> = ours
        .iter()
        .filter_map(|(v, t)| Some((v.parse::<f64>().ok()?.max(0.01), median(t))))
        .collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut by_threshold: BTreeMap<String, Vec<(f64, f64)>> = BTreeMap::new();
    by_threshold.insert("farfield (this run)".into(), pts);
    by_threshold.insert(
        "QSplat Figure 1 (SGI Onyx2, 2000)".into(),
        QSPLAT_FIGURE_1.iter().map(|&(c, _, ms)| (c, ms)).collect(),
    );
    macro_rules! draw {
        ($root:expr, $name:expr) => {
            match $name {
                FRONTIER => chart(
                    $root,
                    ALL[0].1,
                    "frame time, ms (median over repeats and cameras)",
                    &psnr,
                    &frontier,
                    true,
                )?,
                BYTES => chart(
                    $root,
                    ALL[1].1,
                    "bytes received (or touched, from a file)",
                    &psnr,
                    &bytes,
                    true,
                )?,
                PROGRESS => chart(
                    $root,
                    ALL[2].1,
                    "time since connect, ms",
                    &psnr,
                    &streams,
                    false,
                )?,
                COVERAGE_BYTES => chart(
                    $root,
                    COVERAGE[0].1,
                    "MB received (10^6 bytes)",
                    coverage,
                    &by_bytes,
                    false,
                )?,
                COVERAGE_TIME => chart(
                    $root,
                    COVERAGE[1].1,
                    "time since connect, ms",
                    coverage,
                    &by_time,
                    false,
                )?,
                _ => threshold_chart($root, &by_threshold)?,
            }
        };
    }
    let mut written = ALL.to_vec();
    if !by_bytes.is_empty() {
        written.extend(COVERAGE);
    }
    for &(name, _) in &written {
        let path = dir.join(name);
        let root = SVGBackend::new(&path, SIZE).into_drawing_area();
        draw!(&root, name);
    }
    for &(name, _) in &written {
        let mut rgb = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
        {
            let root = BitMapBackend::with_buffer(&mut rgb, SIZE).into_drawing_area();
            draw!(&root, name);
        }
        let rgba: Vec<u8> = rgb
            .chunks_exact(3)
            .flat_map(|p| [p[0], p[1], p[2], 255])
            .collect();
        let png = dir.join(name.replace(".svg", ".png"));
        farfield_image::write_png(&png, SIZE.0, SIZE.1, &rgba)?;
    }
    Ok(written)
}

/// DejaVu Sans (Bitstream Vera license, `tools/assets/`), for the
/// labels: plotters measures text with it for SVG and rasterizes it for
/// PNG, so the plots look the same on every machine.
static LABEL_FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");

/// Registers the label font with plotters, once.
fn label_font() -> anyhow::Result<()> {
    static REGISTERED: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font("sans-serif", FontStyle::Normal, LABEL_FONT).is_ok()
    });
    anyhow::ensure!(ok, "the embedded label font did not load");
    Ok(())
}

/// Frame time (log y) against the threshold (log x).
fn threshold_chart<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    series: &BTreeMap<String, Vec<(f64, f64)>>,
) -> anyhow::Result<()> {
    let pts: Vec<(f64, f64)> = series.values().flatten().copied().collect();
    let x1 = pts.iter().map(|p| p.0).fold(32.0, f64::max) * 1.3;
    let y0 = pts
        .iter()
        .map(|p| p.1)
        .fold(f64::INFINITY, f64::min)
        .max(1e-3)
        * 0.7;
    let y1 = pts.iter().map(|p| p.1).fold(10.0, f64::max) * 1.5;
    let err = |e: &dyn std::fmt::Display| anyhow!("plotting {}: {e}", ALL[3].1);
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let chart = ChartBuilder::on(root)
        .caption(ALL[3].1, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(42)
        .y_label_area_size(56)
        .build_cartesian_2d((0.7..x1).log_scale(), (y0..y1).log_scale());
    draw_lines!(
        chart,
        "threshold (spheres) or eps (cubes), pixels",
        "frame time, ms",
        series,
        err
    );
    root.present().map_err(|e| err(&e))?;
    Ok(())
}
