//! What every traversal kind reports besides its draw list: the pages it
//! would descend into (the protocol's [`PageWish`], as the client sends
//! it, most urgent first) and the pages it read, tracked per traversal by
//! [`PageTracker`]. A wish's priority is the node's projected size,
//! discounted off-centre: larger is more urgent.

use farfield_protocol::messages::PageWish;

/// A wish for `page` at `priority`, held in the wire's `f32` (an infinite
/// or larger priority is the largest finite one).
fn wish(page: u32, priority: f64) -> PageWish {
    PageWish {
        page,
        priority: priority.min(f64::from(f32::MAX)) as f32,
    }
}

/// The pages one traversal touched and wished for: what both hierarchy
/// kinds' traversals report besides what they draw.
#[derive(Debug)]
pub struct PageTracker {
    /// The pages the traversal read, when recorded: a set, not a flag per
    /// page, so a header's page count (which a server chooses) is never
    /// allocated for.
    touched: Option<std::collections::BTreeSet<u32>>,
    /// Wanted page -> its highest priority.
    wanted: std::collections::HashMap<u32, f64>,
}

impl PageTracker {
    pub fn new(record_touched: bool) -> Self {
        Self {
            touched: record_touched.then(Default::default),
            wanted: std::collections::HashMap::new(),
        }
    }

    pub fn touch(&mut self, page: u32) {
        if let Some(t) = &mut self.touched {
            t.insert(page);
        }
    }

    /// Wishes for `page` with a priority from the node that needed it:
    /// projected size, discounted off-centre.
    pub fn want(&mut self, page: u32, size_px: f64, off_center: f64) {
        let priority = size_px.min(1e9) / (1.0 + off_center);
        let entry = self.wanted.entry(page).or_insert(0.0);
        *entry = entry.max(priority);
    }

    /// Writes the touched pages and the wishes, most urgent first.
    pub fn finish(self, touched: &mut Vec<u32>, wanted: &mut Vec<PageWish>) {
        touched.extend(self.touched.into_iter().flatten());
        // Ordered in f64, before the priorities are rounded to the wire's
        // f32, so that close priorities keep their order.
        let mut wishes: Vec<(u32, f64)> = self.wanted.into_iter().collect();
        wishes.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        wanted.extend(
            wishes
                .into_iter()
                .map(|(page, priority)| wish(page, priority)),
        );
    }
}

/// The wish when not even page 0 is resident.
pub fn want_page_zero(wanted: &mut Vec<PageWish>) {
    wanted.push(wish(0, f64::INFINITY));
}
