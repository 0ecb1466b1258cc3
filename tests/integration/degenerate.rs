//! Zero-area faces, as scanners and CAD exports leave them, added to a real
//! scan: the horse (a Cyberware scan, binary PLY with normals) with faces that repeat a corner and faces whose corners
//! are collinear (exactly, rounded in f64, and rounded to f32 as a PLY
//! stores them), many of them long (between vertices half the model
//! apart), renders like the clean horse, as spheres (with and without input
//! normals) and as cubes.

use std::time::Duration;

use farfield_builder::cubes::{CubeOptions, build_cubes};
use farfield_builder::import::{Params, load_input};
use farfield_builder::scene::{Geometry, Primitives, Scene};
use farfield_builder::zero_area::is_zero_area;
use farfield_builder::{BuildOptions, PagedFile, build_spheres};
use farfield_client::camera_spec::CameraSpec;
use farfield_client::frame_loop::Until;
use farfield_client::render_job::{RenderJob, Source, run};
use farfield_image::compare;
use farfield_net::SessionOptions;
use farfield_render::{Coverage, Kernel, headless_or_skip};
use farfield_store::write_atomic;
use farfield_tests::{scratch, shared_data};
use glam::DVec3;

const SIZE: (u32, u32) = (160, 160);

/// The floor the issue sets: zero-area faces may cost at most rounding.
const MIN_PSNR_DB: f64 = 40.0;

/// Pairs of far-apart vertices that get long zero-area faces.
const LONG_PAIRS: usize = 100;
/// Mesh triangles that get short zero-area faces along their edges.
const SHORT_TRIANGLES: usize = 200;

/// The scan's geometry with zero-area faces added: for each of
/// [`LONG_PAIRS`] pairs of vertices at least half the bounding box's
/// diagonal apart, a face repeating a corner, one with a second vertex at
/// a corner's position, and three collinear ones through a new vertex on
/// the segment (the midpoint, a point rounded in f64, a point rounded to
/// f32); for [`SHORT_TRIANGLES`] of its triangles, the same along an edge
/// but for the f32 point, and a face that is one point. New vertices take
/// the normal of a segment end, so only the faces differ.
///
/// No f32 point on a short edge: the horse's edges are a hundredth of its
/// coordinates, so f32 rounding moves such a point off its line by up to
/// 1e-5 of the edge, a thin sliver by any measure that does not know the
/// file's precision; [`ZERO_AREA_EPS`] says why the bound is tighter.
///
/// [`ZERO_AREA_EPS`]: farfield_builder::zero_area::ZERO_AREA_EPS
fn with_zero_area_faces(clean: &Geometry) -> Geometry {
    let mut g = clean.clone();
    let Primitives::Triangles(clean_triangles) = &clean.primitives else {
        panic!("the scan is a mesh")
    };
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = |n: usize| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state % n as u64) as u32
    };
    let (lo, hi) = g
        .positions
        .iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &p| {
            (lo.min(p), hi.max(p))
        });
    let far = 0.5 * lo.distance(hi);
    let n = g.positions.len();
    let mut faces = Vec::new();
    let mut segments = Vec::new();
    while segments.len() < LONG_PAIRS {
        let (a, b) = (next(n), next(n));
        if g.positions[a as usize].distance(g.positions[b as usize]) >= far {
            segments.push((a, b, true));
        }
    }
    for _ in 0..SHORT_TRIANGLES {
        let [a, b, c] = clean_triangles[next(clean_triangles.len()) as usize];
        segments.push((a, b, false));
        faces.push([c, c, c]);
    }
    for (a, b, long) in segments {
        let (pa, pb) = (g.positions[a as usize], g.positions[b as usize]);
        let t = 0.2 + 0.6 * f64::from(next(1000)) / 1000.0;
        let copy = push_vertex(&mut g, pb, b);
        let middle = push_vertex(&mut g, (pa + pb) * 0.5, a);
        let rounded = push_vertex(&mut g, pa + (pb - pa) * t, a);
        faces.extend([[a, b, b], [a, b, copy], [a, middle, b], [rounded, a, b]]);
        if long {
            let stored = (pa + (pb - pa) * (1.0 - t)).as_vec3().as_dvec3();
            let stored = push_vertex(&mut g, stored, b);
            faces.push([b, stored, a]);
        }
    }
    let corners = |f: &[u32; 3]| f.map(|i| g.positions[i as usize]);
    assert!(
        faces
            .iter()
            .map(corners)
            .all(|[a, b, c]| is_zero_area(a, b, c)),
        "every added face has zero area"
    );
    g.primitives = Primitives::Triangles([&clean_triangles[..], &faces].concat());
    g
}

/// Appends a vertex at `p` with the normal of vertex `like`; its index.
fn push_vertex(g: &mut Geometry, p: DVec3, like: u32) -> u32 {
    g.positions.push(p);
    if let Some(normals) = g.normals.as_mut() {
        normals.push(normals[like as usize]);
    }
    (g.positions.len() - 1) as u32
}

fn spheres(scene: Scene) -> PagedFile {
    build_spheres(scene, &BuildOptions::default())
        .expect("sphere build")
        .0
}

fn cubes(scene: Scene) -> PagedFile {
    build_cubes(scene, &CubeOptions::default())
        .expect("cube build")
        .0
}

/// Both files rendered by the client's own render path (`farfield render
/// --file`, its default 1 px threshold) from the clean file's default
/// camera, and the dirty render's PSNR against the clean one's.
fn psnr_of_renders(
    renderer: &mut farfield_render::Renderer,
    dir: &std::path::Path,
    name: &str,
    clean: &PagedFile,
    dirty: &PagedFile,
) -> f64 {
    let camera = CameraSpec::default().resolve(&clean.header, SIZE.0, SIZE.1);
    let mut images = Vec::new();
    for (which, file) in [("clean", clean), ("dirty", dirty)] {
        let path = dir.join(format!("{name}-{which}.ff"));
        write_atomic(&path, file).expect("write");
        let job = RenderJob {
            source: Source::File(path),
            camera: CameraSpec::Eye {
                eye: camera.eye,
                target: camera.target,
                fov_deg: camera.fov_y_deg,
            },
            width: SIZE.0,
            height: SIZE.1,
            out: Some(dir.join(format!("{name}-{which}.png"))),
            until: Until::Refined,
            threshold_px: 1.0,
            kernel: Kernel::Square,
            edl: None,
            color_by: Default::default(),
            clip: None,
            coverage: Coverage::Alpha,
            session: SessionOptions::default(),
            cache_bytes: 256 << 20,
            timeout: Duration::from_secs(120),
            budget: Default::default(),
        };
        let rendered = run(&job, renderer, false).expect("render");
        assert!(rendered.report.refined, "{name} {which}: not refined");
        let lit = rendered.rgba.chunks_exact(4).filter(|p| p[..3] != [0; 3]);
        assert!(lit.count() > 1000, "{name} {which}: blank render");
        images.push(rendered.rgba);
    }
    compare(&images[0], &images[1], SIZE.0, SIZE.1, 8)
        .expect("same size")
        .psnr_db
}

#[test]
fn zero_area_faces_leave_the_horse_render_as_it_was() {
    let Some(data) = shared_data() else { return };
    let Some(mut renderer) = headless_or_skip(SIZE.0, SIZE.1).unwrap() else {
        return;
    };
    let horse = data.join("horse.ply");
    let clean = load_input(horse.to_str().unwrap(), &Params::default()).unwrap();
    assert!(
        clean.geometries[0].normals.is_some(),
        "the horse has normals"
    );
    let dirty_geometry = with_zero_area_faces(&clean.geometries[0]);
    let dirty = Scene::single(dirty_geometry.clone());
    // Without input normals the builder computes them from the faces.
    let bare = |g: &Geometry| {
        Scene::single(Geometry {
            normals: None,
            ..g.clone()
        })
    };
    let dir = scratch("degenerate");
    let cases = [
        ("spheres", spheres(clean.clone()), spheres(dirty.clone())),
        (
            "spheres-computed-normals",
            spheres(bare(&clean.geometries[0])),
            spheres(bare(&dirty_geometry)),
        ),
        ("cubes", cubes(clean), cubes(dirty)),
    ];
    let mut failed = Vec::new();
    for (name, clean, dirty) in &cases {
        let psnr = psnr_of_renders(&mut renderer, &dir, name, clean, dirty);
        eprintln!("{name}: PSNR {psnr:.2} dB with zero-area faces");
        if psnr < MIN_PSNR_DB {
            failed.push(format!("{name}: {psnr:.2} dB"));
        }
    }
    assert!(
        failed.is_empty(),
        "zero-area faces changed the render (at least {MIN_PSNR_DB} dB wanted): {failed:?}; \
         images in {}",
        dir.display()
    );
}
