//! Image caching looks ahead: life spans counted along a known path (the
//! paper's offline estimate), and the pages of leaves about to enter the
//! view wanted before they do.

use std::collections::BTreeSet;

use farfield_protocol::bsp_codec::Split;
use farfield_protocol::camera::Camera;
use farfield_protocol::hierarchy::Hierarchy;
use farfield_traverse::bsp::box_culled;
use farfield_traverse::impostors::plan::{ImpostorCut, ImpostorOptions, Planner};
use glam::DVec3;

use crate::impostors::{island_file, orbit};
use crate::{resident, resident_where};

fn plan_with(
    planner: &mut Planner,
    h: &Hierarchy,
    camera: &Camera,
    options: ImpostorOptions,
) -> ImpostorCut {
    let mut cut = ImpostorCut::default();
    planner.plan(h, camera, &options, true, &mut cut);
    cut
}

fn at_epsilon(epsilon_px: f64) -> ImpostorOptions {
    ImpostorOptions {
        epsilon_px,
        atlas_side: 1024,
        ..ImpostorOptions::default()
    }
}

#[test]
fn a_known_path_decides_whether_a_cache_pays() {
    let file = island_file();
    let h = resident(&file);
    let camera = orbit(&h, 0);
    let made = |path: Option<Vec<DVec3>>| {
        let mut planner = Planner::default();
        if let Some(eyes) = path {
            planner.set_known_path(&eyes);
        }
        plan_with(&mut planner, &h, &camera, at_epsilon(2.0))
            .stats
            .caches_made
    };
    // Unknown, standing: the life span is the cap, caching pays.
    assert!(made(None) > 0);
    // Known to stay 50 frames: caching pays.
    assert!(made(Some(vec![camera.eye; 50])) > 0);
    // Known to jump far away next frame, or to end here: no cache lives a
    // frame, none is made (the motion, standing, would have made them).
    let far = camera.eye + DVec3::splat(h.header.root_radius * 10.0);
    assert_eq!(made(Some(vec![camera.eye, far])), 0);
    assert_eq!(made(Some(vec![camera.eye])), 0);
    // A viewer off the path falls back to its motion.
    assert!(made(Some(vec![far; 50])) > 0);
}

/// Leaf pages wanted by a frame whose leaves are culled by its view.
fn wanted_outside_the_view(h: &Hierarchy, camera: &Camera, cut: &ImpostorCut) -> usize {
    let s = h.bsp_skeleton().expect("page 0");
    let view = camera.view(1e-9);
    let outside: BTreeSet<u32> = s
        .nodes
        .iter()
        .filter_map(|n| match n.split {
            Split::Leaf { leaf } if box_culled(&view, n.box_min, n.box_max) => {
                Some(s.leaf_page(leaf))
            }
            _ => None,
        })
        .collect();
    let inside: BTreeSet<u32> = s
        .nodes
        .iter()
        .filter_map(|n| match n.split {
            Split::Leaf { leaf } if !box_culled(&view, n.box_min, n.box_max) => {
                Some(s.leaf_page(leaf))
            }
            _ => None,
        })
        .collect();
    cut.wanted
        .iter()
        .filter(|w| outside.contains(&w.page) && !inside.contains(&w.page))
        .count()
}

#[test]
fn leaves_about_to_enter_the_view_are_wanted_below_the_frame() {
    let file = island_file();
    // Only the skeleton: every leaf's page is missing.
    let h = resident_where(&file, |i| i == 0);
    // A narrow view of part of the island: many leaves just outside it.
    let camera = Camera {
        fov_y_deg: 20.0,
        ..orbit(&h, 0)
    };
    // ε = 0 draws every leaf in view as geometry and makes no cache, so
    // only the look-ahead can want a page outside the view.
    let off = ImpostorOptions {
        entering_pages: 0,
        ..at_epsilon(0.0)
    };
    let cut = plan_with(&mut Planner::default(), &h, &camera, off);
    assert_eq!(wanted_outside_the_view(&h, &camera, &cut), 0);
    let own = cut.wanted.len();
    assert!(own > 0, "the frame wants its own leaves");

    let on = at_epsilon(0.0);
    let cut = plan_with(&mut Planner::default(), &h, &camera, on);
    let entering = wanted_outside_the_view(&h, &camera, &cut);
    assert!(entering > 0, "no page of a leaf about to enter the view");
    assert!(entering <= on.entering_pages, "{entering} pages a frame");
    // Below every page the frame draws from.
    let lowest_own = cut
        .wanted
        .iter()
        .take(own)
        .map(|w| w.priority)
        .fold(f32::INFINITY, f32::min);
    let highest_entering = cut
        .wanted
        .iter()
        .skip(own)
        .map(|w| w.priority)
        .fold(0.0, f32::max);
    assert_eq!(cut.wanted.len(), own + entering);
    assert!(
        highest_entering < lowest_own,
        "{highest_entering} >= {lowest_own}"
    );
}
