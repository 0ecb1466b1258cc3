//! The LAS/LAZ importer (one reader for both: the header's point format
//! says whether the points are compressed), as `farfield-server build`
//! runs it: load, validate, and (for a small cloud) build both hierarchies
//! and read them back. A panic inside the LAZ decompressor that the
//! importer catches (and reports as corrupt data) is not a finding.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    farfield_fuzz::allow_caught_laz_panics();
    farfield_fuzz::import("las", data);
});
