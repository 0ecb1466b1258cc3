//! Out of core, scaled for CI: a scene whose file is more than four times
//! the server's page cache and larger than all the memory the server
//! process may hold (a memory cgroup made by the test), served to 16 load
//! clients: no errors, no process killed, the limit held, and the pages
//! really came from disk again and again. The full-size run (64 clients,
//! 60 s) is the benchmark `scripts/out-of-core-bench`.

use farfield_builder::import::{Params, load_input};
use farfield_builder::{BuildOptions, build_spheres};
use farfield_store::write_atomic;
use farfield_tests::scratch;
use farfield_tools::loadtest::LoadReport;

use crate::cgroup::MemoryCgroup;
use crate::serve::support::ChildServer;

/// All the memory the server process may hold.
const LIMIT: u64 = 40 << 20;
/// Its page cache.
const CACHE: u64 = 6 << 20;

#[cfg(target_os = "linux")]
#[test]
fn a_scene_over_the_memory_limit_serves_load_clients_with_no_errors() {
    let Some(cgroup) = MemoryCgroup::create("out-of-core", LIMIT) else {
        return;
    };
    assert_eq!(cgroup.limit(), LIMIT);
    let dir = scratch("out-of-core");
    let scenes = dir.join("scenes");
    std::fs::create_dir_all(&scenes).unwrap();
    let mut params = Params::default();
    // 40 MB of compressed pages (55 MB before pages were compressed).
    params.set("trees", 220);
    let (file, _) = build_spheres(
        load_input("gen:island", &params).unwrap(),
        &BuildOptions::default(),
    )
    .expect("build");
    let path = scenes.join("island.ff");
    write_atomic(&path, &file).unwrap();
    drop(file);
    let bytes = std::fs::metadata(&path).unwrap().len();
    assert!(
        bytes > LIMIT.max(4 * CACHE),
        "the scene ({bytes} bytes) must outgrow the cache and the limit"
    );

    let mut server = ChildServer::start(&scenes, &format!("--cache-bytes {CACHE}"));
    cgroup.add(server.child.id());
    let out = dir.join("run");
    crate::loadtest::cli(&[
        "loadtest",
        "--server",
        &format!("http://{}", server.addr),
        "--scene",
        "island",
        "--clients",
        "16",
        "--duration",
        "8",
        "--ramp",
        "1",
        "--size",
        "320x240",
        "--client-cache-mib",
        "8",
        "--out",
        out.to_str().unwrap(),
    ])
    .expect("loadtest");
    let text = std::fs::read_to_string(out.join("loadtest.json")).unwrap();
    let r: LoadReport = serde_json::from_str(&text).unwrap();
    let alive = server.alive();
    let (peak, kills) = (cgroup.peak(), cgroup.oom_kills());
    eprintln!(
        "out of core: {bytes} byte scene, cache {CACHE}, limit {LIMIT}: {} pages, p99 {:?} ms, \
         server resident {:?}..{:?} MiB, cgroup peak {peak:?}, disk reads {:?}",
        r.pages,
        r.latency_p99_ms,
        r.server_resident_min_mib,
        r.server_resident_max_mib,
        r.server_disk_reads
    );
    assert!(
        alive && kills == 0,
        "the server was killed ({kills} OOM kills)"
    );
    assert_eq!(r.errors, 0, "{r:?}");
    assert_eq!(r.clients_with_first_image, 16, "{r:?}");
    assert!(r.pages > 0);
    assert!(peak.is_none_or(|p| p <= LIMIT), "{peak:?}");
    assert!(
        r.server_resident_max_mib
            .is_some_and(|m| m * f64::from(1 << 20) <= LIMIT as f64),
        "{r:?}"
    );
    // Out of core for real: more was read from disk than the cache holds.
    let read: f64 = r.server_disk_reads.expect("disk reads sampled");
    let page = bytes as f64 / file_pages(&path) as f64;
    assert!(
        read * page > CACHE as f64,
        "only {read} pages read from disk"
    );
    drop(server);
    drop(cgroup);
}

fn file_pages(path: &std::path::Path) -> usize {
    farfield_store::SceneFile::open(path)
        .expect("open")
        .header
        .page_count as usize
}
