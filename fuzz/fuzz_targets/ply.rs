//! The PLY importer, as `farfield-server build` runs it: load, validate,
//! and (for a small scene) build both hierarchies and read them back.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| farfield_fuzz::import("ply", data));
