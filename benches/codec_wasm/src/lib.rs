//! Exports for `run`: a buffer for a scene file's bytes, and a function
//! that checks and decodes every page of it, as the browser's client does
//! on arrival ([`Hierarchy::insert_page`] less the kind's node decoding:
//! what the page codec costs).
//!
//! No wasm-bindgen: plain `extern "C"` functions on numbers, so Node.js
//! loads the module with nothing but `WebAssembly.instantiate`.

use farfield_protocol::file::FileHeader;
use farfield_protocol::page::check_page;

/// A buffer of `len` bytes for the caller to fill; leaked on purpose (one
/// per run).
#[unsafe(no_mangle)]
pub extern "C" fn alloc(len: usize) -> *mut u8 {
    Box::leak(vec![0u8; len].into_boxed_slice()).as_mut_ptr()
}

/// Checks and decodes every page of the file in `ptr..ptr + len`;
/// returns the bytes decoded (records and payloads), or -1 when the file
/// or a page is refused.
///
/// # Safety
///
/// `ptr` and `len` must be a buffer from [`alloc`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn decode_pages(ptr: *const u8, len: usize) -> f64 {
    // SAFETY: the caller passes a buffer `alloc` made, of `len` bytes.
    let file = unsafe { std::slice::from_raw_parts(ptr, len) };
    let Ok(header) = FileHeader::decode(file) else {
        return -1.0;
    };
    let mut decoded = 0usize;
    for (index, entry) in header.pages.iter().enumerate() {
        let start = entry.offset as usize;
        let Some(bytes) = file.get(start..start + entry.length as usize) else {
            return -1.0;
        };
        match check_page(&header, index as u32, bytes) {
            Ok(page) => decoded += page.records().len() + page.payload().len(),
            Err(_) => return -1.0,
        }
    }
    decoded as f64
}
