//! What every traversal kind reports besides its draw list: the pages it
//! would descend into ([`WantedPage`], most urgent first) and the pages it
//! read, tracked per traversal by [`PageTracker`].

/// A page the traversal would have descended into.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WantedPage {
    pub page: u32,
    /// Larger is more urgent: projected size, discounted off-centre.
    pub priority: f64,
}

/// The pages one traversal touched and wished for: what both hierarchy
/// kinds' traversals report besides what they draw.
#[derive(Debug)]
pub struct PageTracker {
    /// Per page, whether the traversal read it (empty when not recorded).
    touched: Vec<bool>,
    /// Wanted page -> its highest priority.
    wanted: std::collections::HashMap<u32, f64>,
}

impl PageTracker {
    pub fn new(pages: usize, record_touched: bool) -> Self {
        Self {
            touched: if record_touched {
                vec![false; pages]
            } else {
                Vec::new()
            },
            wanted: std::collections::HashMap::new(),
        }
    }

    pub fn touch(&mut self, page: u32) {
        if let Some(t) = self.touched.get_mut(page as usize) {
            *t = true;
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
    pub fn finish(self, touched: &mut Vec<u32>, wanted: &mut Vec<WantedPage>) {
        touched.extend((0..self.touched.len() as u32).filter(|&p| self.touched[p as usize]));
        wanted.extend(
            self.wanted
                .into_iter()
                .map(|(page, priority)| WantedPage { page, priority }),
        );
        wanted.sort_by(|a, b| b.priority.total_cmp(&a.priority).then(a.page.cmp(&b.page)));
    }
}

/// The wish when not even page 0 is resident.
pub fn want_page_zero(wanted: &mut Vec<WantedPage>) {
    wanted.push(WantedPage {
        page: 0,
        priority: f64::INFINITY,
    });
}
