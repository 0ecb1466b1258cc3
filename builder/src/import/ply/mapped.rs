//! [`Mapped`]: a binary PLY body read through a memory map of the file.
//!
//! Reading a body into a buffer copies it into freshly allocated memory, and
//! on a virtual machine each fresh page can cost microseconds to fault in
//! (the host backs it on first touch): for igea.ply the two reads took from
//! 0.6 to 2.4 ms of a 40 ms build. The file's pages are already in the page
//! cache, so mapping them copies nothing and zeroes nothing. Pages are
//! mapped in as the decoders reach them (the kernel maps a few dozen
//! kilobytes around each fault), and the whole pages behind the element
//! being decoded are handed back as each element begins, so the import
//! holds about what the buffered reader held: one element's bytes (the
//! last one's until the import ends) beside what they decode to.

use std::fs::File;
use std::io;

use memmap2::{Mmap, MmapOptions, UncheckedAdvice};

use super::{BodyError, Element, Scalar, Values, skip_values, take_value};

/// A binary body decoded straight from a memory map of its file.
pub(super) struct Mapped {
    map: Mmap,
    /// Offset in the file of the next byte to decode.
    pos: usize,
    /// Bytes below this offset (whole pages) are no longer mapped in.
    released: usize,
    big: bool,
}

impl Mapped {
    /// Maps `file` (a regular file), whose body starts at `body_start`;
    /// `None` when it cannot be mapped, and the caller reads it instead.
    pub(super) fn new(file: &File, body_start: u64, big: bool) -> Option<Self> {
        let pos = usize::try_from(body_start).ok()?;
        // SAFETY: the map is read-only and only read while `Mapped` lives.
        // If another process truncates the file meanwhile, reads past the
        // new end raise SIGBUS: the documented hazard of memory maps (ripgrep
        // takes it too), which a reader cannot guard against short of
        // copying the file, which is what this avoids.
        let map = unsafe { MmapOptions::new().map(file) }.ok()?;
        Some(Self {
            map,
            pos,
            released: 0,
            big,
        })
    }

    fn rest(&self) -> &[u8] {
        self.map.get(self.pos..).unwrap_or_default()
    }

    /// Unmaps the whole pages before the next byte to decode: the decoded
    /// elements' bytes, which nothing reads again. They stay in the page
    /// cache; only this process's resident memory shrinks.
    fn release_decoded(&mut self) {
        let page = crate::allocator::page_size().unwrap_or(4096);
        let end = self.pos.min(self.map.len()) / page * page;
        if end > self.released {
            // SAFETY: the range is inside the map and behind `pos`, so no
            // slice of it is alive and none is made again. The map is a
            // read-only file map, so the pages read back as the file if
            // touched; nothing is lost. A failure only keeps them resident.
            let _ = unsafe {
                self.map.unchecked_advise_range(
                    UncheckedAdvice::DontNeed,
                    self.released,
                    end - self.released,
                )
            };
            self.released = end;
        }
    }
}

impl Values for Mapped {
    fn value(&mut self, ty: Scalar) -> Result<f64, BodyError> {
        take_value(&self.map, &mut self.pos, ty, self.big)
    }

    fn skip(&mut self, ty: Scalar, n: u64) -> Result<(), BodyError> {
        skip_values(&self.map, &mut self.pos, ty, n)
    }

    fn binary_rest(&self) -> Option<(&[u8], bool)> {
        Some((self.rest(), self.big))
    }

    fn consume(&mut self, n: usize) {
        self.pos += n;
    }

    fn begin_element(&mut self, _element: &Element) -> io::Result<()> {
        self.release_decoded();
        Ok(())
    }

    fn batch_done(&mut self) {
        self.release_decoded();
    }
}
