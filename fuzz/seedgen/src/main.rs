//! Writes the seed corpora of the fuzz targets into `fuzz/corpus/<target>/`
//! as `seed-*` files: small cases cut from the shared data (the first
//! vertices of a scan, the first atoms of a molecule, the first points of
//! a lidar cloud, written in every variant of their format) and scene
//! files built from them. Nothing is copied whole: every seed is a few
//! kilobytes at most.
//!
//! `cargo run --release` in this folder; `FARFIELD_DATA` names the data
//! folder (default `../../../shared/data`).

use std::fmt::Write as _;
use std::io::Cursor;
use std::path::{Path, PathBuf};

use farfield_builder::cubes::{CubeOptions, build_cubes};
use farfield_builder::plp::{PlpOptions, build_plp};
use farfield_builder::import::{Params, load_input};
use farfield_builder::scene::{Geometry, Primitives, Scene};
use farfield_builder::{BuildOptions, build_spheres};
use farfield_protocol::codec::{encode_control, encode_header_frame, encode_page_frame};
use farfield_protocol::cube_codec::{CubeRecord, RECORD_BYTES};
use farfield_protocol::file::HierarchyKind;
use farfield_protocol::messages::{ClientMessage, PROTOCOL_VERSION, PageWish, ServerMessage};
use farfield_protocol::page::Page;
use farfield_protocol::paged_file::PagedFile;

struct Out {
    root: PathBuf,
    written: usize,
    bytes: usize,
}

impl Out {
    fn seed(&mut self, target: &str, name: &str, bytes: &[u8]) {
        let dir = self.root.join(target);
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join(format!("seed-{name}")), bytes).unwrap();
        self.written += 1;
        self.bytes += bytes.len();
    }
}

fn main() {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    let data = std::env::var_os("FARFIELD_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| here.join("../../../shared/data"));
    let mut out = Out {
        root: here.join("../corpus"),
        written: 0,
        bytes: 0,
    };
    let load = |name: &str| {
        load_input(data.join(name).to_str().unwrap(), &Params::default())
            .unwrap_or_else(|e| panic!("{name}: {e}"))
    };

    let horse = mesh_subset(&load("horse.ply"), 40);
    let bunny = mesh_subset(&load("stanford-bunny.obj"), 30);
    let spot = mesh_subset(&load("spot.obj"), 30);
    let molecule = first_vertices(&load("2XHE.pdb"), 30);
    let lidar = first_vertices(&load("autzen_trim.las"), 30);

    obj_seeds(&mut out, &data, &[&horse, &bunny, &spot]);
    ply_seeds(&mut out, &data, &[&horse, &bunny]);
    off_seeds(&mut out, &[&horse, &spot]);
    las_seeds(&mut out, &data);
    pdb_seeds(&mut out, &data);

    let mut files = Vec::new();
    let spheres = BuildOptions {
        page_bytes: 256,
        ..BuildOptions::default()
    };
    let cubes = CubeOptions {
        samples: 2,
        max_depth: 4,
        page_bytes: 1024,
        ..CubeOptions::default()
    };
    for (name, scene) in [
        ("horse", &horse),
        ("bunny", &bunny),
        ("molecule", &molecule),
        ("lidar", &lidar),
    ] {
        let (file, _) = build_spheres(scene.clone(), &spheres).unwrap();
        files.push((format!("spheres-{name}"), file));
    }
    let atoms = first_vertices(&molecule, 2);
    for (name, scene) in [("horse", &horse), ("atoms", &atoms)] {
        let (file, _) = build_cubes(scene.clone(), &cubes).unwrap();
        files.push((format!("cubes-{name}"), file));
    }
    let k2 = CubeOptions {
        cluster: 2,
        ..cubes
    };
    let (file, _) = build_cubes(spot.clone(), &k2).unwrap();
    files.push(("cubes-k2-spot".into(), file));
    // A PLP tessellation small enough for a seed: one octree split.
    let plp = PlpOptions {
        leaf_fraction: 1.0,
        page_bytes: 1024,
        ..PlpOptions::default()
    };
    let (file, _) = build_plp(&spot, &plp).unwrap();
    files.push(("plp-spot".into(), file));
    for (name, file) in &files {
        file_seeds(&mut out, name, file);
    }
    message_seeds(&mut out, &files[0].1);
    check_imports(&out.root);
    println!(
        "{} seeds, {} bytes, in {}",
        out.written,
        out.bytes,
        out.root.display()
    );
}

/// The first `n` triangles of a mesh and the vertices they use (in order
/// of first use).
fn mesh_subset(scene: &Scene, n: usize) -> Scene {
    let g = &scene.geometries[0];
    let Primitives::Triangles(tris) = &g.primitives else {
        panic!("{} is not a mesh", g.name)
    };
    let mut new_index = std::collections::HashMap::new();
    let mut used = Vec::new();
    let tris: Vec<[u32; 3]> = tris[..n]
        .iter()
        .map(|t| {
            t.map(|i| {
                *new_index.entry(i).or_insert_with(|| {
                    used.push(i as usize);
                    used.len() as u32 - 1
                })
            })
        })
        .collect();
    fn pick<T: Copy>(used: &[usize], v: &[T]) -> Vec<T> {
        used.iter().map(|&i| v[i]).collect()
    }
    let mut sub = Geometry::new(
        g.name.clone(),
        pick(&used, &g.positions),
        Primitives::Triangles(tris),
    );
    sub.normals = g.normals.as_ref().map(|v| pick(&used, v));
    sub.colors = g.colors.as_ref().map(|v| pick(&used, v));
    Scene::single(sub)
}

/// The first `n` points (or atoms) of a cloud.
fn first_vertices(scene: &Scene, n: usize) -> Scene {
    let g = &scene.geometries[0];
    let primitives = match &g.primitives {
        Primitives::Spheres(r) => Primitives::Spheres(r[..n].to_vec()),
        Primitives::Points => Primitives::Points,
        Primitives::Triangles(_) => panic!("{} is a mesh", g.name),
    };
    let mut sub = Geometry::new(g.name.clone(), g.positions[..n].to_vec(), primitives);
    sub.normals = g.normals.as_ref().map(|v| v[..n].to_vec());
    sub.colors = g.colors.as_ref().map(|v| v[..n].to_vec());
    Scene::single(sub)
}

fn geometry(scene: &Scene) -> (&Geometry, &[[u32; 3]]) {
    let g = &scene.geometries[0];
    match &g.primitives {
        Primitives::Triangles(t) => (g, t),
        _ => (g, &[]),
    }
}

/// Short, so text seeds stay small: 6 significant digits.
fn num(v: f64) -> String {
    format!("{v:.6}")
        .trim_end_matches('0')
        .trim_end_matches('.')
        .to_string()
}

/// The first `budget` bytes of a text file, cut at a line end.
fn text_prefix(path: &Path, budget: usize) -> Vec<u8> {
    let bytes = std::fs::read(path).unwrap();
    let cut = bytes[..budget.min(bytes.len())]
        .iter()
        .rposition(|&b| b == b'\n')
        .map_or(0, |i| i + 1);
    bytes[..cut].to_vec()
}

fn obj_seeds(out: &mut Out, data: &Path, meshes: &[&Scene]) {
    for (k, mesh) in meshes.iter().enumerate() {
        let (g, tris) = geometry(mesh);
        // Plain, with colors, normals and negative indices.
        let mut plain = String::from("# first vertices\no part\n");
        let mut rich = String::from("mtllib m.mtl\ng rich\nusemtl m\ns 1\n");
        for (i, p) in g.positions.iter().enumerate() {
            writeln!(plain, "v {} {} {}", num(p.x), num(p.y), num(p.z)).unwrap();
            let c = g.colors.as_ref().map_or([200, 100, 50], |c| c[i]);
            writeln!(
                rich,
                "v {} {} {} {} {} {}",
                num(p.x),
                num(p.y),
                num(p.z),
                num(f64::from(c[0]) / 255.0),
                num(f64::from(c[1]) / 255.0),
                num(f64::from(c[2]) / 255.0)
            )
            .unwrap();
            let n = g.normals.as_ref().map_or(glam::Vec3::Z, |n| n[i]);
            writeln!(rich, "vn {} {} {}", n.x, n.y, n.z).unwrap();
            writeln!(rich, "vt 0.{i} 0.5").unwrap();
        }
        let n = g.positions.len() as i64;
        for (j, t) in tris.iter().enumerate() {
            let [a, b, c] = t.map(|i| i64::from(i) + 1);
            writeln!(plain, "f {a} {b} {c}").unwrap();
            match j % 3 {
                0 => writeln!(rich, "f {a}//{a} {b}//{b} {c}//{c}").unwrap(),
                1 => writeln!(rich, "f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}").unwrap(),
                _ => writeln!(rich, "f {} {} {}", a - n - 1, b - n - 1, c - n - 1).unwrap(),
            }
        }
        writeln!(rich, "l 1 2\np 3\nf 1 2 3 4\r").unwrap();
        out.seed("obj", &format!("plain-{k}.obj"), plain.as_bytes());
        out.seed("obj", &format!("rich-{k}.obj"), rich.as_bytes());
    }
    // The real files' first lines: their comments, `vt`, quads and all.
    for name in ["stanford-bunny.obj", "beast.obj", "spot.obj"] {
        out.seed(
            "obj",
            &format!("head-{name}"),
            &text_prefix(&data.join(name), 2048),
        );
    }
    out.seed(
        "obj",
        "points.obj",
        b"v 0 0 0 1 0.5 0\nv 1 2 3 0 0 1\nv 4 5 6\n",
    );
    out.seed(
        "obj",
        "bad.obj",
        b"v 1 2 1e999\nf 1 2 0\nvn 1 2\nf 1//3 2 x\n",
    );
}

fn ply_seeds(out: &mut Out, data: &Path, meshes: &[&Scene]) {
    for (k, mesh) in meshes.iter().enumerate() {
        let (g, tris) = geometry(mesh);
        for format in ["ascii", "binary_little_endian", "binary_big_endian"] {
            for strips in [false, true] {
                let seed = ply(g, tris, format, strips);
                let kind = if strips { "strips" } else { "faces" };
                out.seed("ply", &format!("{k}-{format}-{kind}.ply"), &seed);
            }
        }
    }
    // The real headers with small counts, and their first vertices.
    for name in ["horse.ply", "igea.ply"] {
        out.seed(
            "ply",
            &format!("head-{name}"),
            &real_ply_prefix(&data.join(name), 20),
        );
    }
    out.seed(
        "ply",
        "points.ply",
        b"ply\nformat ascii 1.0\ncomment c\nelement vertex 3\nproperty double x\n\
          property double y\nproperty double z\nproperty ushort red\nproperty ushort green\n\
          property ushort blue\nelement other 1\nproperty list uint char stuff\nend_header\n\
          0 0 0 65535 0 0\n1 0 0 0 65535 0\n0 1 0 0 0 65535\n3 1 2 3\n",
    );
}

/// A PLY of vertices (float position, normal, uchar color) and faces or
/// one triangle strip per triangle pair.
fn ply(g: &Geometry, tris: &[[u32; 3]], format: &str, strips: bool) -> Vec<u8> {
    let mut head = format!("ply\nformat {format} 1.0\ncomment seed\n");
    writeln!(head, "element vertex {}", g.positions.len()).unwrap();
    head += "property float x\nproperty float y\nproperty float z\n";
    head += "property float nx\nproperty float ny\nproperty float nz\n";
    head += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    let strip: Vec<i32> = tris
        .iter()
        .enumerate()
        .flat_map(|(i, t)| {
            let t = t.map(|v| v as i32);
            if i + 1 < tris.len() {
                vec![t[0], t[1], t[2], -1]
            } else {
                t.to_vec()
            }
        })
        .collect();
    if strips {
        head += "element tristrips 1\nproperty list int int vertex_indices\n";
    } else {
        writeln!(head, "element face {}", tris.len()).unwrap();
        head += "property list uchar int vertex_indices\n";
    }
    head += "end_header\n";
    let mut body = Vec::new();
    let big = format == "binary_big_endian";
    let f = |v: f32, body: &mut Vec<u8>| {
        body.extend_from_slice(&if big {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        })
    };
    let i = |v: i32, body: &mut Vec<u8>| {
        body.extend_from_slice(&if big {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        })
    };
    let mut text = String::new();
    for (k, p) in g.positions.iter().enumerate() {
        let n = g.normals.as_ref().map_or(glam::Vec3::Z, |n| n[k]);
        let c = g.colors.as_ref().map_or([10, 200, 30], |c| c[k]);
        let v = [p.x as f32, p.y as f32, p.z as f32, n.x, n.y, n.z];
        if format == "ascii" {
            for x in v {
                write!(text, "{} ", num(f64::from(x))).unwrap();
            }
            writeln!(text, "{} {} {}", c[0], c[1], c[2]).unwrap();
        } else {
            for x in v {
                f(x, &mut body);
            }
            body.extend_from_slice(&c);
        }
    }
    if strips {
        if format == "ascii" {
            write!(text, "{}", strip.len()).unwrap();
            for v in &strip {
                write!(text, " {v}").unwrap();
            }
            text.push('\n');
        } else {
            i(strip.len() as i32, &mut body);
            for &v in &strip {
                i(v, &mut body);
            }
        }
    } else {
        for t in tris {
            if format == "ascii" {
                writeln!(text, "3 {} {} {}", t[0], t[1], t[2]).unwrap();
            } else {
                body.push(3);
                for &v in t {
                    i(v as i32, &mut body);
                }
            }
        }
    }
    let mut seed = head.into_bytes();
    seed.extend_from_slice(text.as_bytes());
    seed.extend_from_slice(&body);
    seed
}

/// A little-endian binary PLY's own header with `keep` vertices and its
/// first `keep` vertex records, then, in the file's own list types, a fan
/// of faces over them (for `face`) or one strip (for `tristrips`).
fn real_ply_prefix(path: &Path, keep: u32) -> Vec<u8> {
    let bytes = std::fs::read(path).unwrap();
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let head = std::str::from_utf8(&bytes[..end]).unwrap();
    assert!(head.contains("binary_little_endian"));
    let size = |t: &str| match t {
        "char" | "uchar" | "int8" | "uint8" => 1,
        "short" | "ushort" | "int16" | "uint16" => 2,
        "double" | "float64" => 8,
        _ => 4,
    };
    let int = |v: u32, t: &str| v.to_le_bytes()[..size(t)].to_vec();
    let (mut text, mut record, mut element) = (String::new(), 0usize, String::new());
    let mut tail = Vec::new();
    for line in head.lines() {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["element", name, _] => {
                element = (*name).to_string();
                let count = match *name {
                    "vertex" => keep,
                    "face" => keep - 2,
                    "tristrips" => 1,
                    _ => 0,
                };
                writeln!(text, "element {name} {count}").unwrap();
                continue;
            }
            ["property", t, _] if element == "vertex" => record += size(t),
            ["property", "list", c, i, _] if element == "face" => {
                for k in 1..keep - 1 {
                    tail.extend(int(3, c));
                    for v in [0, k, k + 1] {
                        tail.extend(int(v, i));
                    }
                }
            }
            ["property", "list", c, i, _] if element == "tristrips" => {
                tail.extend(int(keep, c));
                for v in 0..keep {
                    tail.extend(int(v, i));
                }
            }
            _ => {}
        }
        writeln!(text, "{line}").unwrap();
    }
    let mut seed = text.into_bytes();
    seed.extend_from_slice(&bytes[end..end + record * keep as usize]);
    seed.extend_from_slice(&tail);
    seed
}

fn off_seeds(out: &mut Out, meshes: &[&Scene]) {
    for (k, mesh) in meshes.iter().enumerate() {
        let (g, tris) = geometry(mesh);
        for keyword in ["OFF", "COFF", "NOFF", "CNOFF", "STCNOFF", ""] {
            let mut text = String::new();
            let (nv, nf) = (g.positions.len(), tris.len());
            match keyword {
                "" => writeln!(text, "{nv} {nf}").unwrap(),
                "OFF" => writeln!(text, "OFF {nv} {nf} 0 # counts here").unwrap(),
                kw => writeln!(text, "{kw}\n# a comment\n{nv} {nf} 0").unwrap(),
            }
            for (i, p) in g.positions.iter().enumerate() {
                write!(text, "{} {} {}", num(p.x), num(p.y), num(p.z)).unwrap();
                if keyword.contains('N') {
                    let n = g.normals.as_ref().map_or(glam::Vec3::Z, |n| n[i]);
                    write!(text, " {} {} {}", n.x, n.y, n.z).unwrap();
                }
                if keyword.contains('C') {
                    let c = g.colors.as_ref().map_or([1, 2, 250], |c| c[i]);
                    write!(text, " {} {} {} 255", c[0], c[1], c[2]).unwrap();
                }
                if keyword.contains("ST") {
                    text += " 0.5 0.25";
                }
                text.push('\n');
            }
            for (j, t) in tris.iter().enumerate() {
                write!(text, "3 {} {} {}", t[0], t[1], t[2]).unwrap();
                if j % 4 == 0 {
                    text += " 0.5 0.5 0.5";
                }
                text.push('\n');
            }
            text += "4 0 1 2 3\n";
            let name = if keyword.is_empty() { "bare" } else { keyword };
            out.seed("off", &format!("{k}-{name}.off"), text.as_bytes());
        }
    }
}

fn las_seeds(out: &mut Out, data: &Path) {
    let path = data.join("autzen_trim.las");
    let mut reader = las::Reader::from_path(&path).unwrap();
    let points: Vec<las::Point> = reader
        .read_points(12)
        .unwrap()
        .points()
        .map(Result::unwrap)
        .collect();
    let header = reader.header().clone();
    for (version, formats) in [((1, 2), &[0u8, 1, 2, 3][..]), ((1, 4), &[6, 7, 8][..])] {
        for &format in formats {
            for compressed in [false, true] {
                let mut builder = las::Builder::from(version);
                builder.point_format = las::point::Format::new(format).unwrap();
                builder.point_format.is_compressed = compressed;
                builder.transforms = *header.transforms();
                let f = builder.point_format;
                let header = builder.into_header().unwrap();
                let mut writer = las::Writer::new(Cursor::new(Vec::new()), header).unwrap();
                for p in &points {
                    let mut p = p.clone();
                    p.color = f.has_color.then(|| p.color.unwrap_or_default());
                    p.gps_time = f.has_gps_time.then(|| p.gps_time.unwrap_or(1.0));
                    p.nir = f.has_nir.then_some(7);
                    writer.write_point(p).unwrap();
                }
                let bytes = writer.into_inner().unwrap();
                let ext = if compressed { "laz" } else { "las" };
                out.seed(
                    "las",
                    &format!("{}.{}-format{format}.{ext}", version.0, version.1),
                    bytes.get_ref(),
                );
            }
        }
    }
    // The real file's header and VLRs, with its first points.
    let bytes = std::fs::read(&path).unwrap();
    let offset = u32::from_le_bytes(bytes[96..100].try_into().unwrap()) as usize;
    let record = u16::from_le_bytes(bytes[105..107].try_into().unwrap()) as usize;
    let keep = 8u32;
    let mut seed = bytes[..offset + record * keep as usize].to_vec();
    seed[107..111].copy_from_slice(&keep.to_le_bytes());
    out.seed("las", "head-autzen.las", &seed);
}

fn pdb_seeds(out: &mut Out, data: &Path) {
    let text = std::fs::read_to_string(data.join("2XHE.pdb")).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let first_atom = lines.iter().position(|l| l.starts_with("ATOM")).unwrap();
    let first_het = lines.iter().position(|l| l.starts_with("HETATM")).unwrap();
    let header: String = lines[..12].iter().map(|l| format!("{l}\n")).collect();
    let atoms: String = lines[first_atom..first_atom + 24]
        .iter()
        .map(|l| format!("{l}\n"))
        .collect();
    let hets: String = lines[first_het..first_het + 8]
        .iter()
        .map(|l| format!("{l}\n"))
        .collect();
    out.seed(
        "pdb",
        "atoms.pdb",
        format!("{header}{atoms}END\n").as_bytes(),
    );
    out.seed("pdb", "hetatm.pdb", format!("{hets}TER\nEND\n").as_bytes());
    let model = format!("MODEL        1\n{atoms}ENDMDL\nMODEL        2\n{hets}ENDMDL\n");
    out.seed("pdb", "models.pdb", model.as_bytes());
    // Alternate locations, atom names for the element, odd lines.
    let alt = "ATOM      1  CA AALA A   1      11.104   6.134  -6.504  1.00  0.00           C\n\
               ATOM      2  CA BALA A   1      11.200   6.100  -6.500  1.00  0.00           C\n\
               HETATM    3 FE   HEM A   2       1.000   2.000   3.000  1.00  0.00\n\
               ATOM      4 HG21 THR A   3       0.000   0.000   0.000\n\
               ANISOU    1  CA AALA A   1     1000   1000   1000      0      0      0       C\n";
    out.seed("pdb", "alt.pdb", alt.as_bytes());
    out.seed("pdb", "bad.pdb", b"ATOM\nHETATM \xe9\xe9\n\0\n");
}

/// A built file's bytes as stored: header, then pages.
fn file_bytes(file: &PagedFile) -> Vec<u8> {
    file.to_bytes()
}

fn file_seeds(out: &mut Out, name: &str, file: &PagedFile) {
    let h = &file.header;
    let bytes = file_bytes(file);
    println!("{name}: {} bytes, {} pages", bytes.len(), file.pages.len());
    assert!(bytes.len() < 16 << 10, "{name}: {} bytes", bytes.len());
    // The header target: mode 0 (checksums recomputed), the file.
    let mut seed = vec![0u8];
    seed.extend_from_slice(&bytes);
    out.seed("header", name, &seed);
    let cubes = h.kind == HierarchyKind::Cubes;
    let plp = h.kind == HierarchyKind::Plp;
    let flags = u8::from(cubes)
        | u8::from(plp) << 4
        | u8::from(h.attributes.color) << 1
        | u8::from(h.attributes.normals) << 2
        | u8::from(h.attributes.leaf_geometry) << 3;
    let entries: Vec<_> = file.directory.entries().map(|(_, e)| e).collect();
    for (i, (page, entry)) in file.pages.iter().zip(&entries).enumerate().take(4) {
        let after = h.nodes - entry.first_node - u64::from(entry.node_count);
        let mut seed = vec![flags, h.cluster];
        seed.extend_from_slice(&(after as u32).to_le_bytes());
        seed.extend_from_slice(page);
        out.seed("page", &format!("{name}-{i}"), &seed);
    }
    // The node target: sphere records, or cube cells with their payloads
    // (PLP records are two words, decoded with their page).
    if plp {
        return;
    }
    let page = Page::parse_with_payload(&file.pages[0], 0, h.node_bytes).unwrap();
    if !cubes {
        let mut seed = vec![flags, 0];
        seed.extend_from_slice(page.records());
        out.seed("node", name, &seed);
        return;
    }
    let mut at = 0usize;
    let mut kept = 0;
    for (i, record) in page.records().chunks_exact(RECORD_BYTES).enumerate() {
        let cell = CubeRecord::unpack(record).unwrap();
        let len = cell.payload_bytes as usize;
        let payload = &page.payload()[at..at + len];
        at += len;
        if len == 0 && i > 0 || kept >= 3 {
            continue;
        }
        kept += 1;
        let mut seed = vec![flags, h.cluster];
        seed.extend_from_slice(record);
        seed.extend_from_slice(payload);
        out.seed("node", &format!("{name}-cell{i}"), &seed);
    }
}

fn message_seeds(out: &mut Out, file: &PagedFile) {
    let client = [
        ClientMessage::Hello {
            protocol_version: PROTOCOL_VERSION,
            max_in_flight_bytes: 1 << 20,
            allow_push: true,
        },
        ClientMessage::Request {
            pages: vec![
                PageWish {
                    page: 3,
                    priority: 2.5,
                },
                PageWish {
                    page: 0,
                    priority: f32::INFINITY,
                },
            ],
        },
        ClientMessage::Cancel {
            pages: vec![1, 2, 300_000],
        },
        ClientMessage::Received { pages: vec![0] },
    ];
    for (i, m) in client.iter().enumerate() {
        out.seed("message", &format!("client-{i}"), &encode_control(m));
    }
    let server = [
        ServerMessage::Hello {
            protocol_version: PROTOCOL_VERSION,
            server: "farfield-server 0.1.0".into(),
        },
        ServerMessage::Error {
            message: "page 9 does not exist".into(),
            fatal: false,
        },
        ServerMessage::PageUnavailable {
            page: 4,
            reason: "page is truncated".into(),
        },
    ];
    for (i, m) in server.iter().enumerate() {
        out.seed("message", &format!("server-{i}"), &encode_control(m));
    }
    out.seed(
        "message",
        "header",
        &encode_header_frame(&file.header.encode()),
    );
    out.seed("message", "page", &encode_page_frame(&file.pages[0]));
}

/// Every importer seed but the deliberately bad ones imports: a seed the
/// importer refuses at once would teach the fuzzer little.
fn check_imports(root: &Path) {
    for target in ["obj", "ply", "off", "las", "pdb"] {
        for entry in std::fs::read_dir(root.join(target)).unwrap() {
            let path = entry.unwrap().path();
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            if !name.starts_with("seed-") || name.starts_with("seed-bad") {
                continue;
            }
            // The importers pick the format by extension.
            let tmp = std::env::temp_dir().join(format!("seedgen-check.{target}"));
            std::fs::copy(&path, &tmp).unwrap();
            if let Err(e) = load_input(tmp.to_str().unwrap(), &Params::default()) {
                panic!("{name}: {e}");
            }
        }
    }
}
