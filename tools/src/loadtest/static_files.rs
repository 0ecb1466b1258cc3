//! The load test against a static file server (`--static`): the same
//! clients fetch the same pages as plain files over HTTP/1.1 keep-alive,
//! as Potree's and 3D Tiles' viewers do from nginx or a bucket, so the
//! memory server can be compared with the simplest thing that could serve
//! its pages.
//!
//! The client is unchanged: its [`Session`](farfield_net::Session) speaks
//! the websocket protocol to a [`QueueTransport`], and [`drive_static`]
//! answers for the server, turning a hello into the header's and page 0's
//! files and each requested page into a GET (highest priority first, on
//! [`LANES`] connections at once, as a browser opens several to one host).
//! What a file server cannot do is left out: no pushes, no demo sessions.
//! Files are laid out by `farfield-server export`: `BASE/NAME/header` and
//! `BASE/NAME/pages/N`.

use std::collections::HashMap;
use std::net::SocketAddr;
use std::time::Duration;

use anyhow::Context;
use futures_util::StreamExt;
use futures_util::future::LocalBoxFuture;
use futures_util::stream::FuturesUnordered;
use http_body_util::{BodyExt, Empty, Limited};
use hyper::body::Bytes;
use hyper::client::conn::http1::SendRequest;
use hyper_util::rt::TokioIo;

use farfield_net::queue::QueueTransport;
use farfield_net::transport::{Closing, TransportEvent};
use farfield_protocol::codec::{
    decode_control, encode_control, encode_header_frame, encode_page_frame,
};
use farfield_protocol::file::FileHeader;
use farfield_protocol::messages::{ClientMessage, PROTOCOL_VERSION, ServerMessage};

/// Connections (and so requests in flight) per client.
pub const LANES: usize = 4;
/// How long the driver waits for a reply before the session steps again.
const TICK: Duration = Duration::from_millis(20);
/// Largest file taken (a header with a large directory; pages are far smaller).
const MAX_FILE_BYTES: usize = 64 << 20;
/// Tries of one file over connections that broke before it is given up.
const TRIES: u32 = 3;

/// Where the files are: the server's address and the path prefix.
#[derive(Debug, Clone)]
pub struct FileServer {
    addr: SocketAddr,
    host: String,
    prefix: String,
}

impl FileServer {
    /// `http://host:port/prefix` (or `host:port`), resolved now.
    pub async fn resolve(url: &str) -> anyhow::Result<Self> {
        let rest = url.strip_prefix("http://").unwrap_or(url);
        anyhow::ensure!(
            !rest.contains("://"),
            "a static file server is plain http://, not {url:?}"
        );
        let (host, path) = rest.split_once('/').unwrap_or((rest, ""));
        let with_port = if host.contains(':') {
            host.to_owned()
        } else {
            format!("{host}:80")
        };
        let addr = tokio::net::lookup_host(&with_port)
            .await
            .with_context(|| format!("resolving {host}"))?
            .next()
            .with_context(|| format!("{host} has no address"))?;
        let prefix = path.trim_end_matches('/');
        Ok(Self {
            addr,
            host: host.to_owned(),
            prefix: if prefix.is_empty() {
                String::new()
            } else {
                format!("/{prefix}")
            },
        })
    }
}

/// A file a client waits for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum File {
    Header,
    Page(u32),
}

/// How one GET ended.
enum Fetched {
    Bytes(Bytes),
    /// The server answered, without the file (404 and the like).
    Refused(String),
    /// The connection broke; another may do.
    Broken(String),
}

type Lane = Option<SendRequest<Empty<Bytes>>>;
/// A GET under way, with the connection generation it was made for.
type InFlight = LocalBoxFuture<'static, (u64, (usize, File, Lane, Fetched))>;

/// Plays the memory server for the session behind `wire` over `server`'s
/// files of `scene`, calling `step` after each batch or every [`TICK`]
/// (as `drive_wire` does); `step`'s error ends the drive.
pub async fn drive_static<E>(
    wire: &QueueTransport,
    server: &FileServer,
    scene: &str,
    mut step: impl FnMut() -> Result<bool, E>,
) -> Result<(), E> {
    let mut open = false;
    // The header's GET is under way: pages wait for it.
    let mut header_pending = false;
    // The root directory page's id, once the header said it: page 0 is
    // asked for when it arrived (a client cannot check page 0 before).
    let mut root: Option<u32> = None;
    // Counts connections, as the session sees them.
    let mut generation = 0u64;
    let mut lanes: Vec<Lane> = (0..LANES).map(|_| None).collect();
    let mut idle: Vec<usize> = (0..LANES).collect();
    // Wanted files and their priorities (a file server has no queue of its own).
    let mut wanted: HashMap<File, f32> = HashMap::new();
    let mut tries: HashMap<File, u32> = HashMap::new();
    let mut in_flight: FuturesUnordered<InFlight> = FuturesUnordered::new();
    loop {
        if wire.take_close() {
            open = false;
            generation += 1;
            (wanted, header_pending) = (HashMap::new(), false);
        }
        if wire.take_connect().is_some() {
            open = true;
            generation += 1;
            (wanted, header_pending) = (HashMap::new(), false);
            wire.push(TransportEvent::Opened);
        }
        if !step()? {
            return Ok(());
        }
        for frame in wire.take_sent() {
            if open {
                take_message(&frame, wire, &mut wanted);
            }
        }
        while let Some(lane) = idle.pop() {
            let Some(file) = most_wanted(&wanted, header_pending) else {
                idle.push(lane);
                break;
            };
            wanted.remove(&file);
            header_pending |= file == File::Header;
            let sender = lanes[lane].take();
            let get = fetch(server.clone(), scene.to_owned(), lane, file, sender);
            in_flight.push(Box::pin(async move { (generation, get.await) }));
        }
        if in_flight.is_empty() {
            tokio::time::sleep(TICK).await;
            continue;
        }
        let Ok(Some((made_for, (lane, file, sender, fetched)))) =
            tokio::time::timeout(TICK, in_flight.next()).await
        else {
            continue;
        };
        lanes[lane] = sender;
        idle.push(lane);
        // What an earlier connection asked for never reaches a later one.
        if !open || made_for != generation {
            continue;
        }
        if file == File::Header {
            header_pending = false;
        }
        match fetched {
            Fetched::Bytes(bytes) => {
                tries.remove(&file);
                let frame = match file {
                    File::Header => {
                        // The root directory page, then page 0, after the
                        // header, as the memory server sends them: a page
                        // cannot be checked before what places it.
                        root = FileHeader::decode(&bytes).ok().map(|h| h.page_count);
                        if let Some(root) = root {
                            wanted.insert(File::Page(root), f32::MAX);
                        }
                        encode_header_frame(&bytes)
                    }
                    File::Page(page) => {
                        if Some(page) == root {
                            wanted.insert(File::Page(0), f32::MAX);
                        }
                        encode_page_frame(&bytes)
                    }
                };
                wire.push(TransportEvent::Frame(frame.into()));
            }
            Fetched::Refused(reason) => refuse(wire, file, reason),
            Fetched::Broken(reason) => {
                let tried = tries.entry(file).or_insert(0);
                *tried += 1;
                if *tried < TRIES {
                    wanted.entry(file).or_insert(f32::MAX);
                } else {
                    tries.remove(&file);
                    open = false;
                    generation += 1;
                    (wanted, header_pending) = (HashMap::new(), false);
                    wire.push(TransportEvent::Closed {
                        reason,
                        how: Closing::Failed,
                    });
                }
            }
        }
    }
}

/// What a file the server refused means to the session: a page it cannot
/// have, or (the header) a scene that is not there.
fn refuse(wire: &QueueTransport, file: File, reason: String) {
    match file {
        File::Page(page) => wire.push(TransportEvent::Frame(
            encode_control(&ServerMessage::PageUnavailable { page, reason }).into(),
        )),
        File::Header => wire.push(TransportEvent::Closed {
            reason,
            how: Closing::Refused,
        }),
    }
}

/// Applies one of the session's frames to what is wanted, answering a
/// hello as the memory server would (its hello, then the header and page 0).
fn take_message(frame: &[u8], wire: &QueueTransport, wanted: &mut HashMap<File, f32>) {
    let Ok(message) = decode_control::<ClientMessage>(frame) else {
        return;
    };
    match message {
        ClientMessage::Hello { .. } => {
            wire.push(TransportEvent::Frame(
                encode_control(&ServerMessage::Hello {
                    protocol_version: PROTOCOL_VERSION,
                    server: "static files".into(),
                })
                .into(),
            ));
            wanted.insert(File::Header, f32::MAX);
        }
        ClientMessage::Request { pages } => {
            for wish in pages {
                wanted.insert(File::Page(wish.page), wish.priority);
            }
        }
        ClientMessage::Cancel { pages } => {
            for page in pages {
                wanted.remove(&File::Page(page));
            }
        }
        // Acknowledgements need no answer; a file server has no sessions.
        _ => {}
    }
}

/// The header before anything (and nothing while it is on its way: no
/// page can be read before it), then the highest priority.
fn most_wanted(wanted: &HashMap<File, f32>, header_pending: bool) -> Option<File> {
    if wanted.contains_key(&File::Header) {
        return Some(File::Header);
    }
    if header_pending {
        return None;
    }
    wanted
        .iter()
        .max_by(|a, b| a.1.total_cmp(b.1).then(b.0.page().cmp(&a.0.page())))
        .map(|(f, _)| *f)
}

impl File {
    fn page(self) -> u32 {
        match self {
            File::Header => 0,
            File::Page(p) => p,
        }
    }
}

/// GETs `file` over `sender` (a new connection if it has none or it
/// closed); the connection comes back for the next GET unless it broke.
async fn fetch(
    server: FileServer,
    scene: String,
    lane: usize,
    file: File,
    sender: Lane,
) -> (usize, File, Lane, Fetched) {
    let path = match file {
        File::Header => format!("{}/{scene}/header", server.prefix),
        File::Page(page) => format!("{}/{scene}/pages/{page}", server.prefix),
    };
    let mut sender = match sender {
        Some(s) if !s.is_closed() => s,
        _ => match connect(server.addr).await {
            Ok(s) => s,
            Err(e) => return (lane, file, None, Fetched::Broken(format!("{e:#}"))),
        },
    };
    match get(&mut sender, &server.host, &path).await {
        Ok(fetched) => (lane, file, Some(sender), fetched),
        Err(e) => (
            lane,
            file,
            None,
            Fetched::Broken(format!("GET {path}: {e:#}")),
        ),
    }
}

async fn connect(addr: SocketAddr) -> anyhow::Result<SendRequest<Empty<Bytes>>> {
    let tcp = tokio::net::TcpStream::connect(addr)
        .await
        .with_context(|| format!("connecting to {addr}"))?;
    tcp.set_nodelay(true)?;
    let (sender, connection) = hyper::client::conn::http1::handshake(TokioIo::new(tcp)).await?;
    // The connection's I/O; it ends when the sender drops or the server closes.
    tokio::spawn(async move {
        let _ = connection.await;
    });
    Ok(sender)
}

async fn get(
    sender: &mut SendRequest<Empty<Bytes>>,
    host: &str,
    path: &str,
) -> anyhow::Result<Fetched> {
    sender.ready().await?;
    let request = hyper::Request::get(path)
        .header(hyper::header::HOST, host)
        .body(Empty::new())?;
    let response = sender.send_request(request).await?;
    let status = response.status();
    let body = Limited::new(response.into_body(), MAX_FILE_BYTES)
        .collect()
        .await
        .map_err(|e| anyhow::anyhow!("reading the body: {e}"))?
        .to_bytes();
    Ok(if status.is_success() {
        Fetched::Bytes(body)
    } else {
        Fetched::Refused(format!("GET {path}: {status}"))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_header_comes_alone_first_then_the_highest_priority_then_the_lowest_page() {
        let mut wanted = HashMap::from([
            (File::Page(7), 1.0),
            (File::Page(3), 5.0),
            (File::Page(2), 5.0),
        ]);
        assert_eq!(most_wanted(&wanted, false), Some(File::Page(2)));
        assert_eq!(most_wanted(&wanted, true), None, "the header is on its way");
        wanted.insert(File::Header, 0.0);
        assert_eq!(most_wanted(&wanted, true), Some(File::Header));
        assert_eq!(most_wanted(&HashMap::new(), false), None);
    }

    #[tokio::test]
    async fn addresses_resolve_with_and_without_a_prefix() {
        let s = FileServer::resolve("http://127.0.0.1:8080/scenes/")
            .await
            .unwrap();
        assert_eq!((s.addr.port(), s.prefix.as_str()), (8080, "/scenes"));
        let s = FileServer::resolve("127.0.0.1:81").await.unwrap();
        assert_eq!((s.addr.port(), s.prefix.as_str()), (81, ""));
        assert!(FileServer::resolve("https://127.0.0.1:1").await.is_err());
    }
}
