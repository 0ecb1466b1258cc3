//! farfield-tools: measuring farfield, apart from the product.
//!
//! Benchmarks, evaluation and reference renders may use every product
//! crate (builder, store, server, client core); no product crate depends
//! on this one, so nothing here can leak into what users run or into the
//! browser build. The binaries (`farfield`, `farfield-server`) expose these
//! as subcommands.
//!
//! - [`bench`](mod@bench): `farfield bench` and `farfield report`: error against run
//!   time for every rendering mode, tables, plots and an HTML page.
//! - [`bench_cubes`]: the color-cube paper's Table 2 (`farfield bench-cubes`).
//! - [`bench_plp`]: PLP's Table 1 and Figures 8 and 9 (`farfield bench-plp`):
//!   visible coverage from item buffers, wrong pixels, frame time.
//! - [`bench_stream`]: the memory server on loopback (`farfield bench-stream`).
//! - [`loadtest`]: many headless clients against one server (`farfield
//!   loadtest`): latency quantiles, throughput, errors, the server's
//!   metrics over time.
//! - `wan` (Linux): an emulated wide-area link between a server's and its
//!   clients' network namespaces (`farfield wan`), where the kernel has no netem.
//! - [`bench_build`]: `farfield-server bench build` and `bench traverse`:
//!   build throughput, traversal rate.
//! - [`reference`](mod@reference): a scene's full geometry, the reference renders are
//!   timed and measured against.
//! - [`meters`]: process memory and CPU time.
//! - [`stats`]: summary statistics (medians).

pub mod bench;
pub mod bench_build;
pub mod bench_codecs;
pub mod bench_cubes;
pub mod bench_plp;
pub mod bench_stream;
pub mod lidar_tiles;
pub mod loadtest;
pub mod meters;
pub mod reference;
pub mod stats;
#[cfg(target_os = "linux")]
pub mod wan;

/// What a measuring command produced: one JSON object (printed with
/// `--json`) and a human summary.
#[derive(Debug)]
pub struct Measured {
    pub json: serde_json::Value,
    pub text: String,
}
