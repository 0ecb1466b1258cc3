//! Fast paths for binary bodies: a whole element decoded straight from the
//! bytes, with no per-value dispatch through [`Values`](super::Values).
//!
//! They cover the common cases (a vertex element of scalars only, a face or
//! strip element whose only property is its index list) and give up with
//! `None` on anything else, including a malformed body: the caller then
//! reads the element value by value, which names the instance that failed.
//! So these paths never decide what an error says.

use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;

use super::{Element, Kind, Polygon, Scalar, Strip, is_u32};

/// Records (vertices, triangles) per parallel task: large enough that the
/// tasks' overhead stays small beside their work.
const RECORDS_PER_TASK: usize = 1 << 12;
/// Strip indices per parallel task, about; shorter strip lists are read
/// serially.
const STRIP_ITEMS_PER_TASK: usize = 1 << 14;

/// Where each property of an all-scalar element lies in its record.
pub(super) struct FixedLayout {
    /// (byte offset in the record, type) per property, in property order.
    fields: Vec<(usize, Scalar)>,
    /// Bytes per record.
    pub stride: usize,
}

impl FixedLayout {
    /// The layout of `element`, or `None` when it has a list property.
    pub fn of(element: &Element) -> Option<Self> {
        let mut fields = Vec::with_capacity(element.props.len());
        let mut offset = 0;
        for prop in &element.props {
            let Kind::Scalar(ty) = prop.kind else {
                return None;
            };
            fields.push((offset, ty));
            offset += ty.size();
        }
        (offset > 0).then_some(Self {
            fields,
            stride: offset,
        })
    }

    /// The bytes of the first `count` records of `bytes`, or `None` if it
    /// is too short.
    pub fn records<'b>(&self, bytes: &'b [u8], count: u64) -> Option<&'b [u8]> {
        let len = usize::try_from(count).ok()?.checked_mul(self.stride)?;
        bytes.get(..len)
    }

    /// Decodes every record of `records` with `item` into `out` (which it
    /// replaces), on all threads.
    pub fn decode_all<T: Send>(
        &self,
        records: &[u8],
        out: &mut Vec<T>,
        item: impl Fn(&[u8]) -> T + Sync + Send,
    ) {
        records
            .par_chunks_exact(self.stride)
            .with_min_len(RECORDS_PER_TASK)
            .map(item)
            .collect_into_vec(out);
    }

    /// A reader of property `i` from records of [`FixedLayout::records`].
    pub fn reader(&self, i: usize, big: bool) -> impl Fn(&[u8]) -> f64 + use<> {
        let (offset, ty) = self.fields[i];
        let decode = ty.decoder(big);
        move |record: &[u8]| decode(&record[offset..])
    }
}

/// A list property's types, for [`List::polygons`].
pub(super) struct List {
    pub count: Scalar,
    pub item: Scalar,
    pub big: bool,
}

impl List {
    /// Reads `instances` index lists from `bytes` into `tris`; returns the
    /// bytes read, or `None` (and `tris` as it was) when anything is amiss.
    pub fn polygons(
        &self,
        bytes: &[u8],
        instances: u64,
        polygon: &mut Polygon,
        tris: &mut Vec<[u32; 3]>,
    ) -> Option<usize> {
        let before = tris.len();
        let read = match self.item.integer_decoder(self.big) {
            Some(index_of) => self
                .triangle_lists(bytes, instances, polygon, tris, index_of)
                .or_else(|| self.integer_lists(bytes, instances, polygon, tris, index_of)),
            None => self.float_lists(bytes, instances, polygon, tris),
        };
        if read.is_none() {
            tris.truncate(before);
        }
        read
    }

    /// Faces that are all triangles (most meshes): records of one size,
    /// decoded on all threads. `None` (and `tris` as it was) when a face is
    /// not a triangle or an index is out of range; the serial paths then
    /// read the element again.
    fn triangle_lists(
        &self,
        bytes: &[u8],
        instances: u64,
        polygon: &Polygon,
        tris: &mut Vec<[u32; 3]>,
        index_of: fn(&[u8]) -> i64,
    ) -> Option<usize> {
        if polygon.strips {
            return None;
        }
        let (count_size, item_size) = (self.count.size(), self.item.size());
        let stride = count_size + 3 * item_size;
        let len = usize::try_from(instances).ok()?.checked_mul(stride)?;
        let records = bytes.get(..len)?;
        let count_of = self.count.decoder(self.big);
        // One pass: a face that is not a triangle, or an index out of range,
        // only raises the flag (the element is then read again serially).
        let amiss = AtomicBool::new(false);
        let before = tris.len();
        tris.par_extend(
            records
                .par_chunks_exact(stride)
                .with_min_len(RECORDS_PER_TASK)
                .map(|r| {
                    if count_of(r) != 3.0 {
                        amiss.store(true, Ordering::Relaxed);
                    }
                    std::array::from_fn(|k| {
                        let at = count_size + k * item_size;
                        polygon.index(index_of(&r[at..])).unwrap_or_else(|| {
                            amiss.store(true, Ordering::Relaxed);
                            0
                        })
                    })
                }),
        );
        if amiss.into_inner() {
            tris.truncate(before);
            return None;
        }
        Some(len)
    }

    /// Lists of integer indices (nearly every file): decoded straight to
    /// `u32`, with a triangle (a list of three) pushed as it is. Going
    /// through `f64` and a scratch list was most of a mesh's import.
    fn integer_lists(
        &self,
        bytes: &[u8],
        instances: u64,
        polygon: &mut Polygon,
        tris: &mut Vec<[u32; 3]>,
        index_of: fn(&[u8]) -> i64,
    ) -> Option<usize> {
        let item_size = self.item.size();
        let mut pos = 0;
        for _ in 0..instances {
            let list = self.next_list(bytes, &mut pos)?;
            if polygon.strips && list.len() >= 2 * STRIP_ITEMS_PER_TASK * item_size {
                strips_on_all_threads(self, list, polygon, tris, index_of)?;
                continue;
            }
            let indices = list.chunks_exact(item_size).map(index_of);
            if indices.len() == 3 && !polygon.strips {
                let mut t = [0; 3];
                for (slot, i) in t.iter_mut().zip(indices) {
                    *slot = polygon.index(i)?;
                }
                tris.push(t);
            } else {
                polygon.add_integers(indices, tris)?;
            }
        }
        Some(pos)
    }

    /// Lists of float indices, read through [`Polygon::add`].
    fn float_lists(
        &self,
        bytes: &[u8],
        instances: u64,
        polygon: &mut Polygon,
        tris: &mut Vec<[u32; 3]>,
    ) -> Option<usize> {
        let mut items = Vec::new();
        let mut pos = 0;
        let (item_of, item_size) = (self.item.decoder(self.big), self.item.size());
        for _ in 0..instances {
            items.clear();
            let list = self.next_list(bytes, &mut pos)?;
            items.extend(list.chunks_exact(item_size).map(item_of));
            polygon.add(&items, tris).ok()?;
        }
        Some(pos)
    }

    /// The bytes of the items of the list at `*pos` in `bytes`; moves `*pos`
    /// past the list.
    fn next_list<'b>(&self, bytes: &'b [u8], pos: &mut usize) -> Option<&'b [u8]> {
        let (count_size, item_size) = (self.count.size(), self.item.size());
        let n = self.count.decoder(self.big)(bytes.get(*pos..*pos + count_size)?);
        if !is_u32(n) {
            return None;
        }
        let start = *pos + count_size;
        let end = start.checked_add((n as usize).checked_mul(item_size)?)?;
        let list = bytes.get(start..end)?;
        *pos = end;
        Some(list)
    }
}

/// One long list of triangle-strip indices (igea.ply holds all its
/// triangles in one) triangulated on all threads. The list is cut just
/// after restarts (-1), so every piece starts a new strip and triangulates
/// alone, as the serial reading would (a strip's winding alternates from
/// its own start); the pieces' triangles, in order, are the serial
/// reading's. `None` on an index out of range or negative other than -1
/// (the caller reads the list again serially to say which).
fn strips_on_all_threads(
    list: &List,
    items: &[u8],
    polygon: &Polygon,
    tris: &mut Vec<[u32; 3]>,
    index_of: fn(&[u8]) -> i64,
) -> Option<()> {
    // 32-bit little-endian indices (nearly every file's) decoded inline:
    // through the call, decoding was most of the work.
    match (list.item, list.big) {
        (Scalar::I32, false) => strips_with(items, 4, polygon, tris, |b| {
            b.first_chunk()
                .map_or(i64::MIN, |b| i64::from(i32::from_le_bytes(*b)))
        }),
        _ => strips_with(items, list.item.size(), polygon, tris, index_of),
    }
}

/// [`strips_on_all_threads`] with indices of `item_size` bytes read by
/// `index_of`.
fn strips_with(
    items: &[u8],
    item_size: usize,
    polygon: &Polygon,
    tris: &mut Vec<[u32; 3]>,
    index_of: impl Fn(&[u8]) -> i64 + Sync,
) -> Option<()> {
    let n = items.len() / item_size;
    let item = |i: usize| index_of(&items[i * item_size..]);
    // Piece boundaries: just past the first restart of each even share; a
    // share with no restart merges into the piece before it. Each item is
    // looked at once at most.
    let mut cuts = vec![0];
    for share in 1..n / STRIP_ITEMS_PER_TASK {
        let (from, to) = (
            share * STRIP_ITEMS_PER_TASK,
            (share + 1) * STRIP_ITEMS_PER_TASK,
        );
        if let Some(restart) = (from..to.min(n)).find(|&i| item(i) == -1) {
            cuts.push(restart + 1);
        }
    }
    cuts.push(n);
    cuts.dedup();
    // The pieces triangulate straight into the result, each into its own
    // stretch of room for as many triangles as it has indices (a strip
    // index makes at most one), and the stretches are then closed up. The
    // room is allocated here, on the calling thread: memory a worker thread
    // allocates stays in its own heap once freed, where the rest of the
    // build, on this thread, cannot reuse it (igea.ply's peak rose by 18
    // bytes per vertex). Copying separate pieces into the result took
    // igea's import 1.9 ms, on one thread, into fresh memory. The room is
    // not zeroed first (in a reused heap block that was a 4.5 MB memset).
    let mut room: Vec<[u32; 3]> = Vec::with_capacity(n);
    let mut stretches = Vec::with_capacity(cuts.len());
    let mut rest = &mut room.spare_capacity_mut()[..n];
    for w in cuts.windows(2) {
        let (stretch, tail) = std::mem::take(&mut rest).split_at_mut(w[1] - w[0]);
        stretches.push((w, stretch));
        rest = tail;
    }
    let made: Vec<usize> = stretches
        .into_par_iter()
        .map(|(w, out)| {
            let mut strip = Strip::default();
            let mut made = 0;
            for index in items[w[0] * item_size..w[1] * item_size].chunks_exact(item_size) {
                match index_of(index) {
                    -1 => strip = Strip::default(),
                    v => {
                        if let Some(t) = strip.next(polygon.index(v)?) {
                            out[made].write(t);
                            made += 1;
                        }
                    }
                }
            }
            Some(made)
        })
        .collect::<Option<_>>()?;
    // Closing up moves each stretch's written triangles down, in order, so
    // no move overwrites triangles not yet moved.
    let room_slots = room.spare_capacity_mut();
    let mut end = 0;
    for (w, made) in cuts.windows(2).zip(made) {
        room_slots.copy_within(w[0]..w[0] + made, end);
        end += made;
    }
    // SAFETY: the first `end` slots now hold the stretches' written
    // triangles, closed up; `end` is at most `n`, the capacity.
    unsafe { room.set_len(end) };
    room.shrink_to_fit();
    if tris.is_empty() {
        *tris = room;
    } else {
        tris.extend_from_slice(&room);
    }
    Some(())
}
