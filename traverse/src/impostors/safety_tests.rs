use super::*;
use proptest::prelude::*;

/// The eight corners of the box `centre ± half`.
fn corners(centre: DVec3, half: DVec3) -> Vec<DVec3> {
    (0..8)
        .map(|i| {
            let s = DVec3::new(
                if i & 1 != 0 { 1.0 } else { -1.0 },
                if i & 2 != 0 { 1.0 } else { -1.0 },
                if i & 4 != 0 { 1.0 } else { -1.0 },
            );
            centre + s * half
        })
        .collect()
}

/// `n` directions spread over the unit sphere (a Fibonacci lattice).
fn directions(n: usize) -> Vec<DVec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = golden * i as f64;
            DVec3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

/// Formula (4) exactly as printed: `h = |v0 − a|` and a subtraction.
fn printed_radius(v0: DVec3, a: DVec3, a_tilde: DVec3, epsilon: f64) -> f64 {
    let h = v0.distance(a);
    let r = a.distance(a_tilde) / (2.0 * epsilon.sin());
    (h * h + r * r + 2.0 * h * r * epsilon.sin()).sqrt() - r
}

#[test]
fn a_corner_shows_on_the_quad_along_its_ray_and_the_error_starts_at_zero() {
    let eye = DVec3::new(1.0, 2.0, 3.0);
    let quad = QuadPlane::new(eye, DVec3::new(0.0, 2.0, 0.0), DVec3::new(4.0, 12.0, 5.0))
        .expect("in front");
    assert_eq!(quad.depth, 10.0);
    let box_corners = corners(DVec3::new(4.0, 12.0, 5.0), DVec3::new(1.0, 2.0, 1.5));
    for &a in &box_corners {
        let t = quad.project(a).expect("in front");
        assert!(
            ((t - eye).dot(quad.forward) - 10.0).abs() < 1e-12,
            "on the plane"
        );
        assert!((t - eye).cross(a - eye).length() < 1e-9, "on the ray");
    }
    assert!(error(&quad, &box_corners, eye).unwrap() < 1e-12);
    assert!(error(&quad, &box_corners, eye + DVec3::X).unwrap() > 1e-3);
    // Behind the eye: no quad, no image.
    assert!(QuadPlane::new(eye, DVec3::Y, eye - DVec3::Y).is_none());
    assert!(QuadPlane::new(eye, DVec3::ZERO, DVec3::Y).is_none());
    assert!(quad.project(eye - DVec3::Y).is_none());
    let behind = [eye - DVec3::Y * 3.0];
    assert_eq!(error(&quad, &behind, eye), None);
    assert_eq!(safety_zone(&quad, &behind, 0.01), None);
}

#[test]
fn small_angles_keep_their_digits() {
    let theta = angle(DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1e-12, 0.0));
    assert!((theta - 1e-12).abs() < 1e-24, "{theta}");
    assert_eq!(angle(DVec3::X, DVec3::X, DVec3::Y), 0.0);
    let right = angle(DVec3::ZERO, DVec3::X, DVec3::Y);
    assert!((right - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
}

proptest! {
    /// The defining property of a safety zone: from every eye inside the
    /// sphere of the smallest corner radius (so inside its inscribed
    /// cube), no corner is more than ε from its image.
    #[test]
    fn eyes_inside_the_safety_sphere_see_at_most_epsilon(
        cx in -50.0f64..50.0, cy in -50.0f64..50.0, cz in 20.0f64..400.0,
        hx in 0.01f64..30.0, hy in 0.01f64..30.0, hz in 0.0f64..30.0,
        tilt_x in -0.3f64..0.3, tilt_y in -0.3f64..0.3,
        epsilon in 1e-5f64..0.2,
    ) {
        let centre = DVec3::new(cx, cy, cz);
        let half = DVec3::new(hx, hy, hz.min(cz * 0.5));
        let box_corners = corners(centre, half);
        let forward = (centre + DVec3::new(tilt_x, tilt_y, 0.0) * cz).normalize();
        let quad = QuadPlane::new(DVec3::ZERO, forward, centre).expect("centre ahead");
        prop_assume!(box_corners.iter().all(|&a| quad.project(a).is_some()));
        let d = box_corners
            .iter()
            .map(|&a| safety_radius(DVec3::ZERO, a, quad.project(a).unwrap(), epsilon))
            .fold(f64::INFINITY, f64::min);
        prop_assert!(d > 0.0 && d.is_finite(), "{d}");
        let zone = safety_zone(&quad, &box_corners, epsilon).unwrap();
        for v in directions(200) {
            for reach in [0.25, 0.75, 0.999] {
                let eye = v * d * reach;
                let e = error(&quad, &box_corners, eye).unwrap();
                prop_assert!(e <= epsilon * (1.0 + 1e-9), "{e} > {epsilon} at {eye}");
            }
        }
        // The cube is inside the sphere: its corners are safe too.
        for c in corners((zone.min + zone.max) * 0.5, (zone.max - zone.min) * 0.4999) {
            prop_assert!(zone.contains(c));
            prop_assert!(error(&quad, &box_corners, c).unwrap() <= epsilon * (1.0 + 1e-9));
        }
    }
}

/// Section 3's formula (4) with `h = |v0 − a|`: for a corner behind the
/// quad the chord's nearer end is `ã`, the printed radius is too large,
/// and an eye inside it sees the corner more than ε from its image. With
/// the nearer end, every eye inside is within ε.
#[test]
fn behind_the_quad_the_printed_radius_is_unsafe_and_ours_is_not() {
    let v0 = DVec3::ZERO;
    let quad = QuadPlane::new(v0, DVec3::X, DVec3::new(10.0, 0.0, 0.0)).unwrap();
    let a = DVec3::new(14.0, 4.0, 0.0);
    let a_tilde = quad.project(a).unwrap();
    assert!(
        a.distance(v0) > a_tilde.distance(v0),
        "the corner is behind the quad"
    );
    let epsilon = 0.01;
    let printed = printed_radius(v0, a, a_tilde, epsilon);
    let ours = safety_radius(v0, a, a_tilde, epsilon);
    assert!(printed > ours * 1.05, "printed {printed}, ours {ours}");
    let worst_within = |radius: f64| {
        directions(20_000)
            .into_iter()
            .map(|dir| angle(v0 + dir * radius * 0.999, a, a_tilde))
            .fold(0.0, f64::max)
    };
    let unsafe_worst = worst_within(printed);
    assert!(
        unsafe_worst > epsilon,
        "{unsafe_worst} within the printed radius"
    );
    let safe_worst = worst_within(ours);
    assert!(safe_worst <= epsilon, "{safe_worst} within ours");
    // In front of the quad the two agree.
    let front = DVec3::new(7.0, 3.0, 0.0);
    let front_tilde = quad.project(front).unwrap();
    let (p, o) = (
        printed_radius(v0, front, front_tilde, epsilon),
        safety_radius(v0, front, front_tilde, epsilon),
    );
    assert!((p - o).abs() < 1e-9 * o, "{p} against {o}");
}

/// As ε goes to 0, `r` grows as 1/ε and the printed `sqrt(...) − r`
/// subtracts two nearly equal numbers; ours keeps its digits against the
/// leading term `d ≈ sin ε · h (h + m) / m`.
#[test]
fn as_epsilon_goes_to_zero_the_radius_keeps_its_digits() {
    let v0 = DVec3::ZERO;
    let a = DVec3::new(9.0, 2.0, 1.0);
    let quad = QuadPlane::new(v0, DVec3::X, DVec3::new(10.0, 0.0, 0.0)).unwrap();
    let a_tilde = quad.project(a).unwrap();
    let (h, m) = (a.length(), a.distance(a_tilde));
    for epsilon in [1e-7_f64, 1e-9, 1e-11] {
        let expected = epsilon.sin() * h * (h + m) / m;
        let ours = safety_radius(v0, a, a_tilde, epsilon);
        let printed = printed_radius(v0, a, a_tilde, epsilon);
        assert!(
            ((ours - expected) / expected).abs() < 1e-9,
            "ε {epsilon}: {ours} against {expected}"
        );
        assert!(
            ((printed - expected) / expected).abs() > 1e-6,
            "ε {epsilon}: the printed form kept its digits ({printed})"
        );
    }
}

#[test]
fn epsilon_zero_never_caches_and_a_huge_one_stays_bounded() {
    let quad = QuadPlane::new(DVec3::ZERO, DVec3::Z, DVec3::new(0.0, 0.0, 50.0)).unwrap();
    let box_corners = corners(DVec3::new(0.0, 0.0, 50.0), DVec3::splat(5.0));
    for epsilon in [0.0, -1.0, f64::NAN] {
        let zone = safety_zone(&quad, &box_corners, epsilon).unwrap();
        assert!(zone.is_empty() && !zone.contains(DVec3::ZERO), "{epsilon}");
        assert_eq!(
            zone.frames_until_exit(DVec3::ZERO, DVec3::ZERO, DVec3::ZERO, 99),
            0
        );
    }
    for epsilon in [1.0, 10.0, 1e300, f64::INFINITY] {
        let zone = safety_zone(&quad, &box_corners, epsilon).unwrap();
        assert!(zone.contains(DVec3::ZERO), "{epsilon}");
        assert!(
            zone.min.is_finite() && zone.max.is_finite(),
            "{epsilon}: {zone:?}"
        );
        // No wider than the sphere of the nearest corner's distance.
        assert!(
            (zone.max - zone.min).max_element() <= 2.0 * 50.0,
            "{zone:?}"
        );
    }
}

/// A flat node, its corners on the quad: the image is exact from
/// everywhere, and the zone is still finite (the radius is the corner's
/// distance).
#[test]
fn a_flat_node_has_no_error_and_a_finite_zone() {
    let centre = DVec3::new(0.0, 0.0, 30.0);
    let quad = QuadPlane::new(DVec3::ZERO, DVec3::Z, centre).unwrap();
    let flat = corners(centre, DVec3::new(4.0, 3.0, 0.0));
    for v in [DVec3::new(20.0, -7.0, 2.0), DVec3::new(0.0, 0.0, 29.0)] {
        assert!(error(&quad, &flat, v).unwrap() < 1e-12);
    }
    let zone = safety_zone(&quad, &flat, 0.001).unwrap();
    let nearest = flat
        .iter()
        .map(|c| c.length())
        .fold(f64::INFINITY, f64::min);
    let half = (zone.max - zone.min) * 0.5;
    assert!((half.x - nearest / 3f64.sqrt()).abs() < 1e-9, "{zone:?}");
}

#[test]
fn zones_intersect_into_a_box_or_nothing() {
    let a = Zone::around(DVec3::ZERO, 3f64.sqrt());
    assert_eq!((a.min, a.max), (DVec3::splat(-1.0), DVec3::splat(1.0)));
    let b = Zone::around(DVec3::splat(1.5), 3f64.sqrt());
    let both = a.intersect(&b);
    assert_eq!((both.min, both.max), (DVec3::splat(0.5), DVec3::splat(1.0)));
    let far = Zone::around(DVec3::splat(5.0), 3f64.sqrt());
    assert!(a.intersect(&far).is_empty());
    assert!(Zone::EMPTY.intersect(&a).is_empty());
    assert!(!a.intersect(&far).contains(DVec3::splat(0.9)));
}

#[test]
fn life_spans_follow_the_motion_and_a_standing_viewer_is_capped() {
    let zone = Zone {
        min: DVec3::splat(-10.5),
        max: DVec3::splat(10.5),
    };
    let (zero, cap) = (DVec3::ZERO, 500);
    assert_eq!(zone.frames_until_exit(zero, zero, zero, cap), cap);
    // One unit a frame along x: in for frames 1..=10, out at 10.5.
    assert_eq!(zone.frames_until_exit(zero, DVec3::X, zero, cap), 10);
    assert_eq!(zone.frames_until_exit(zero, -DVec3::X * 2.0, zero, cap), 5);
    // Slowing down and turning back: x = t − t²/4 peaks at 1, then leaves
    // through −10.5 at t = 2 + sqrt(46).
    let turning = zone.frames_until_exit(zero, DVec3::X, DVec3::X * -0.5, cap);
    assert_eq!(turning, (2.0 + 46f64.sqrt()).floor() as u32);
    // Already outside, or a fast viewer: no frame at all.
    assert_eq!(
        zone.frames_until_exit(DVec3::splat(11.0), zero, zero, cap),
        0
    );
    assert_eq!(zone.frames_until_exit(zero, DVec3::Y * 100.0, zero, cap), 0);
    // The cap holds for a slow one.
    assert_eq!(
        zone.frames_until_exit(zero, DVec3::Z * 1e-9, zero, cap),
        cap
    );
}

#[test]
fn epsilon_in_pixels_is_the_angle_those_pixels_subtend_at_the_centre() {
    for (px, fov, height) in [(1.0, 60.0, 480), (2.0, 45.0, 480), (8.0, 90.0, 1080)] {
        let theta = epsilon_angle(px, fov, height);
        let tan_half = (f64::to_radians(fov) / 2.0).tan();
        let back = (theta / 2.0).tan() * f64::from(height) / tan_half;
        assert!(
            (back - px).abs() < 1e-9,
            "{px} px -> {theta} rad -> {back} px"
        );
    }
    assert_eq!(epsilon_angle(0.0, 60.0, 480), 0.0);
    assert_eq!(epsilon_angle(2.0, 0.0, 480), 0.0);
    assert_eq!(epsilon_angle(2.0, 60.0, 0), 0.0);
    assert_eq!(epsilon_angle(f64::NAN, 60.0, 480), 0.0);
}
