//! GPU tests of the renderer; they run on llvmpipe/lavapipe without a GPU.

use farfield_protocol::camera::Camera;
use farfield_traverse::spheres::Splat;
use glam::{DVec3, Vec3};

use super::{Kernel, Renderer, SplatStyle, headless_or_skip};

const W: u32 = 64;
const H: u32 = 48;
const BG: [u8; 3] = [10, 20, 30];

fn renderer() -> Option<Renderer> {
    headless_or_skip(W, H).expect("no GPU adapter")
}

/// Eye at `eye` looking along +X, +Z up: image right is world -Y.
fn camera(eye: DVec3) -> Camera {
    Camera {
        eye,
        target: eye + DVec3::X,
        up: DVec3::Z,
        fov_y_deg: 60.0,
        width: W,
        height: H,
    }
}

/// Light toward the camera, so a splat facing the camera is fully lit.
fn style(kernel: Kernel) -> SplatStyle {
    SplatStyle {
        kernel,
        background: BG,
        light_dir: Vec3::NEG_X,
        two_sided: false,
        coverage: Default::default(),
        outline_caches: false,
        edl: None,
        color_by: Default::default(),
        clip: None,
    }
}

fn facing(center: DVec3, radius: f64, color: [u8; 3]) -> Splat {
    Splat {
        center,
        radius,
        normal: Some(Vec3::NEG_X),
        color: Some(color),
        node: 0,
    }
}

fn rgb(p: Option<[u8; 4]>) -> [u8; 3] {
    let p = p.expect("pixel inside the image");
    [p[0], p[1], p[2]]
}

fn close(a: [u8; 3], b: [u8; 3]) -> bool {
    a.iter().zip(b).all(|(x, y)| x.abs_diff(y) <= 1)
}

#[test]
fn nothing_gives_the_background() {
    let Some(mut r) = renderer() else { return };
    eprintln!("adapter: {}", r.adapter_description());
    let out = r
        .render(&camera(DVec3::ZERO), &[], &style(Kernel::Round))
        .unwrap();
    assert_eq!((out.width, out.height), (W, H));
    assert_eq!(out.rgba.len(), (W * H * 4) as usize);
    assert!(out.rgba.chunks(4).all(|p| p == [10, 20, 30, 255]));
}

#[test]
fn one_splat_covers_the_center_in_its_color() {
    let Some(mut r) = renderer() else { return };
    let splat = facing(DVec3::new(10.0, 0.0, 0.0), 3.0, [200, 50, 25]);
    let out = r
        .render(&camera(DVec3::ZERO), &[splat], &style(Kernel::Round))
        .unwrap();
    assert!(close(rgb(out.pixel(W / 2, H / 2)), [200, 50, 25]));
    for (x, y) in [(0, 0), (W - 1, 0), (0, H - 1), (W - 1, H - 1)] {
        assert_eq!(rgb(out.pixel(x, y)), BG, "corner {x},{y}");
    }
    // Lit from behind: only the ambient 0.3 remains.
    let back = SplatStyle {
        light_dir: Vec3::X,
        ..style(Kernel::Round)
    };
    let out = r.render(&camera(DVec3::ZERO), &[splat], &back).unwrap();
    assert!(close(rgb(out.pixel(W / 2, H / 2)), [60, 15, 8]));
    let two_sided = SplatStyle {
        two_sided: true,
        ..back
    };
    let out = r
        .render(&camera(DVec3::ZERO), &[splat], &two_sided)
        .unwrap();
    assert!(close(rgb(out.pixel(W / 2, H / 2)), [200, 50, 25]));
}

#[test]
fn nearer_splat_wins_in_either_order() {
    let Some(mut r) = renderer() else { return };
    let near = facing(DVec3::new(10.0, 0.0, 0.0), 2.0, [255, 0, 0]);
    let far = facing(DVec3::new(20.0, 0.0, 0.0), 8.0, [0, 0, 255]);
    for splats in [[near, far], [far, near]] {
        let out = r
            .render(&camera(DVec3::ZERO), &splats, &style(Kernel::Round))
            .unwrap();
        assert_eq!(rgb(out.pixel(W / 2, H / 2)), [255, 0, 0]);
        // Outside the near splat, the far one shows.
        assert_eq!(rgb(out.pixel(W / 2 + 12, H / 2)), [0, 0, 255]);
    }
}

#[test]
fn round_kernel_cuts_the_corners() {
    let Some(mut r) = renderer() else { return };
    // tan(30) * 10 = 5.77 units span H / 2 = 24 px: radius 3 is ~12.5 px.
    let splat = facing(DVec3::new(10.0, 0.0, 0.0), 3.0, [0, 255, 0]);
    let (x, y) = (W / 2 + 10, H / 2 - 10); // inside the square, outside the disc
    let square = r
        .render(&camera(DVec3::ZERO), &[splat], &style(Kernel::Square))
        .unwrap();
    let round = r
        .render(&camera(DVec3::ZERO), &[splat], &style(Kernel::Round))
        .unwrap();
    assert_eq!(rgb(square.pixel(x, y)), [0, 255, 0]);
    assert_eq!(rgb(round.pixel(x, y)), BG);
    assert_eq!(rgb(round.pixel(W / 2, H / 2)), [0, 255, 0]);
}

#[test]
fn image_is_upright_and_not_mirrored() {
    let Some(mut r) = renderer() else { return };
    // World +Z is up in the image; looking along +X, world -Y is to the right.
    let up = facing(DVec3::new(10.0, 0.0, 3.0), 1.0, [255, 0, 0]);
    let right = facing(DVec3::new(10.0, -3.0, 0.0), 1.0, [0, 255, 0]);
    let out = r
        .render(&camera(DVec3::ZERO), &[up, right], &style(Kernel::Round))
        .unwrap();
    let row_up = H / 2 - 12; // 3 / 5.77 * 24 px above the center
    let col_right = W / 2 + 12;
    assert_eq!(rgb(out.pixel(W / 2, row_up)), [255, 0, 0]);
    assert_eq!(rgb(out.pixel(W / 2, H - 1 - row_up)), BG);
    assert_eq!(rgb(out.pixel(col_right, H / 2)), [0, 255, 0]);
    assert_eq!(rgb(out.pixel(W - 1 - col_right, H / 2)), BG);
}

#[test]
fn spheres_are_lit_balls() {
    let Some(mut r) = renderer() else { return };
    let atom = Splat {
        center: DVec3::new(10.0, 0.0, 0.0),
        radius: 4.0,
        normal: None,
        color: None,
        node: 0,
    };
    // Light from above: the top of the ball is brighter than its bottom,
    // and the ball is round even with the square kernel.
    let above = SplatStyle {
        light_dir: Vec3::Z,
        ..style(Kernel::Square)
    };
    let out = r.render(&camera(DVec3::ZERO), &[atom], &above).unwrap();
    let top = rgb(out.pixel(W / 2, H / 2 - 12))[0];
    let bottom = rgb(out.pixel(W / 2, H / 2 + 12))[0];
    assert!(top > 150 && bottom < 70, "top {top}, bottom {bottom}");
    assert_eq!(rgb(out.pixel(W / 2 + 14, H / 2 - 14)), BG);
    // Headlight (zero direction): the center faces the light, full gray.
    let head = SplatStyle {
        light_dir: Vec3::ZERO,
        ..above
    };
    let out = r.render(&camera(DVec3::ZERO), &[atom], &head).unwrap();
    assert!(close(rgb(out.pixel(W / 2, H / 2)), [200, 200, 200]));
}

#[test]
fn sub_pixel_splats_still_cover_a_pixel() {
    let Some(mut r) = renderer() else { return };
    // A grid of 0.01 px splats, one per pixel column/row pitch: every pixel
    // must be covered, as with splats of one pixel.
    let per_px = 2.0 * (30f64).to_radians().tan() * 10.0 / f64::from(H);
    let mut splats = Vec::new();
    for i in -8..8 {
        for j in -8..8 {
            let offset = DVec3::new(0.0, f64::from(i) * per_px, f64::from(j) * per_px);
            splats.push(facing(
                DVec3::new(10.0, 0.0, 0.0) + offset,
                0.01 * per_px,
                [255, 255, 255],
            ));
        }
    }
    let out = r
        .render(&camera(DVec3::ZERO), &splats, &style(Kernel::Round))
        .unwrap();
    let lit = out.rgba.chunks(4).filter(|p| p[..3] != BG).count();
    assert!(lit >= 256, "{lit} pixels lit by 256 splats");
    assert_eq!(rgb(out.pixel(W / 2, H / 2)), [255, 255, 255]);
}

fn ring(center: DVec3) -> Vec<Splat> {
    (0..40)
        .map(|i| {
            let a = f64::from(i) * 0.3;
            let depth = 8.0 + f64::from(i % 7);
            facing(
                center + DVec3::new(depth, 3.0 * a.cos(), 2.0 * a.sin()),
                0.8 + 0.1 * f64::from(i % 5),
                [(i * 6) as u8, 255 - (i * 6) as u8, 128],
            )
        })
        .collect()
}

#[test]
fn chunked_draws_match_one_draw() {
    let Some(mut r) = renderer() else { return };
    let splats = ring(DVec3::ZERO);
    let whole = r
        .render(&camera(DVec3::ZERO), &splats, &style(Kernel::Round))
        .unwrap();
    r.set_chunk_splats(3);
    let chunked = r
        .render(&camera(DVec3::ZERO), &splats, &style(Kernel::Round))
        .unwrap();
    assert_eq!(whole.rgba, chunked.rgba);
    let covered = whole.rgba.chunks(4).filter(|p| p[..3] != BG).count();
    assert!(covered > 300, "{covered} pixels covered");
}

#[test]
fn far_from_the_origin_renders_as_at_the_origin() {
    let Some(mut r) = renderer() else { return };
    let base = DVec3::new(1.0e7, -2.5e7, 4.0e6);
    let here = r
        .render(
            &camera(DVec3::ZERO),
            &ring(DVec3::ZERO),
            &style(Kernel::Round),
        )
        .unwrap();
    let there = r
        .render(&camera(base), &ring(base), &style(Kernel::Round))
        .unwrap();
    let m = farfield_image::compare(&here.rgba, &there.rgba, W, H, 8).unwrap();
    assert!(m.wrong_fraction < 0.005, "{m:?}");
}

#[test]
fn resize_and_size_checks() {
    let Some(mut r) = renderer() else { return };
    assert_eq!(r.size(), (W, H));
    let mut cam = camera(DVec3::ZERO);
    cam.width = 33;
    cam.height = 17;
    let err = r.render(&cam, &[], &style(Kernel::Round)).unwrap_err();
    assert!(err.to_string().contains("resize"), "{err}");
    r.resize(33, 17);
    assert_eq!(r.size(), (33, 17));
    let out = r.render(&cam, &[], &style(Kernel::Round)).unwrap();
    assert_eq!(out.rgba.len(), 33 * 17 * 4);
    assert_eq!(out.pixel(32, 16), Some([10, 20, 30, 255]));
    assert_eq!(out.pixel(33, 0), None);
}

/// Eye-dome lighting darkens depth steps and outlines silhouettes, and
/// leaves flat parts and open background as they were: a square in front
/// of a wall in front of a bright background, along the middle row.
#[test]
fn eye_dome_lighting_outlines_depth_steps_and_leaves_flat_parts() {
    let Some(mut r) = renderer() else { return };
    let bright = [100, 150, 200];
    let splats = [
        facing(DVec3::new(20.0, 0.0, 0.0), 6.0, [200, 200, 200]),
        facing(DVec3::new(10.0, 0.0, 0.0), 1.5, [200, 200, 200]),
    ];
    let plain_style = SplatStyle {
        background: bright,
        ..style(Kernel::Square)
    };
    let edl_style = SplatStyle {
        edl: Some(crate::Edl::default()),
        ..plain_style
    };
    let cam = camera(DVec3::ZERO);
    let plain = r.render(&cam, &splats, &plain_style).unwrap();
    let shaded = r.render(&cam, &splats, &edl_style).unwrap();
    let row = |out: &crate::RenderOutput| -> Vec<[u8; 3]> {
        (0..W).map(|x| rgb(out.pixel(x, H / 2))).collect()
    };
    let (plain_row, shaded_row) = (row(&plain), row(&shaded));
    let dark = |p: &[u8; 3]| p.iter().map(|&c| u32::from(c)).sum::<u32>() < 90;
    assert!(!plain_row.iter().any(dark), "plain: {plain_row:?}");
    // Where the row crosses the square's edges (at about 25 and 38) and
    // the wall's (19 and 44).
    let darkened: Vec<u32> = (0..W).filter(|&x| dark(&shaded_row[x as usize])).collect();
    let (square, wall) = (
        darkened.iter().filter(|&&x| (22..42).contains(&x)).count(),
        darkened.len(),
    );
    assert!(square >= 2, "the square's edges: dark at {darkened:?}");
    assert!(
        wall - square >= 2,
        "the wall's silhouette: dark at {darkened:?}"
    );
    // Flat parts and open background keep their color.
    for x in [W / 2, W / 2 + 1, 1, W - 2] {
        let (a, b) = (plain_row[x as usize], shaded_row[x as usize]);
        assert!(close(a, b), "x {x}: {a:?} became {b:?}");
    }
    assert!(darkened.len() < 12, "dark at {darkened:?}");
}

/// Paraboloid splats meet along the line where their depths cross: two of
/// one depth, overlapping, split the overlap between them, where flat
/// discs give it all to the one drawn first.
#[test]
fn paraboloid_splats_split_their_overlap() {
    let Some(mut r) = renderer() else { return };
    let (red, blue) = ([220, 30, 30], [30, 30, 220]);
    // Image right is world -Y: red left of the middle, blue right of it.
    let splats = [
        facing(DVec3::new(10.0, 1.0, 0.0), 1.5, red),
        facing(DVec3::new(10.0, -1.0, 0.0), 1.5, blue),
    ];
    let cam = camera(DVec3::ZERO);
    let flat = r.render(&cam, &splats, &style(Kernel::Round)).unwrap();
    let curved = r.render(&cam, &splats, &style(Kernel::Paraboloid)).unwrap();
    let at = |out: &crate::RenderOutput, x: u32| rgb(out.pixel(x, H / 2));
    // Left and right of the middle, inside the overlap (columns 30 to 34).
    assert!(close(at(&flat, W / 2 - 1), red) && close(at(&flat, W / 2 + 1), red));
    assert!(
        close(at(&curved, W / 2 - 1), red),
        "{:?}",
        at(&curved, W / 2 - 1)
    );
    assert!(
        close(at(&curved, W / 2 + 1), blue),
        "{:?}",
        at(&curved, W / 2 + 1)
    );
    // Away from the overlap both kernels draw the same.
    for x in [W / 2 - 6, W / 2 + 6] {
        assert_eq!(at(&flat, x), at(&curved, x), "column {x}");
    }
}
