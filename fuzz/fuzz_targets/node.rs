//! The node decoders on arbitrary records: a sphere node
//! (`NodeRecord::unpack` in every layout, then the sphere, normal, cone
//! and color codes, the sphere code only where `insert_page` would accept
//! it), and a color-cube cell (`CubeRecord::unpack`, `decode_payload`:
//! sub-cubes and leaf geometry, and octahedral leaf normals). What decodes
//! must encode back to the same bytes.
//!
//! Input: a flags byte (bit 0: cube cell, else sphere records; bits 1-2:
//! color, normals; bit 7: keep the record's payload length as it is
//! instead of setting it to the payload's), the cluster size, then sphere
//! records back to back, or one cube record and its payload.
#![no_main]

use farfield_protocol::cube_codec::Channels;
use farfield_protocol::cube_codec::{
    CubeRecord, RECORD_BYTES, decode_payload, encode_payload, valid_cluster,
};
use farfield_protocol::octahedral::unpack_normal;
use farfield_protocol::sphere_codec::{
    self, NORMAL_CODES, NodeLayout, NodeRecord, cone_half_angle, decode_color, decode_normal,
    decode_sphere,
};
use glam::DVec3;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((head, body)) = data.split_at_checked(2) else {
        return;
    };
    let (flags, cluster) = (head[0], head[1]);
    let (color, normals) = (flags & 2 != 0, flags & 4 != 0);
    if flags & 1 == 0 {
        spheres(NodeLayout { normals, color }, body);
    } else {
        cube(
            Channels { normals, color },
            cluster,
            flags & 0x80 == 0,
            body,
        );
    }
});

fn spheres(layout: NodeLayout, body: &[u8]) {
    let node_bytes = layout.bytes() as usize;
    let codes = sphere_codec::sphere_table().len();
    let (mut center, mut radius) = (DVec3::ZERO, 1.0);
    for chunk in body.chunks(node_bytes) {
        let mut word = [0u8; 8];
        word[..chunk.len()].copy_from_slice(chunk);
        let word = u64::from_le_bytes(word);
        let record = NodeRecord::unpack(word, layout);
        assert_eq!(NodeRecord::unpack(record.pack(layout), layout), record);
        assert_eq!(NodeRecord::child_count(word), record.children.get());
        let _ = decode_normal(record.normal);
        let _ = cone_half_angle(record.cone);
        let _ = decode_color(record.color);
        // As `insert_page` checks every record before traversal decodes it.
        if usize::from(record.sphere) < codes && u32::from(record.normal) < NORMAL_CODES {
            let (c, r) = decode_sphere(center, radius, record.sphere);
            assert!(r <= radius && c.distance(center) + r <= radius * (1.0 + 1e-9));
            // Descend: each record is the child of the one before (from the
            // root again once the radius is too small beside the center for
            // the check above to be exact enough).
            (center, radius) = if r > 1e-6 { (c, r) } else { (DVec3::ZERO, 1.0) };
        }
    }
}

fn cube(channels: Channels, cluster: u8, set_length: bool, body: &[u8]) {
    let Some((record, payload)) = body.split_at_checked(RECORD_BYTES) else {
        let _ = CubeRecord::unpack(body);
        return;
    };
    let Some(mut record) = CubeRecord::unpack(record) else {
        return;
    };
    assert_eq!(&record.pack()[..], &body[..RECORD_BYTES]);
    if set_length {
        record.payload_bytes = payload.len() as u32;
    }
    let _ = record.child_count();
    if !valid_cluster(cluster) {
        // The header check refuses such a file before any payload is read.
        return;
    }
    let Ok(decoded) = decode_payload(&record, payload, cluster, channels) else {
        return;
    };
    for s in &decoded.sub_cubes {
        let _ = s.coords(cluster);
    }
    if let Some(g) = &decoded.geometry {
        for &n in g.normals.iter().flatten() {
            let _ = unpack_normal(n);
        }
    }
    let encoded = encode_payload(&decoded.sub_cubes, decoded.geometry.as_ref());
    assert_eq!(encoded, payload, "a decoded payload encodes to its bytes");
}
