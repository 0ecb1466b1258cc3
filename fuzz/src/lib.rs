//! What the fuzz targets share: the steps the real code takes after a
//! decoder succeeds (a hierarchy's pages inserted and traversed, an
//! imported scene validated, built and read back), checksums recomputed so
//! mutated inputs get past them, and a scratch file for importers that
//! read a path.
//!
//! Anything that fails here that the real code would also reach is a
//! finding: bad input must give an error, never a panic, a hang or
//! unbounded memory.

use std::path::PathBuf;
use std::sync::Once;

use farfield_builder::cubes::{CubeOptions, build_cubes};
use farfield_builder::import::{Params, load_input};
use farfield_builder::scene::Primitives;
use farfield_builder::{BuildOptions, build_spheres};
use farfield_protocol::camera::Camera;
use farfield_protocol::file::{FileHeader, PAGE_ENTRY_BYTES};
use farfield_protocol::hierarchy::Hierarchy;
use farfield_protocol::page::PAGE_CHECKSUM_BYTES;
use farfield_protocol::paged_file::{PagedFile, read_image};
use farfield_traverse::{TraversalOptions, for_hierarchy};

/// Scenes up to this many vertices are also built as spheres after they
/// import; larger ones would only slow the fuzzer down.
pub const MAX_BUILD_VERTICES: u64 = 256;

/// Scenes of up to this many triangles, an atom counting as the 320 it is
/// drawn with, are also built as cubes (a few atoms took milliseconds).
pub const MAX_CUBE_TRIANGLES: u64 = 700;

/// One worker thread for rayon: the fuzzer runs one job at a time, and a
/// pool as wide as the machine would only compete with it.
pub fn single_threaded() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let _ = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build_global();
    });
}

/// The LAS importer turns a panic inside the `laz` decompressor into an
/// error ("the LAZ data is corrupt"), as its documentation says, so for the
/// `las` target such a panic is no finding: this keeps libFuzzer's hook
/// from aborting on it (each place is printed once). The target catches a
/// `laz` panic that the importer let out and aborts; a panic anywhere else
/// aborts in the hook as before.
pub fn allow_caught_laz_panics() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let aborting = std::panic::take_hook();
        let seen = std::sync::Mutex::new(std::collections::HashSet::new());
        std::panic::set_hook(Box::new(move |info| {
            // The crate from the registry (laz-0.13.0/src) or its patched
            // copy (third_party/laz/src).
            let in_laz = |file: &str| file.contains("/laz-") || file.contains("/laz/src/");
            let Some(at) = info.location().filter(|l| in_laz(l.file())) else {
                return aborting(info);
            };
            let place = format!("{}:{}", at.file(), at.line());
            if seen.lock().is_ok_and(|mut s| s.insert(place.clone())) {
                eprintln!(
                    "farfield-fuzz: a panic inside laz, caught by the importer: {place}: {info}"
                );
            }
        }));
    });
}

/// A scratch file of this process, with extension `ext` (importers pick
/// their format by it), holding `data`. In /dev/shm where there is one.
pub fn scratch_file(ext: &str, data: &[u8]) -> PathBuf {
    let dir = std::env::var_os("FARFIELD_FUZZ_TMP")
        .map(PathBuf::from)
        .or_else(|| {
            let shm = PathBuf::from("/dev/shm");
            shm.is_dir().then_some(shm)
        })
        .unwrap_or_else(std::env::temp_dir);
    let path = dir.join(format!("farfield-fuzz-{}.{ext}", std::process::id()));
    std::fs::write(&path, data).expect("cannot write the fuzzer's scratch file");
    path
}

/// Imports `data` as a file of extension `ext` the way `farfield-server
/// build` does (format by extension, then `validate`); a small scene is
/// then built as spheres and as cubes, and each file read back and
/// traversed.
pub fn import(ext: &str, data: &[u8]) {
    single_threaded();
    let path = scratch_file(ext, data);
    let path = path.to_str().expect("scratch path is UTF-8");
    let Ok(scene) = load_input(path, &Params::default()) else {
        return;
    };
    if scene.instanced_vertex_count() > MAX_BUILD_VERTICES {
        return;
    }
    let spheres = build_spheres(
        scene.clone(),
        &BuildOptions {
            // Small pages, so even a tiny scene has several.
            page_bytes: 256,
            ..BuildOptions::default()
        },
    );
    if let Ok((file, _)) = spheres {
        read_back(&file);
    }
    let triangles: u64 = scene
        .geometries
        .iter()
        .map(|g| match &g.primitives {
            Primitives::Triangles(t) => t.len() as u64,
            Primitives::Spheres(r) => 320 * r.len() as u64,
            Primitives::Points => 0,
        })
        .sum();
    if triangles > MAX_CUBE_TRIANGLES {
        return;
    }
    let cubes = build_cubes(
        scene,
        &CubeOptions {
            samples: 2,
            max_depth: 6,
            page_bytes: 1024,
            ..CubeOptions::default()
        },
    );
    if let Ok((file, _)) = cubes {
        read_back(&file);
    }
}

/// A built file as the store writes it, read back as a client would: every
/// build must give a file that reads back.
fn read_back(file: &PagedFile) {
    let bytes = file.to_bytes();
    let h = read_image(&bytes).expect("a built file reads back");
    exercise(&h);
}

/// What a client does with a hierarchy: the reference decoder and a
/// traversal of its kind from a few views.
pub fn exercise(h: &Hierarchy) {
    let _ = h.decode_all();
    let mut traversal = for_hierarchy(h.header.kind);
    let options = TraversalOptions::default();
    for (azimuth, distance) in [(30.0, 3.0), (200.0, 0.5)] {
        let camera = Camera::orbit(
            h.header.root_center,
            h.header.root_radius,
            azimuth,
            20.0,
            distance,
            64,
            48,
        );
        traversal.traverse(h, &camera, &options);
        let _ = traversal.wanted();
    }
}

/// Recomputes the checksums of a file's bytes in place where the bytes
/// say where they are: walking the directory pages from the header's root
/// reference, each page an entry places inside `bytes` (its last four
/// bytes and its entry), then each directory page (and the reference to
/// it), children before parents, then the header's. Mutations elsewhere
/// then reach the checks behind the checksums.
pub fn fix_file_checksums(bytes: &mut [u8]) {
    use farfield_protocol::directory::{DIRECTORY_HEADER_BYTES, DIRECTORY_REF_BYTES};
    let Ok(len) = FileHeader::peek_len(bytes) else {
        return;
    };
    if len != FileHeader::ENCODED_LEN || len > bytes.len() {
        return;
    }
    let u32_at = |b: &[u8], at: usize| u32::from_le_bytes(b[at..at + 4].try_into().unwrap());
    let u64_at = |b: &[u8], at: usize| u64::from_le_bytes(b[at..at + 8].try_into().unwrap());
    // (where the page is, where its checksum is kept), breadth-first.
    let reference = 136;
    let mut found: Vec<(std::ops::Range<usize>, usize)> = Vec::new();
    let mut queue = vec![reference];
    while let Some(at) = queue.pop() {
        if found.len() > 4096 {
            break;
        }
        let (offset, length) = (u64_at(bytes, at), u32_at(bytes, at + 8));
        let Some(range) = usize::try_from(offset)
            .ok()
            .and_then(|start| Some(start..start.checked_add(length as usize)?))
            .filter(|r| r.end <= bytes.len() && r.len() >= DIRECTORY_HEADER_BYTES + 4)
        else {
            continue;
        };
        if found.iter().any(|(r, _)| r.start == range.start) {
            continue;
        }
        let page = &bytes[range.clone()];
        let (entries, children) = (u32_at(page, 40) as usize, u32_at(page, 44) as usize);
        let refs = DIRECTORY_HEADER_BYTES + entries.saturating_mul(PAGE_ENTRY_BYTES);
        for c in 0..children.min(1024) {
            let at = refs + c * DIRECTORY_REF_BYTES;
            if at + DIRECTORY_REF_BYTES + 4 <= page.len() {
                queue.push(range.start + at);
            }
        }
        found.push((range, at + 12));
    }
    for (range, checksum_at) in found.into_iter().rev() {
        let entries = u32_at(bytes, range.start + 40) as usize;
        for e in 0..entries.min(4096) {
            let at = range.start + DIRECTORY_HEADER_BYTES + e * PAGE_ENTRY_BYTES;
            if at + PAGE_ENTRY_BYTES + 4 > range.end {
                break;
            }
            let offset = u64_at(bytes, at);
            let length = u32_at(bytes, at + 8);
            let Some(page) = usize::try_from(offset)
                .ok()
                .and_then(|start| Some(start..start.checked_add(length as usize)?))
                .filter(|r| r.end <= bytes.len() && r.len() >= PAGE_CHECKSUM_BYTES)
            else {
                continue;
            };
            let crc = fix_page_checksum(&mut bytes[page]);
            bytes[at + 36..at + 40].copy_from_slice(&crc.to_le_bytes());
        }
        let crc = fix_page_checksum(&mut bytes[range]);
        bytes[checksum_at..checksum_at + 4].copy_from_slice(&crc.to_le_bytes());
    }
    let crc = crc32fast_hash(&bytes[..len - 4]);
    bytes[len - 4..len].copy_from_slice(&crc.to_le_bytes());
}

/// Rewrites a page's trailing checksum to match its bytes; returns it.
pub fn fix_page_checksum(page: &mut [u8]) -> u32 {
    let Some(body) = page.len().checked_sub(PAGE_CHECKSUM_BYTES) else {
        return 0;
    };
    let crc = crc32fast_hash(&page[..body]);
    page[body..].copy_from_slice(&crc.to_le_bytes());
    crc
}

/// The CRC-32 every farfield page and header carries.
fn crc32fast_hash(bytes: &[u8]) -> u32 {
    crc32fast::hash(bytes)
}
