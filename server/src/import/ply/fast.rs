//! Fast paths for binary bodies: a whole element decoded straight from the
//! bytes, with no per-value dispatch through [`Values`](super::Values).
//!
//! They cover the common cases (a vertex element of scalars only, a face or
//! strip element whose only property is its index list) and give up with
//! `None` on anything else, including a malformed body: the caller then
//! reads the element value by value, which names the instance that failed.
//! So these paths never decide what an error says.

use super::{Element, Kind, Polygon, Scalar, is_u32};

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

    /// The first `count` records of `bytes`, or `None` if it is too short.
    pub fn records<'b>(
        &self,
        bytes: &'b [u8],
        count: u64,
    ) -> Option<std::slice::ChunksExact<'b, u8>> {
        let len = usize::try_from(count).ok()?.checked_mul(self.stride)?;
        Some(bytes.get(..len)?.chunks_exact(self.stride))
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
            Some(index_of) => self.integer_lists(bytes, instances, polygon, tris, index_of),
            None => self.float_lists(bytes, instances, polygon, tris),
        };
        if read.is_none() {
            tris.truncate(before);
        }
        read
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
        let mut pos = 0;
        for _ in 0..instances {
            let indices = self.next_list(bytes, &mut pos)?.map(index_of);
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
        let item_of = self.item.decoder(self.big);
        for _ in 0..instances {
            items.clear();
            items.extend(self.next_list(bytes, &mut pos)?.map(item_of));
            polygon.add(&items, tris).ok()?;
        }
        Some(pos)
    }

    /// The items of the list at `*pos` in `bytes`, each as its bytes; moves
    /// `*pos` past the list.
    fn next_list<'b>(
        &self,
        bytes: &'b [u8],
        pos: &mut usize,
    ) -> Option<std::slice::ChunksExact<'b, u8>> {
        let (count_size, item_size) = (self.count.size(), self.item.size());
        let n = self.count.decoder(self.big)(bytes.get(*pos..*pos + count_size)?);
        if !is_u32(n) {
            return None;
        }
        let start = *pos + count_size;
        let end = start.checked_add((n as usize).checked_mul(item_size)?)?;
        let list = bytes.get(start..end)?;
        *pos = end;
        Some(list.chunks_exact(item_size))
    }
}
