use super::*;

fn origin() -> DVec3 {
    DVec3::new(100.0, -50.0, 3.0)
}

/// A root split on direction 0 with two leaves, one prototype.
fn small() -> BspSkeleton {
    let b = |lo: f64, hi: f64| (DVec3::splat(lo) + origin(), DVec3::splat(hi) + origin());
    let node = |(box_min, box_max): (DVec3, DVec3), triangles, split| BspNode {
        box_min,
        box_max,
        triangles,
        split,
    };
    BspSkeleton {
        directions: vec![DVec3::X, DVec3::Y],
        nodes: vec![
            node(
                b(-2.0, 2.0),
                30,
                Split::Plane {
                    direction: 0,
                    offset: 0.5,
                    back: 1,
                    front: 2,
                },
            ),
            node(b(-2.0, 0.5), 10, Split::Leaf { leaf: 1 }),
            node(b(0.5, 2.0), 20, Split::Leaf { leaf: 0 }),
        ],
        prototypes: vec![PrototypeInfo {
            triangles: 7,
            box_min: DVec3::new(-1.0, -1.0, 0.0),
            box_max: DVec3::new(1.0, 1.0, 4.0),
        }],
        leaves: 2,
        scene_triangles: 30,
        inflation: 0.17,
    }
}

#[test]
fn the_skeleton_round_trips_with_its_boxes_rounded_outward() {
    let s = small();
    let bytes = s.encode(origin());
    let back = BspSkeleton::decode(&bytes, origin(), 3).expect("decodes");
    assert_eq!(back.directions, s.directions);
    assert_eq!(back.prototypes, s.prototypes);
    assert_eq!((back.leaves, back.scene_triangles), (2, 30));
    assert_eq!(back.inflation, 0.17);
    for (a, b) in back.nodes.iter().zip(&s.nodes) {
        assert_eq!((a.split, a.triangles), (b.split, b.triangles));
        assert!(a.box_min.cmple(b.box_min).all() && a.box_max.cmpge(b.box_max).all());
        assert!((a.box_min - b.box_min).abs().max_element() < 1e-4);
    }
    assert_eq!(back.leaf_page(0), 2);
    assert_eq!(BspSkeleton::prototype_page(0), 1);
    // A box that does not fit f32 exactly still holds its corner.
    let mut odd = small();
    odd.nodes[1].box_max = origin() + DVec3::splat(0.1);
    let back = BspSkeleton::decode(&odd.encode(origin()), origin(), 3).unwrap();
    assert!(back.nodes[1].box_max.cmpge(odd.nodes[1].box_max).all());
    // An empty node stays empty.
    let mut empty = small();
    empty.nodes[2].box_min = DVec3::INFINITY;
    empty.nodes[2].box_max = DVec3::NEG_INFINITY;
    let back = BspSkeleton::decode(&empty.encode(origin()), origin(), 3).unwrap();
    assert_eq!(back.nodes[2].box_min, DVec3::INFINITY);
}

#[test]
fn bad_skeletons_are_refused() {
    let good = small();
    let refuse = |s: &BspSkeleton, children: u64, why: &str| {
        let e = BspSkeleton::decode(&s.encode(origin()), origin(), children);
        assert!(e.is_err(), "{why}: {e:?}");
    };
    refuse(&good, 4, "more pages than prototypes and leaves");
    let mut cycle = good.clone();
    cycle.nodes[1].split = Split::Plane {
        direction: 0,
        offset: 0.0,
        back: 0,
        front: 2,
    };
    refuse(&cycle, 3, "a child before its parent");
    let mut twice = good.clone();
    twice.nodes[2].split = Split::Leaf { leaf: 1 };
    refuse(&twice, 3, "a leaf twice");
    let mut dir = good.clone();
    dir.nodes[0].split = Split::Plane {
        direction: 2,
        offset: 0.0,
        back: 1,
        front: 2,
    };
    refuse(&dir, 3, "a direction out of range");
    let mut short = good.clone();
    short.directions[1] = DVec3::new(0.0, 0.5, 0.0);
    refuse(&short, 3, "a direction that is not unit");
    let mut nan = good.clone();
    nan.nodes[1].box_min.x = f64::NAN;
    refuse(&nan, 3, "a NaN box");
    let bytes = good.encode(origin());
    for cut in [0, 10, bytes.len() - 1] {
        assert!(
            BspSkeleton::decode(&bytes[..cut], origin(), 3).is_err(),
            "{cut}"
        );
    }
    let mut longer = bytes.clone();
    longer.push(0);
    assert!(BspSkeleton::decode(&longer, origin(), 3).is_err());
}

#[test]
fn content_pages_round_trip_and_bad_ones_are_refused() {
    let triangle = FlatTriangle {
        corners: [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.5]],
        rgba: [10, 20, 30, 255],
    };
    let leaf = LeafPage {
        leaf: 4,
        anchor: DVec3::new(1e6, 2.0, -3.0),
        own_triangles: 2,
        own_placements: 1,
        triangles: vec![triangle; 3],
        placements: vec![Placement {
            prototype: 0,
            matrix: [[0.0, 2.0, 0.0], [-2.0, 0.0, 0.0], [0.0, 0.0, 2.0]],
            translation: [5.0, 6.0, 7.0],
        }],
    };
    let (record, payload) = leaf.encode();
    assert_eq!(
        ContentPage::decode(&record, &payload),
        Ok(ContentPage::Leaf(leaf.clone()))
    );
    let world = leaf.placements[0].world_from_local(leaf.anchor);
    let p = world.transform_point3(DVec3::X);
    assert_eq!(p, DVec3::new(1e6 + 5.0, 2.0 + 6.0 + 2.0, -3.0 + 7.0));
    let proto = PrototypePage {
        prototype: 2,
        triangles: vec![triangle],
    };
    let (record, payload) = proto.encode();
    assert_eq!(
        ContentPage::decode(&record, &payload),
        Ok(ContentPage::Prototype(proto))
    );
    // Truncated, padded, mislabelled, or a NaN corner: refused.
    let (record, payload) = leaf.encode();
    assert!(ContentPage::decode(&record, &payload[..payload.len() - 1]).is_err());
    let mut padded = payload.clone();
    padded.extend_from_slice(&[0; 4]);
    assert!(ContentPage::decode(&record, &padded).is_err());
    let mut tag = record.clone();
    tag[0] = 9;
    assert!(ContentPage::decode(&tag, &payload).is_err());
    assert!(ContentPage::decode(&record[..4], &payload).is_err());
    let mut nan = payload.clone();
    nan[40..44].copy_from_slice(&f32::NAN.to_le_bytes());
    assert!(ContentPage::decode(&record, &nan).is_err());
    // More own triangles or placements than stored: refused.
    for at in [32, 36] {
        let mut own = payload.clone();
        own[at..at + 4].copy_from_slice(&9u32.to_le_bytes());
        assert!(ContentPage::decode(&record, &own).is_err(), "{at}");
    }
    // A count that would overflow is refused, not allocated.
    let mut huge = payload.clone();
    huge[24..28].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(ContentPage::decode(&record, &huge).is_err());
}
