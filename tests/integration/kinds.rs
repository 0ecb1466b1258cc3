//! Every hierarchy kind through one harness, from its registries: built by
//! its builder (`farfield_builder::kinds::BUILDERS`), every page verified
//! as the store does and decoded as the client does, traversed by each
//! registered traversal (`farfield_traverse::KINDS`) whole and streamed in
//! part, and drawn. A new kind is tested here with no change but a new
//! draw list's bounds (the match below is exhaustive, so the compiler asks).

use farfield_builder::import::{Params, load_input};
use farfield_builder::kinds::{BUILDERS, BuildSettings, builder_for};
use farfield_builder::{PagedFile, Silent};
use farfield_protocol::bsp_codec::Split;
use farfield_protocol::camera::{Camera, Containment, View};
use farfield_protocol::file::HierarchyKind;
use farfield_protocol::hierarchy::{Hierarchy, PlpPage};
use farfield_render::{Renderer, SplatStyle};
use farfield_tests::scratch;
use farfield_traverse::impostors::plan::Item;
use farfield_traverse::{DrawList, KINDS, TraversalOptions, for_hierarchy};
use glam::DVec3;

use crate::{resident_where, write_and_open};

/// A small tree scene as a file of `kind`, built by the kind's registered
/// builder, with pages small enough that a view needs several.
fn file_of(kind: HierarchyKind) -> PagedFile {
    let mut params = Params::default();
    params.set("triangles", 4000);
    let scene = load_input("gen:tree", &params).expect("gen:tree");
    let mut settings = BuildSettings::default();
    settings.spheres.page_bytes = 2048;
    settings.cubes.page_bytes = 4096;
    settings.plp.page_bytes = 8192;
    settings.bsp.leaf_triangles = 500;
    let builder = builder_for(kind);
    assert_eq!(builder.kind, kind);
    (builder.build)(scene, &settings, &Silent)
        .unwrap_or_else(|e| panic!("{}: {e}", builder.name()))
        .file
}

/// Orbits near and far, one looking past the scene's edge, one from inside.
fn cameras(h: &Hierarchy) -> Vec<Camera> {
    let (c, r) = (h.header.root_center, h.header.root_radius);
    let mut cameras: Vec<Camera> = [(30.0, 10.0, 3.0), (200.0, 40.0, 1.2), (75.0, -20.0, 8.0)]
        .iter()
        .map(|&(az, el, d)| Camera::orbit(c, r, az, el, d, 200, 150))
        .collect();
    // Looking from the scene's edge towards its side, so part of it is behind.
    cameras.push(Camera {
        eye: c + DVec3::new(r * 0.9, 0.0, 0.0),
        target: c + DVec3::new(r * 0.9, r, 0.0),
        up: DVec3::Z,
        fov_y_deg: 50.0,
        width: 200,
        height: 150,
    });
    cameras
}

/// Bounding spheres of everything a draw list draws.
fn drawn_spheres(h: &Hierarchy, list: DrawList<'_>) -> Vec<(DVec3, f64)> {
    let cube = |min: DVec3, edge: f64| (min + DVec3::splat(edge * 0.5), edge * 0.5 * 3f64.sqrt());
    match list {
        DrawList::Splats(splats) => splats.iter().map(|s| (s.center, s.radius)).collect(),
        DrawList::Cubes(cut) => cut
            .faces
            .iter()
            .map(|f| cube(f.min, f.edge))
            .chain(cut.leaves.iter().map(|l| cube(l.min, l.edge)))
            .collect(),
        DrawList::Bsp(cut) => {
            let Some(s) = h.bsp_skeleton() else {
                assert!(cut.leaves.is_empty(), "drew leaves without page 0");
                return Vec::new();
            };
            let leaf_boxes = cut.leaves.iter().map(|l| {
                let node = s
                    .nodes
                    .iter()
                    .find(|n| n.split == Split::Leaf { leaf: l.leaf })
                    .expect("a drawn leaf is in the skeleton");
                box_sphere(node.box_min, node.box_max)
            });
            let instance_boxes = cut.instances.iter().map(|i| {
                let info = &s.prototypes[(i.prototype_page - 1) as usize];
                let corners = farfield_traverse::bsp::box_corners(info.box_min, info.box_max)
                    .map(|c| i.world_from_local.transform_point3(c));
                let (lo, hi) = corners
                    .iter()
                    .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), c| {
                        (lo.min(*c), hi.max(*c))
                    });
                box_sphere(lo, hi)
            });
            leaf_boxes.chain(instance_boxes).collect()
        }
        DrawList::Impostors(cut) => {
            let Some(s) = h.bsp_skeleton() else {
                assert!(cut.items.is_empty(), "drew without page 0");
                return Vec::new();
            };
            cut.items
                .iter()
                .map(|item| match item {
                    Item::Leaf { leaf, .. } => {
                        let node = s
                            .nodes
                            .iter()
                            .find(|n| n.split == Split::Leaf { leaf: *leaf })
                            .expect("a drawn leaf is in the skeleton");
                        box_sphere(node.box_min, node.box_max)
                    }
                    Item::Quad { corners, .. } => {
                        let lo = corners.iter().fold(DVec3::INFINITY, |a, c| a.min(*c));
                        let hi = corners.iter().fold(DVec3::NEG_INFINITY, |a, c| a.max(*c));
                        box_sphere(lo, hi)
                    }
                })
                .collect()
        }
        DrawList::Triangles(cut) => cut
            .triangles
            .iter()
            .map(|t| {
                let Some(PlpPage::Cells(page)) = h.page(t.page as usize).and_then(|p| p.plp())
                else {
                    panic!(
                        "drew a triangle of page {}, which is not a resident cell page",
                        t.page
                    );
                };
                let corners = page.triangles[t.index as usize]
                    .corners
                    .map(|c| page.world(c));
                let centre = (corners[0] + corners[1] + corners[2]) / 3.0;
                let radius = corners
                    .iter()
                    .map(|c| c.distance(centre))
                    .fold(0.0, f64::max);
                (centre, radius)
            })
            .collect(),
    }
}

/// A box's bounding sphere.
fn box_sphere(min: DVec3, max: DVec3) -> (DVec3, f64) {
    ((min + max) * 0.5, (max - min).length() * 0.5)
}

/// A frustum a little wider than any traversal's (near plane at a
/// billionth of the scene), so rounding at the planes cannot fail a test.
fn test_view(camera: &Camera, h: &Hierarchy) -> View {
    camera.view(h.header.root_radius * 1e-9)
}

#[test]
fn every_kind_draws_nothing_outside_the_frustum_and_wants_only_pages_the_file_has() {
    assert!(!KINDS.is_empty());
    for kind in KINDS {
        let file = file_of(kind.hierarchy);
        let pages = file.pages.len();
        assert!(
            pages > 3,
            "{}: {pages} pages is too few to stream",
            kind.name
        );
        let whole = resident_where(&file, |_| true);
        let partial = resident_where(&file, |i| i == 0 || i % 3 == 1);
        let page_zero = resident_where(&file, |i| i == 0);
        let nothing = resident_where(&file, |_| false);
        let mut traversal = (kind.make)();
        assert_eq!(traversal.registered().name, kind.name);
        let mut drew_something = false;
        for (what, h) in [
            ("whole", &whole),
            ("partial", &partial),
            ("page 0", &page_zero),
            ("nothing", &nothing),
        ] {
            for (k, camera) in cameras(h).iter().enumerate() {
                for threshold_px in [kind.reference_threshold_px, 1.0, 8.0] {
                    let options = TraversalOptions {
                        threshold_px,
                        record_pages: true,
                        ..TraversalOptions::default()
                    };
                    traversal.traverse(h, camera, &options);
                    let at = format!(
                        "{}, {what}, camera {k}, threshold {threshold_px}",
                        kind.name
                    );
                    let view = test_view(camera, h);
                    let drawn = drawn_spheres(h, traversal.draw_list());
                    for &(center, radius) in &drawn {
                        assert_ne!(
                            view.classify(center, radius),
                            Containment::Outside,
                            "{at}: drew a primitive outside the frustum at {center} (radius {radius})"
                        );
                    }
                    drew_something |= !drawn.is_empty();
                    for w in traversal.wanted() {
                        assert!(
                            (w.page as usize) < pages,
                            "{at}: wants page {} of a {pages}-page file",
                            w.page
                        );
                        assert!(
                            !h.is_resident(w.page as usize),
                            "{at}: wants page {}, which is resident",
                            w.page
                        );
                        assert!(w.priority > 0.0, "{at}: priority {}", w.priority);
                    }
                    for &p in traversal.touched_pages() {
                        assert!(
                            h.is_resident(p as usize),
                            "{at}: touched page {p}, not resident"
                        );
                    }
                    if what == "nothing" {
                        let wanted: Vec<u32> = traversal.wanted().iter().map(|w| w.page).collect();
                        assert_eq!(wanted, vec![0], "{at}: with nothing resident, page 0 first");
                        assert!(drawn.is_empty(), "{at}: drew without pages");
                    }
                    if what == "whole" {
                        assert!(
                            traversal.wanted().is_empty(),
                            "{at}: wants pages of a whole file"
                        );
                    }
                }
            }
        }
        assert!(drew_something, "{}: never drew anything", kind.name);
    }
}

#[test]
fn every_hierarchy_kind_builds_verifies_traverses_and_draws() {
    assert_eq!(BUILDERS.len(), HierarchyKind::ALL.len());
    let size = (96, 72);
    let mut renderer = Renderer::new_headless(size.0, size.1).expect("a headless renderer");
    let style = SplatStyle::default();
    let dir = scratch("every-kind");
    for kind in HierarchyKind::ALL {
        let name = kind.name();
        let file = file_of(kind);
        assert_eq!(
            file.header.kind, kind,
            "{name}: the builder wrote another kind"
        );
        // Written, every page read back as the server reads it (checked
        // against the directory) and made resident as the client keeps it
        // (decoded as the kind's page).
        let scene = write_and_open(&file, &dir.join(format!("{name}.ff")));
        assert_eq!(
            scene.corrupt_pages().len(),
            0,
            "{name}: {:?}",
            scene.corrupt_pages()
        );
        let h = scene.load_all().unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(h.resident_pages(), file.pages.len(), "{name}");
        let camera = Camera::orbit(
            h.header.root_center,
            h.header.root_radius,
            30.0,
            20.0,
            2.5,
            size.0,
            size.1,
        );
        let mut traversal = for_hierarchy(kind);
        traversal.traverse(&h, &camera, &TraversalOptions::default());
        assert!(
            traversal.wanted().is_empty(),
            "{name}: wants pages of a whole file"
        );
        let image = renderer
            .draw(&h, &camera, traversal.draw_list(), &style)
            .unwrap_or_else(|e| panic!("{name}: draw: {e:#}"));
        let background = style.background;
        let drawn = image
            .rgba
            .chunks_exact(4)
            .filter(|p| p[..3] != background)
            .count();
        let pixels = (size.0 * size.1) as usize;
        assert!(
            drawn * 20 > pixels,
            "{name}: {drawn} of {pixels} pixels drawn: the tree should cover more than 5 %"
        );
    }
}

/// Every kind's pages are stored compressed (most of them: a page that
/// would not shrink is stored as is). A compressed page damaged with its
/// checksums forged to match is refused whole when its first block's type
/// is changed, and decodes to no other length than its own wherever the
/// damage is.
#[test]
fn every_kind_stores_compressed_pages_and_refuses_damaged_streams() {
    use farfield_protocol::page::{PAGE_CHECKSUM_BYTES, PAGE_HEADER_BYTES, StoredPage};
    use farfield_protocol::page_codec::PageCodec;
    for kind in HierarchyKind::ALL {
        let name = kind.name();
        let file = file_of(kind);
        let h = &file.header;
        let mut compressed = 0;
        let (mut stored_bytes, mut decoded_bytes) = (0usize, 0usize);
        for (index, bytes) in file.pages.iter().enumerate() {
            let page = StoredPage::parse(bytes, index as u32, h.node_bytes).expect("a built page");
            stored_bytes += page.stored.len();
            decoded_bytes += page.decoded_len as usize;
            if page.codec != PageCodec::PlanesDeflate {
                continue;
            }
            compressed += 1;
            // Deflate's first byte holds its first block's type: flipped
            // bits there and mid-stream, resealed with a new checksum
            // in the page and the directory.
            for at in [PAGE_HEADER_BYTES, (PAGE_HEADER_BYTES + bytes.len()) / 2] {
                let mut bad = bytes.clone();
                bad[at] ^= 0x06;
                let end = bad.len() - PAGE_CHECKSUM_BYTES;
                let crc = crc32fast::hash(&bad[..end]);
                bad[end..].copy_from_slice(&crc.to_le_bytes());
                let mut client = crate::forged(&file, index, crc);
                if client.insert_page(index as u32, &bad).is_ok() {
                    // A change deflate cannot see (a literal's value)
                    // must still decode to the page's own length and
                    // pass every check of the kind's records.
                    let page = farfield_protocol::page::check_page(
                        &client.header,
                        client.directory(),
                        index as u32,
                        &bad,
                    )
                    .expect("inserted");
                    assert_eq!(
                        page.records().len() + page.payload().len(),
                        StoredPage::parse(bytes, index as u32, h.node_bytes)
                            .unwrap()
                            .decoded_len as usize,
                        "{name}: page {index} decoded to another length"
                    );
                } else {
                    assert!(!client.is_resident(index));
                    continue;
                }
                assert_ne!(
                    at, PAGE_HEADER_BYTES,
                    "{name}: page {index} with another first block type was accepted"
                );
            }
        }
        assert!(
            compressed * 2 >= file.pages.len(),
            "{name}: only {compressed} of {} pages compressed",
            file.pages.len()
        );
        assert!(
            stored_bytes < decoded_bytes,
            "{name}: {stored_bytes} bytes stored for {decoded_bytes} decoded"
        );
    }
}
