//! A whole scene file: `FileHeader::decode` (and `peek_len`), the file read
//! into a hierarchy (`read_image`: every page verified and inserted), and
//! the server's `SceneFile::open` of the same bytes on disk with its page
//! reads; every hierarchy that results is decoded and traversed.
//!
//! Input: one mode byte, then the file. Unless the mode's low bit is set,
//! the checksums are recomputed first (pages the directory places, then
//! the header), so mutations get past them to the checks behind.
#![no_main]

use farfield_protocol::file::FileHeader;
use farfield_protocol::hierarchy::Hierarchy;
use farfield_protocol::paged_file::read_image;
use farfield_store::SceneFile;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&mode, file)) = data.split_first() else {
        return;
    };
    let mut bytes = file.to_vec();
    if mode & 1 == 0 {
        farfield_fuzz::fix_file_checksums(&mut bytes);
    }
    let _ = FileHeader::peek_len(&bytes);
    if let Ok(header) = FileHeader::decode(&bytes) {
        let encoded = header.encode();
        let again = FileHeader::decode(&encoded).expect("a re-encoded header decodes");
        assert_eq!(again, header, "a header survives encoding");
        if let Ok(mut h) = Hierarchy::new(header) {
            // The root directory page from the bytes, as a client gets it.
            let root = h.header.root_directory;
            if let Some(root_bytes) = usize::try_from(root.offset).ok().and_then(|start| {
                bytes.get(start..start.checked_add(root.length as usize)?)
            }) {
                let _ = h.insert_page(h.header.page_count, root_bytes);
            }
            let nodes = h.header.nodes;
            for node in [0, nodes / 2, nodes.saturating_sub(1), nodes] {
                let _ = h.directory().locate(node);
            }
            let _ = h.directory().file_len();
            farfield_fuzz::exercise(&h);
        }
    }
    if let Ok(h) = read_image(&bytes) {
        farfield_fuzz::exercise(&h);
    }
    let path = farfield_fuzz::scratch_file("ff", &bytes);
    if let Ok(scene) = SceneFile::open(&path) {
        let _ = scene.corrupt_pages();
        if let Ok(h) = scene.load_all() {
            farfield_fuzz::exercise(&h);
        }
    }
});
