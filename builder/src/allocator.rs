//! [`HugePageAlloc`]: the system allocator, asking Linux for transparent
//! huge pages on large blocks; [`drop_releasing`]: a free that returns its
//! pages.
//!
//! A build streams arrays of hundreds of megabytes (leaves, interior nodes,
//! triangles) in every step. With 4 KiB pages each of those costs one page
//! fault per 4 KiB on first touch and misses the TLB on nearly every
//! scattered read; with 2 MiB pages both nearly vanish. Most Linux systems
//! ship transparent huge pages in `madvise` mode, where a program has to ask
//! (`madvise(MADV_HUGEPAGE)`), so this allocator asks for every block of
//! [`HUGE_MIN`] bytes or more. Measured on `gen:island size=2048 trees=256`
//! (13.6 M vertices): the build ran about 15 % faster, with peak memory
//! within 1.2 %. Elsewhere, or where the kernel says no, nothing changes.
//!
//! Binaries opt in with `#[global_allocator]`; the library never does.
//!
//! [`drop_releasing`] frees a buffer and hands its pages back to the kernel
//! at once, for the one place where memory the allocator would keep idle
//! raises the build's peak.

use std::alloc::{GlobalAlloc, Layout, System};

/// Blocks at least this large ask for huge pages: below one huge page
/// there is nothing to gain.
pub const HUGE_MIN: usize = 2 << 20;

/// The system allocator plus a huge-page request on large blocks.
#[derive(Debug, Default, Clone, Copy)]
pub struct HugePageAlloc;

// SAFETY: every call is forwarded unchanged to `System`, which upholds the
// `GlobalAlloc` contract; `advise` only changes how the kernel backs memory
// the block already owns, never its contents or its extent.
unsafe impl GlobalAlloc for HugePageAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's guarantees for `layout` are passed on.
        let block = unsafe { System.alloc(layout) };
        advise(block, layout.size());
        block
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as for `alloc`.
        let block = unsafe { System.alloc_zeroed(layout) };
        advise(block, layout.size());
        block
    }

    unsafe fn dealloc(&self, block: *mut u8, layout: Layout) {
        // SAFETY: `block` came from `System` through this allocator.
        unsafe { System.dealloc(block, layout) }
    }

    unsafe fn realloc(&self, block: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: as for `dealloc`, with the caller's guarantees on `new_size`.
        let moved = unsafe { System.realloc(block, layout, new_size) };
        advise(moved, new_size);
        moved
    }
}

/// The system's memory page size, if it reports a sensible one.
pub fn page_size() -> Option<usize> {
    // SAFETY: `sysconf` has no preconditions.
    let size = unsafe { libc::sysconf(libc::_SC_PAGESIZE) };
    usize::try_from(size).ok().filter(|&s| s > 0)
}

/// The first and end address of the whole pages inside `len` bytes at
/// `block`, if there are any.
#[cfg(target_os = "linux")]
fn whole_pages(block: *mut u8, len: usize) -> Option<(usize, usize)> {
    let page = page_size()?;
    let start = (block as usize).next_multiple_of(page);
    let end = (block as usize + len) / page * page;
    (end > start).then_some((start, end))
}

/// Asks for huge pages on the whole pages inside `len` bytes at `block`.
#[cfg(target_os = "linux")]
fn advise(block: *mut u8, len: usize) {
    if block.is_null() || len < HUGE_MIN {
        return;
    }
    if let Some((start, end)) = whole_pages(block, len) {
        // SAFETY: `start..end` lies inside the block just allocated, and
        // MADV_HUGEPAGE is advice: it never changes the memory's contents.
        // A refusal (THP disabled, an old kernel) is harmless and ignored.
        unsafe {
            libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn advise(_block: *mut u8, _len: usize) {}

/// Below this, a freed buffer is left to the allocator as it is.
#[cfg(target_os = "linux")]
const RELEASE_MIN: usize = 64 << 10;
/// At or above this, glibc maps a block on its own (its mmap threshold
/// never exceeds 32 MiB on 64-bit systems) and unmaps it on free, so a
/// release would only repeat that work (for a scene's 100 MB of triangles,
/// tens of milliseconds).
#[cfg(target_os = "linux")]
const RELEASE_MAX: usize = 32 << 20;

/// Drops `buffer`, first handing its whole pages back to the kernel.
///
/// The C allocator keeps a freed block of a megabyte or so in its heap for
/// reuse, resident. Where the next allocation is larger than the block (the
/// leaves, made just after the triangles they were sized from are freed),
/// it cannot reuse it, and the idle block adds to the build's peak: 24
/// bytes per vertex of horse.ply's 112. Released, it costs page faults
/// only when the allocator hands that memory out again. Blocks under
/// 64 KiB, or of 32 MiB and more (which glibc unmaps on free anyway), are
/// simply freed.
///
/// `T: Copy` has no destructor, so nothing reads the contents after they
/// are discarded.
pub fn drop_releasing<T: Copy>(mut buffer: Vec<T>) {
    release(
        buffer.as_mut_ptr().cast(),
        buffer.capacity() * size_of::<T>(),
    );
    drop(buffer);
}

/// Discards the whole pages inside `len` bytes at `block`.
#[cfg(target_os = "linux")]
fn release(block: *mut u8, len: usize) {
    if !(RELEASE_MIN..RELEASE_MAX).contains(&len) {
        return;
    }
    let Some((start, end)) = whole_pages(block, len) else {
        return;
    };
    // SAFETY: `start..end` lies inside a block the caller owns and frees
    // right after without reading it. MADV_DONTNEED only discards the
    // contents of those pages (anonymous memory, the heap's, then reads as
    // zero when next touched); the mapping stays. The allocator's own
    // bookkeeping lies outside the block (glibc's header before it, the
    // next block's after), and anything an allocator writes inside the
    // block on free simply faults a page back in.
    unsafe {
        libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_DONTNEED);
    }
}

#[cfg(not(target_os = "linux"))]
fn release(_block: *mut u8, _len: usize) {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    #[cfg(target_os = "linux")]
    fn release_discards_exactly_the_whole_pages_inside_a_block() {
        let page = page_size().unwrap();
        let mut buffer = vec![7u8; 64 * page + 100];
        // An unaligned stretch: its first and last partial pages stay.
        let (offset, len) = (page / 2 + 3, 20 * page);
        let block = buffer[offset..].as_mut_ptr();
        release(block, len);
        let (start, end) = whole_pages(block, len).unwrap();
        let base = buffer.as_ptr() as usize;
        for (i, &b) in buffer.iter().enumerate() {
            let at = base + i;
            let discarded = at >= start && at < end;
            assert_eq!(b, if discarded { 0 } else { 7 }, "byte {i}");
        }
        assert!(end - start >= len - 2 * page);
    }

    #[test]
    fn large_and_small_blocks_keep_their_contents_through_realloc() {
        for size in [64, HUGE_MIN - 1, HUGE_MIN, 3 * HUGE_MIN + 123] {
            let layout = Layout::from_size_align(size, 8).unwrap();
            // SAFETY: a non-zero size; the block is freed with its layout.
            unsafe {
                let block = HugePageAlloc.alloc_zeroed(layout);
                assert!(!block.is_null());
                assert!((0..size).step_by(4096).all(|i| *block.add(i) == 0));
                for i in (0..size).step_by(4096) {
                    *block.add(i) = (i / 4096 % 251) as u8;
                }
                let grown = HugePageAlloc.realloc(block, layout, 2 * size);
                assert!(!grown.is_null());
                assert!(
                    (0..size)
                        .step_by(4096)
                        .all(|i| *grown.add(i) == (i / 4096 % 251) as u8)
                );
                HugePageAlloc.dealloc(grown, Layout::from_size_align(2 * size, 8).unwrap());
            }
        }
    }
}
