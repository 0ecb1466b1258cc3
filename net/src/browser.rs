//! The browser's transport: a `WebSocket` of the page (web-sys).
//!
//! A browser runs the socket itself and tells the page through callbacks;
//! each callback pushes what happened onto a queue that
//! [`Transport::poll`] empties, so the session sees the same events as
//! over the native transport and never blocks (a browser frame must not).
//! Each connection has its own queue: callbacks of an abandoned socket
//! push into a queue nobody reads, so nothing of it is reported.
//!
//! What a browser hides: the HTTP status of a refused upgrade (a 404 for an
//! unknown scene is just a failed connection here, which is why the server
//! checks the scene when it serves the viewer's page) and a close frame's
//! difference from a reset. A connection that opened and then ended is
//! [`Closing::ByServer`] (a restart: try again soon); one that never opened
//! is [`Closing::Failed`] (back off).

use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;
use std::time::Duration;

use bytes::Bytes;
use wasm_bindgen::JsCast;
use wasm_bindgen::closure::Closure;
use web_sys::{BinaryType, CloseEvent, MessageEvent, WebSocket};

use crate::transport::{Closing, Target, Transport, TransportEvent, Waker};

type Events = Rc<RefCell<VecDeque<TransportEvent>>>;

/// The owner's waker, shared with the socket's callbacks.
type Wake = Rc<RefCell<Option<Waker>>>;

/// Queues `event` and wakes the owner.
fn push(events: &Events, wake: &Wake, event: TransportEvent) {
    events.borrow_mut().push_back(event);
    if let Some(waker) = wake.borrow().as_ref() {
        waker.wake();
    }
}

/// One open (or opening) socket, its callbacks and its queue.
struct Connection {
    socket: WebSocket,
    events: Events,
    /// Kept alive as long as the socket may call them.
    _callbacks: [Closure<dyn FnMut(web_sys::Event)>; 3],
}

impl Connection {
    /// Opens a socket to `target`; a token goes as a subprotocol, the one
    /// field of the handshake a page may set ([`farfield_protocol::auth`]).
    fn open(target: &Target, hello: Vec<u8>, wake: &Wake) -> Result<Self, String> {
        let url = target.url.as_str();
        let socket = match &target.token {
            None => WebSocket::new(url),
            Some(token) => {
                let protocols = js_sys::Array::of2(
                    &farfield_protocol::auth::SUBPROTOCOL.into(),
                    &farfield_protocol::auth::token_subprotocol(token).into(),
                );
                WebSocket::new_with_str_sequence(url, &protocols)
            }
        }
        .map_err(|e| format!("connect {url}: {e:?}"))?;
        socket.set_binary_type(BinaryType::Arraybuffer);
        let events: Events = Rc::default();
        let opened = Rc::new(std::cell::Cell::new(false));

        let on_open = {
            let (events, opened, socket) = (events.clone(), opened.clone(), socket.clone());
            let wake = wake.clone();
            Closure::<dyn FnMut(web_sys::Event)>::new(move |_| {
                opened.set(true);
                // The hello goes first, the moment the socket opens.
                let _ = socket.send_with_u8_array(&hello);
                push(&events, &wake, TransportEvent::Opened);
            })
        };
        let on_message = {
            let (events, wake) = (events.clone(), wake.clone());
            Closure::<dyn FnMut(web_sys::Event)>::new(move |event: web_sys::Event| {
                let Some(message) = event.dyn_ref::<MessageEvent>() else {
                    return;
                };
                // Text frames are not part of the protocol: ignored, as natively.
                if let Ok(buffer) = message.data().dyn_into::<js_sys::ArrayBuffer>() {
                    let bytes = js_sys::Uint8Array::new(&buffer).to_vec();
                    push(&events, &wake, TransportEvent::Frame(Bytes::from(bytes)));
                }
            })
        };
        let on_close = {
            let (events, url, wake) = (events.clone(), url.to_owned(), wake.clone());
            Closure::<dyn FnMut(web_sys::Event)>::new(move |event: web_sys::Event| {
                let (code, reason) = event
                    .dyn_ref::<CloseEvent>()
                    .map_or((0, String::new()), |c| (c.code(), c.reason()));
                let (reason, how) = if opened.get() {
                    (
                        format!("server closed the connection (code {code}) {reason}"),
                        Closing::ByServer,
                    )
                } else {
                    (
                        format!("connect {url}: failed (code {code})"),
                        Closing::Failed,
                    )
                };
                push(&events, &wake, TransportEvent::Closed { reason, how });
            })
        };
        socket.set_onopen(Some(on_open.as_ref().unchecked_ref()));
        socket.set_onmessage(Some(on_message.as_ref().unchecked_ref()));
        socket.set_onclose(Some(on_close.as_ref().unchecked_ref()));
        Ok(Self {
            socket,
            events,
            _callbacks: [on_open, on_message, on_close],
        })
    }

    fn close(&self) {
        self.socket.set_onopen(None);
        self.socket.set_onmessage(None);
        self.socket.set_onclose(None);
        let _ = self.socket.close();
    }
}

/// A session's transport in a browser page.
#[derive(Default)]
pub struct BrowserTransport {
    connection: Option<Connection>,
    /// Events of the transport itself (a URL the browser refused at once).
    pending: VecDeque<TransportEvent>,
    wake: Wake,
}

impl std::fmt::Debug for BrowserTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BrowserTransport")
            .field("connected", &self.connection.is_some())
            .finish()
    }
}

impl BrowserTransport {
    pub fn new() -> Self {
        Self::default()
    }
}

impl Transport for BrowserTransport {
    fn connect(&mut self, target: &Target, hello: Vec<u8>) {
        self.close();
        match Connection::open(target, hello, &self.wake) {
            Ok(c) => self.connection = Some(c),
            Err(reason) => self.pending.push_back(TransportEvent::Closed {
                reason,
                how: Closing::Failed,
            }),
        }
    }

    fn send(&mut self, frame: Vec<u8>) {
        if let Some(c) = &self.connection
            && c.socket.ready_state() == WebSocket::OPEN
        {
            let _ = c.socket.send_with_u8_array(&frame);
        }
    }

    fn close(&mut self) {
        if let Some(c) = self.connection.take() {
            c.close();
        }
    }

    fn set_waker(&mut self, waker: Waker) -> bool {
        *self.wake.borrow_mut() = Some(waker);
        true
    }

    fn poll(&mut self, _wait: Duration) -> Option<TransportEvent> {
        if let Some(event) = self.pending.pop_front() {
            return Some(event);
        }
        let event = self.connection.as_ref()?.events.borrow_mut().pop_front();
        if matches!(event, Some(TransportEvent::Closed { .. })) {
            // The socket is done; its callbacks may go.
            self.connection = None;
        }
        event
    }
}
