//! Demo sessions: one presenter, many followers, one scene.
//!
//! The registry holds each session's members and the presenter's latest
//! view. Members are connections ([`crate::session`]), each with a
//! [`Mailbox`] the registry posts into: the session's state, the latest
//! view, or that the session closed. A mailbox keeps only the newest of
//! each (a follower that falls behind skips views, it never queues them),
//! so a member costs a fixed few hundred bytes whatever the presenter does.
//!
//! Pages are not the session's business: every member asks for its own,
//! and they come from the shared page cache that the presenter's requests
//! (and their read-ahead) filled first, so fifty followers cost the disk
//! about what one client costs.
//!
//! A presenter that leaves keeps its seat for [`Limits::session_grace`]
//! (the followers are told, with the time left); anyone who joins as
//! presenter meanwhile takes the seat. If nobody does, the session closes
//! and its members are told.

use std::collections::{BTreeMap, HashMap};
use std::fmt::Write as _;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use axum::body::Bytes;
use farfield_protocol::codec::encode_control;
use farfield_protocol::messages::{LISTED_FOLLOWERS, ServerMessage, SessionState, SharedView};
use serde::Serialize;
use tokio::sync::Notify;

use super::limits::Limits;

/// Longest session name, in bytes.
pub const MAX_NAME_BYTES: usize = 64;

/// What the registry has for one connection, newest only.
#[derive(Debug, Default)]
struct Mail {
    state: Option<Bytes>,
    view: Option<Bytes>,
    closed: Option<Bytes>,
}

/// A member's mailbox; posting wakes the connection's writer.
#[derive(Debug)]
pub(crate) struct Mailbox {
    mail: Mutex<Mail>,
    wake: Arc<Notify>,
}

impl Mailbox {
    pub(crate) fn new(wake: Arc<Notify>) -> Self {
        Self {
            mail: Mutex::new(Mail::default()),
            wake,
        }
    }

    fn lock(&self) -> MutexGuard<'_, Mail> {
        self.mail.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn post(&self, f: impl FnOnce(&mut Mail)) {
        f(&mut self.lock());
        self.wake.notify_one();
    }

    /// The next frame to send: the state before the view (a new member
    /// learns who presents, then what they show), a closing last.
    pub(crate) fn take(&self) -> Option<Bytes> {
        let mut mail = self.lock();
        mail.state
            .take()
            .or_else(|| mail.view.take())
            .or_else(|| mail.closed.take())
    }
}

/// One connection in a session.
#[derive(Debug, Clone)]
struct Member {
    mailbox: Arc<Mailbox>,
}

#[derive(Debug)]
struct DemoSession {
    scene: String,
    presenter: Option<u64>,
    /// When the presenter left, while its seat waits.
    away_since: Option<Instant>,
    /// Every member, the presenter included while connected.
    members: BTreeMap<u64, Member>,
    /// The latest view's frame, for late joiners.
    view: Option<Bytes>,
    views: u64,
    /// Page bytes sent to this session's members.
    bytes: Arc<AtomicU64>,
    /// Bumped whenever the presenter leaves, so a grace timer that ran out
    /// knows whether it is still the one that counts.
    epoch: u64,
}

impl DemoSession {
    fn presenter_connected(&self) -> bool {
        self.presenter
            .is_some_and(|p| self.members.contains_key(&p))
    }

    fn followers(&self) -> Vec<u64> {
        self.members
            .keys()
            .copied()
            .filter(|&m| Some(m) != self.presenter)
            .collect()
    }

    /// Tells every member who is in the session now.
    fn broadcast_state(&self, name: &str, grace: Duration) {
        let closes_in_s = self
            .away_since
            .map(|t| grace.saturating_sub(t.elapsed()).as_secs_f64());
        let all = self.followers();
        let follower_count = u32::try_from(all.len()).unwrap_or(u32::MAX);
        let followers: Vec<u64> = all.into_iter().take(LISTED_FOLLOWERS).collect();
        for (&id, member) in &self.members {
            let frame = Bytes::from(encode_control(&ServerMessage::SessionState {
                state: SessionState {
                    session: name.to_owned(),
                    you: id,
                    presenter: self.presenter,
                    presenter_connected: self.presenter_connected(),
                    follower_count,
                    followers: followers.clone(),
                    closes_in_s,
                },
            }));
            member.mailbox.post(|m| m.state = Some(frame));
        }
    }
}

/// A session as `/sessions` lists it.
#[derive(Debug, Clone, Serialize)]
pub struct SessionSummary {
    pub name: String,
    pub scene: String,
    pub presenter_connected: bool,
    pub followers: usize,
    pub views: u64,
    pub bytes_served: u64,
}

/// A connection's seat in a session: what it needs to send pages on the
/// session's account.
#[derive(Debug, Clone)]
pub(crate) struct Seat {
    pub name: String,
    pub bytes: Arc<AtomicU64>,
}

/// Every demo session of the server.
#[derive(Debug)]
pub(crate) struct DemoSessions {
    sessions: Mutex<HashMap<String, DemoSession>>,
    next_member: AtomicU64,
    grace: Duration,
    max_sessions: usize,
}

/// Whether `name` may name a session: 1 to [`MAX_NAME_BYTES`] of ASCII
/// letters, digits, `-`, `_` and `.` (it goes into URLs and metric labels).
pub fn valid_name(name: &str) -> bool {
    (1..=MAX_NAME_BYTES).contains(&name.len())
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b"-_.".contains(&b))
}

impl DemoSessions {
    pub(crate) fn new(limits: &Limits) -> Self {
        Self {
            sessions: Mutex::new(HashMap::new()),
            next_member: AtomicU64::new(1),
            grace: limits.session_grace,
            max_sessions: limits.max_sessions,
        }
    }

    fn lock(&self) -> MutexGuard<'_, HashMap<String, DemoSession>> {
        self.sessions.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A fresh member id for a connection.
    pub(crate) fn member_id(&self) -> u64 {
        self.next_member.fetch_add(1, Ordering::Relaxed)
    }

    /// Joins `member` (of scene `scene`) to session `name`; the error says
    /// why not, for the client.
    pub(crate) fn join(
        &self,
        name: &str,
        scene: &str,
        present: bool,
        member: u64,
        mailbox: &Arc<Mailbox>,
    ) -> Result<Seat, String> {
        if !valid_name(name) {
            return Err(format!(
                "a session name is 1 to {MAX_NAME_BYTES} letters, digits, '-', '_' or '.'"
            ));
        }
        let mut sessions = self.lock();
        if !sessions.contains_key(name) {
            if !present {
                return Err(format!("no session named {name:?}"));
            }
            if sessions.len() >= self.max_sessions {
                return Err(format!(
                    "the server holds {} sessions, its most",
                    self.max_sessions
                ));
            }
            sessions.insert(
                name.to_owned(),
                DemoSession {
                    scene: scene.to_owned(),
                    presenter: None,
                    away_since: None,
                    members: BTreeMap::new(),
                    view: None,
                    views: 0,
                    bytes: Arc::new(AtomicU64::new(0)),
                    epoch: 0,
                },
            );
        }
        let Some(session) = sessions.get_mut(name) else {
            return Err(format!("no session named {name:?}"));
        };
        if session.scene != scene {
            return Err(format!(
                "session {name:?} shows scene {:?}, not {scene:?}",
                session.scene
            ));
        }
        if present {
            if session.presenter_connected() && session.presenter != Some(member) {
                return Err(format!("session {name:?} has a presenter"));
            }
            session.presenter = Some(member);
            session.away_since = None;
        }
        session.members.insert(
            member,
            Member {
                mailbox: mailbox.clone(),
            },
        );
        // A late joiner starts from where the presenter is now.
        if !present && let Some(view) = &session.view {
            let view = view.clone();
            mailbox.post(|m| m.view = Some(view));
        }
        session.broadcast_state(name, self.grace);
        Ok(Seat {
            name: name.to_owned(),
            bytes: session.bytes.clone(),
        })
    }

    /// Takes `member` out of session `name` (it left, or its connection
    /// ended). A presenter's seat waits for the grace period; `registry`
    /// closes the session if nobody takes it by then.
    pub(crate) fn leave(registry: &Arc<Self>, name: &str, member: u64) {
        let mut sessions = registry.lock();
        let Some(session) = sessions.get_mut(name) else {
            return;
        };
        if session.members.remove(&member).is_none() {
            return;
        }
        if session.presenter == Some(member) {
            session.away_since = Some(Instant::now());
            session.epoch += 1;
            let (registry, name, epoch) = (registry.clone(), name.to_owned(), session.epoch);
            let grace = registry.grace;
            tokio::spawn(async move {
                tokio::time::sleep(grace).await;
                registry.close_if_abandoned(&name, epoch);
            });
        }
        session.broadcast_state(name, registry.grace);
    }

    /// Closes session `name` if its presenter is still away since the
    /// leaving that `epoch` counts.
    fn close_if_abandoned(&self, name: &str, epoch: u64) {
        let mut sessions = self.lock();
        let abandoned = sessions
            .get(name)
            .is_some_and(|s| s.epoch == epoch && s.away_since.is_some());
        if !abandoned {
            return;
        }
        if let Some(session) = sessions.remove(name) {
            let frame = Bytes::from(encode_control(&ServerMessage::SessionClosed {
                session: name.to_owned(),
                reason: format!(
                    "its presenter did not come back within {:.0} s",
                    self.grace.as_secs_f64()
                ),
            }));
            for member in session.members.values() {
                let frame = frame.clone();
                member.mailbox.post(|m| {
                    *m = Mail {
                        closed: Some(frame),
                        ..Mail::default()
                    };
                });
            }
        }
    }

    /// The presenter's new view, handed to every follower.
    pub(crate) fn view(&self, name: &str, member: u64, view: SharedView) -> Result<(), String> {
        let mut sessions = self.lock();
        let session = sessions
            .get_mut(name)
            .ok_or_else(|| format!("no session named {name:?}"))?;
        if session.presenter != Some(member) {
            return Err(format!("only session {name:?}'s presenter may show a view"));
        }
        session.views += 1;
        let frame = Bytes::from(encode_control(&ServerMessage::View {
            seq: session.views,
            view,
        }));
        for (&id, m) in &session.members {
            if id != member {
                let frame = frame.clone();
                m.mailbox.post(|mail| mail.view = Some(frame));
            }
        }
        session.view = Some(frame);
        Ok(())
    }

    /// The presenter hands control to follower `to`.
    pub(crate) fn hand_over(&self, name: &str, member: u64, to: u64) -> Result<(), String> {
        let mut sessions = self.lock();
        let session = sessions
            .get_mut(name)
            .ok_or_else(|| format!("no session named {name:?}"))?;
        if session.presenter != Some(member) {
            return Err(format!(
                "only session {name:?}'s presenter may hand it over"
            ));
        }
        if to == member || !session.members.contains_key(&to) {
            return Err(format!("member {to} does not follow session {name:?}"));
        }
        session.presenter = Some(to);
        session.broadcast_state(name, self.grace);
        Ok(())
    }

    /// Every session, by name.
    pub fn list(&self) -> Vec<SessionSummary> {
        let sessions = self.lock();
        let mut list: Vec<SessionSummary> = sessions
            .iter()
            .map(|(name, s)| SessionSummary {
                name: name.clone(),
                scene: s.scene.clone(),
                presenter_connected: s.presenter_connected(),
                followers: s.followers().len(),
                views: s.views,
                bytes_served: s.bytes.load(Ordering::Relaxed),
            })
            .collect();
        list.sort_by(|a, b| a.name.cmp(&b.name));
        list
    }

    /// The sessions' figures in the Prometheus text format.
    pub fn render_metrics(&self, out: &mut String, shown: impl Fn(&str) -> bool) {
        let list: Vec<SessionSummary> = self
            .list()
            .into_iter()
            .filter(|s| shown(&s.scene))
            .collect();
        let _ = writeln!(
            out,
            "# HELP farfield_sessions Demo sessions open.\n# TYPE farfield_sessions gauge\nfarfield_sessions {}",
            list.len()
        );
        /// Name, type, help, and the figure of a session.
        type Series<'a> = (&'a str, &'a str, &'a str, fn(&SessionSummary) -> u64);
        let series: [Series; 3] = [
            (
                "farfield_session_followers",
                "gauge",
                "Followers in a demo session now.",
                |s| s.followers as u64,
            ),
            (
                "farfield_session_presenter_connected",
                "gauge",
                "1 while a demo session's presenter is connected.",
                |s| u64::from(s.presenter_connected),
            ),
            (
                "farfield_session_bytes_served_total",
                "counter",
                "Page bytes sent to a demo session's members.",
                |s| s.bytes_served,
            ),
        ];
        for (name, kind, help, value) in series {
            let _ = writeln!(out, "# HELP {name} {help}\n# TYPE {name} {kind}");
            for s in &list {
                // Names are checked to hold no quote or backslash.
                let _ = writeln!(out, "{name}{{session=\"{}\"}} {}", s.name, value(s));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use farfield_protocol::codec::decode_control;

    fn mailbox() -> Arc<Mailbox> {
        Arc::new(Mailbox::new(Arc::new(Notify::new())))
    }

    fn next(m: &Mailbox) -> Option<ServerMessage> {
        m.take()
            .map(|f| decode_control(&f).expect("server message"))
    }

    fn view(x: f64) -> SharedView {
        SharedView {
            eye: [x, 0.0, 3.0],
            target: [0.0; 3],
            up: [0.0, 1.0, 0.0],
            fov_y_deg: 45.0,
            options: vec![("threshold".into(), "1".into())],
        }
    }

    fn registry(grace_ms: u64) -> Arc<DemoSessions> {
        Arc::new(DemoSessions::new(&Limits {
            session_grace: Duration::from_millis(grace_ms),
            max_sessions: 2,
            ..Limits::default()
        }))
    }

    #[test]
    fn followers_get_the_latest_view_only_and_late_joiners_start_from_it() {
        let r = registry(1000);
        let (p, f) = (mailbox(), mailbox());
        assert!(
            r.join("demo", "island", false, 1, &p).is_err(),
            "no such session"
        );
        r.join("demo", "island", true, 1, &p).expect("present");
        r.join("demo", "island", false, 2, &f).expect("follow");
        assert!(
            r.join("demo", "island", true, 3, &mailbox()).is_err(),
            "a presenter is there"
        );
        assert!(r.join("demo", "other", false, 3, &mailbox()).is_err());
        assert!(r.join("bad name", "island", true, 3, &mailbox()).is_err());
        let Some(ServerMessage::SessionState { state }) = next(&f) else {
            panic!("state first")
        };
        assert_eq!(
            (state.you, state.presenter, state.followers.clone()),
            (2, Some(1), vec![2])
        );
        r.view("demo", 1, view(1.0)).unwrap();
        r.view("demo", 1, view(2.0)).unwrap();
        assert!(
            r.view("demo", 2, view(9.0)).is_err(),
            "a follower shows nothing"
        );
        match next(&f) {
            Some(ServerMessage::View { seq: 2, view: v }) => assert_eq!(v.eye[0], 2.0),
            other => panic!("{other:?}"),
        }
        assert!(
            next(&f).is_none(),
            "the older view was replaced, not queued"
        );
        let late = mailbox();
        r.join("demo", "island", false, 4, &late).unwrap();
        assert!(matches!(
            next(&late),
            Some(ServerMessage::SessionState { .. })
        ));
        assert!(matches!(
            next(&late),
            Some(ServerMessage::View { seq: 2, .. })
        ));
        let list = r.list();
        assert_eq!((list[0].followers, list[0].presenter_connected), (2, true));
    }

    #[tokio::test]
    async fn a_presenter_who_leaves_keeps_the_seat_for_the_grace_then_the_session_closes() {
        let r = registry(100);
        let (p, f) = (mailbox(), mailbox());
        r.join("demo", "island", true, 1, &p).unwrap();
        r.join("demo", "island", false, 2, &f).unwrap();
        r.hand_over("demo", 1, 2).unwrap();
        assert!(
            r.hand_over("demo", 1, 2).is_err(),
            "no longer the presenter"
        );
        r.hand_over("demo", 2, 1).unwrap();
        while next(&f).is_some() {}
        DemoSessions::leave(&r, "demo", 1);
        let Some(ServerMessage::SessionState { state }) = next(&f) else {
            panic!("told")
        };
        assert!(!state.presenter_connected && state.closes_in_s.is_some_and(|s| s > 0.0));
        // Someone takes the seat in time: the session stays.
        let p2 = mailbox();
        r.join("demo", "island", true, 3, &p2).unwrap();
        tokio::time::sleep(Duration::from_millis(250)).await;
        assert_eq!(r.list().len(), 1);
        DemoSessions::leave(&r, "demo", 3);
        tokio::time::sleep(Duration::from_millis(250)).await;
        assert!(r.list().is_empty());
        let mut last = None;
        while let Some(m) = next(&f) {
            last = Some(m);
        }
        assert!(
            matches!(last, Some(ServerMessage::SessionClosed { .. })),
            "{last:?}"
        );
    }

    #[test]
    fn a_state_lists_a_bounded_few_followers_and_counts_them_all() {
        let r = registry(1000);
        r.join("big", "s", true, 1, &mailbox()).unwrap();
        let last = mailbox();
        for id in 2..=(LISTED_FOLLOWERS as u64 + 11) {
            r.join("big", "s", false, id, &last).unwrap();
        }
        while let Some(m) = next(&last) {
            if let ServerMessage::SessionState { state } = m {
                assert_eq!(state.follower_count as usize, LISTED_FOLLOWERS + 10);
                assert_eq!(state.followers.len(), LISTED_FOLLOWERS);
                assert_eq!(state.followers[0], 2, "the first by id");
                return;
            }
        }
        panic!("no state");
    }

    #[test]
    fn sessions_are_bounded_in_number() {
        let r = registry(100);
        r.join("a", "s", true, 1, &mailbox()).unwrap();
        r.join("b", "s", true, 2, &mailbox()).unwrap();
        let e = r.join("c", "s", true, 3, &mailbox()).unwrap_err();
        assert!(e.contains("its most"), "{e}");
    }
}
