//! What a session counts, and the pages it gave up on.

/// A page given up on, and the last reason it could not be had.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct FailedPage {
    pub page: u32,
    pub reason: String,
}

/// Counters a render reports.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct NetStats {
    pub bytes_received: u64,
    pub pages_received: u64,
    pub pages_requested: u64,
    pub pages_cancelled: u64,
    pub pages_rejected: u64,
    /// Pages the server said it cannot send (corrupt on its disk).
    pub pages_unavailable: u64,
    pub disconnects: u64,
    /// Connections to the same scene opened again after one was lost.
    pub reconnects: u64,
    /// Reported through the render report's own `last_error`.
    #[serde(skip)]
    pub last_error: Option<String>,
}
