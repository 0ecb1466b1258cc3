//! farfield's one integration test binary: each module covers one area,
//! against real files and the real command line (run in-process).

mod adapter;
mod bad_input;
mod bench;
mod bsp;
mod cgroup;
mod chunked_builds;
mod cli;
mod crowd;
mod cubes;
mod degenerate;
mod demo_sessions;
mod directory;
mod extremes;
mod holes;
mod impostor_prefetch;
mod impostor_tools;
mod impostors;
mod kinds;
mod layout;
mod loadtest;
mod objects;
mod out_of_core;
mod plp;
mod progress;
mod real_data;
mod repeats;
mod replicas;
mod s3;
pub(crate) mod serve;
mod streaming;
mod surface;
mod tiles;
mod tls;
mod traversal;
mod viewer;
mod wan;
mod xvfb;

use std::path::Path;

use clap::Parser;
use farfield_builder::scene::Scene;
use farfield_builder::{BuildOptions, PagedFile, build_spheres};
use farfield_protocol::hierarchy::Hierarchy;
use farfield_server::cli::{Cli, Report, run};
use farfield_store::{SceneFile, write_atomic};

/// Runs `farfield-server ARGS...` in-process.
pub fn cli(args: &[&str]) -> anyhow::Result<Report> {
    run(Cli::try_parse_from(
        std::iter::once("farfield-server").chain(args.iter().copied()),
    )?)
}

/// Builds a scene in memory with leaf sources recorded.
pub fn build(scene: Scene) -> PagedFile {
    build_spheres(
        scene,
        &BuildOptions {
            record_leaf_sources: true,
            ..BuildOptions::default()
        },
    )
    .expect("build")
    .0
}

/// Every page of a built file made resident, through the real page parser.
pub fn resident(file: &PagedFile) -> Hierarchy {
    let mut h = with_directory(file);
    for (i, page) in file.pages.iter().enumerate() {
        h.insert_page(i as u32, page).expect("page");
    }
    h
}

/// The file with only the pages `keep` accepts resident.
pub fn resident_where(file: &PagedFile, keep: impl Fn(usize) -> bool) -> Hierarchy {
    let mut h = with_directory(file);
    for (i, page) in file.pages.iter().enumerate().filter(|&(i, _)| keep(i)) {
        h.insert_page(i as u32, page).expect("page");
    }
    h
}

/// A client's hierarchy of `file` with its directory pages arrived (each
/// checked, as a client checks them) and no page resident yet.
pub fn with_directory(file: &PagedFile) -> Hierarchy {
    let mut h = Hierarchy::new(file.header.clone()).expect("header");
    for (n, bytes) in file.directory_pages.iter().enumerate() {
        h.insert_page(file.header.page_count + n as u32, bytes)
            .expect("directory page");
    }
    h
}

/// A client's hierarchy of a forged `file` whose directory says page
/// `index` has checksum `checksum` (a forged page's), its directory pages
/// arrived: the page then reaches the checks behind the checksums.
pub fn forged(file: &PagedFile, index: usize, checksum: u32) -> Hierarchy {
    let mut entries: Vec<_> = file.directory.entries().map(|(_, e)| e).collect();
    entries[index].checksum = checksum;
    let forged =
        PagedFile::assemble(file.header.clone(), entries, file.pages.clone()).expect("forged file");
    with_directory(&forged)
}

/// Writes a built file and opens it again, as a reader would.
pub fn write_and_open(file: &PagedFile, path: &Path) -> SceneFile {
    write_atomic(path, file).expect("write");
    SceneFile::open(path).expect("open")
}

/// A runtime and a memory server on a free loopback port serving the
/// scenes in `dir`, with its base URL. Shut it down with
/// `rt.block_on(server.shutdown())`.
pub fn serve_dir(
    dir: &Path,
) -> (
    tokio::runtime::Runtime,
    farfield_memory_server::RunningServer,
    String,
) {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime");
    let config = farfield_memory_server::ServerConfig::new(
        dir,
        std::net::SocketAddr::from(([127, 0, 0, 1], 0)),
    );
    let server = rt
        .block_on(farfield_memory_server::start(config))
        .expect("server starts");
    let url = format!("http://{}", server.local_addr());
    (rt, server, url)
}
