//! The LAS/LAZ importer (one reader for both: the header's point format
//! says whether the points are compressed), as `farfield-server build`
//! runs it: load, validate, and (for a small cloud) build both hierarchies
//! and read them back. A panic inside the LAZ decompressor that the
//! importer catches (and reports as corrupt data) is not a finding; one
//! that escapes the importer is.
#![no_main]

use std::panic::{AssertUnwindSafe, catch_unwind};

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    farfield_fuzz::allow_caught_laz_panics();
    if catch_unwind(AssertUnwindSafe(|| farfield_fuzz::import("las", data))).is_err() {
        // Only a panic inside laz unwinds this far (any other aborts in the
        // hook): the importer let it out. Abort, so libFuzzer keeps the input.
        eprintln!("farfield-fuzz: a panic inside laz escaped the importer");
        std::process::abort();
    }
});
