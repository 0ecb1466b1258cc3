//! An emulated wide-area network between a server and its clients
//! (`farfield wan`), for measuring streaming over a real network on one
//! machine: two network namespaces, the server's and the clients', joined
//! by a link with a round trip, a rate and random loss.
//!
//! `tc netem` is how this is usually done, but kernels built without it
//! (this project's CI machine's among them) have only plain queues. So the
//! link is emulated where any Linux can: each namespace has a TUN device,
//! and threads here carry every IP packet from one to the other through
//! [`line::Line`], netem's model (loss, then the link's rate, then the
//! delay). The kernels' TCP stacks on both ends are real: they see the
//! round trip, the bandwidth and the losses and react as on a real network.
//!
//! Needs root (namespaces, TUN devices) and iproute2. Linux only.

pub mod line;
mod netns;
mod tun;

use std::net::Ipv4Addr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::{Context, bail};

use self::line::{Fate, Line, LineCounts, LineSpec};
pub use self::netns::run_in;
use self::tun::Tun;

/// The server's address, inside the server's namespace.
pub const SERVER_ADDR: Ipv4Addr = Ipv4Addr::new(10, 201, 0, 1);
/// The clients' address, inside the clients' namespace.
pub const CLIENT_ADDR: Ipv4Addr = Ipv4Addr::new(10, 201, 0, 2);
/// How often the carrying threads look whether they should stop.
const POLL: Duration = Duration::from_millis(50);
/// Larger than any packet a TUN device with the default MTU hands over.
const MAX_PACKET: usize = 65_536;

/// Counts of both directions, from [`Wan::stop`].
#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct WanCounts {
    pub to_clients: LineCounts,
    pub to_server: LineCounts,
}

/// A running link; [`Wan::stop`] (or dropping it) removes the namespaces.
#[derive(Debug)]
pub struct Wan {
    name: String,
    stop: Arc<AtomicBool>,
    carriers: Vec<JoinHandle<LineCounts>>,
}

impl Wan {
    /// Makes namespaces `NAME-server` and `NAME-client` and the link
    /// between them, with `spec` in each direction. `NAME`: 1 to 8 of
    /// a-z and 0-9 (device names are short). Fails, changing nothing, if
    /// either namespace exists.
    pub fn start(name: &str, spec: LineSpec) -> anyhow::Result<Self> {
        if name.is_empty()
            || name.len() > 8
            || !name
                .bytes()
                .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit())
        {
            bail!("a link's name is 1 to 8 of a-z and 0-9, not {name:?}");
        }
        if !(0.0..=1.0).contains(&spec.loss) {
            bail!("loss is a share from 0 to 1, not {}", spec.loss);
        }
        let mut wan = Self {
            name: name.to_owned(),
            stop: Arc::new(AtomicBool::new(false)),
            carriers: Vec::new(),
        };
        for ns in [wan.server_namespace(), wan.client_namespace()] {
            if netns::exists(&ns) {
                // Not ours: `wan` must not remove it when it drops.
                wan.name.clear();
                bail!("network namespace {ns} exists already (remove it with `ip netns del {ns}`)");
            }
        }
        let server_tun = wan.make_end(&wan.server_namespace(), 's', SERVER_ADDR, CLIENT_ADDR)?;
        let client_tun = wan.make_end(&wan.client_namespace(), 'c', CLIENT_ADDR, SERVER_ADDR)?;
        let (server_tun, client_tun) = (Arc::new(server_tun), Arc::new(client_tun));
        wan.carriers.push(carry(
            server_tun.clone(),
            client_tun.clone(),
            Line::new(spec, 0x5eed_0001),
            wan.stop.clone(),
        )?);
        wan.carriers.push(carry(
            client_tun,
            server_tun,
            Line::new(spec, 0x5eed_0002),
            wan.stop.clone(),
        )?);
        Ok(wan)
    }

    pub fn server_namespace(&self) -> String {
        format!("{}-server", self.name)
    }

    pub fn client_namespace(&self) -> String {
        format!("{}-client", self.name)
    }

    /// Stops carrying packets, removes the namespaces and says what the
    /// link carried.
    pub fn stop(mut self) -> WanCounts {
        self.shut()
    }

    /// Namespace `ns` with one end of the link, `local` on a
    /// point-to-point TUN device to `peer`.
    fn make_end(
        &self,
        ns: &str,
        side: char,
        local: Ipv4Addr,
        peer: Ipv4Addr,
    ) -> anyhow::Result<Tun> {
        let device = format!("ff{}{side}", self.name);
        netns::ip(&["netns", "add", ns])?;
        // Made in the namespace, so two links never clash on a device name.
        let tun = netns::run_in(ns, move || Tun::create(&device).map(|t| (t, device)))?
            .with_context(|| "making a TUN device (needs root and /dev/net/tun)")?;
        let (tun, device) = tun;
        let (local, peer) = (local.to_string(), peer.to_string());
        netns::ip(&["-n", ns, "link", "set", "lo", "up"])?;
        netns::ip(&[
            "-n", ns, "addr", "add", &local, "peer", &peer, "dev", &device,
        ])?;
        netns::ip(&["-n", ns, "link", "set", &device, "up"])?;
        Ok(tun)
    }

    fn shut(&mut self) -> WanCounts {
        self.stop.store(true, Ordering::Relaxed);
        let counts: Vec<LineCounts> = self
            .carriers
            .drain(..)
            .map(|c| c.join().unwrap_or_default())
            .collect();
        let to_clients = counts.first().copied().unwrap_or_default();
        let to_server = counts.get(1).copied().unwrap_or_default();
        if !self.name.is_empty() {
            for ns in [self.server_namespace(), self.client_namespace()] {
                if netns::exists(&ns)
                    && let Err(e) = netns::ip(&["netns", "del", &ns])
                {
                    tracing::warn!("{e}");
                }
            }
            self.name.clear();
        }
        WanCounts {
            to_clients,
            to_server,
        }
    }
}

impl Drop for Wan {
    fn drop(&mut self) {
        self.shut();
    }
}

/// Starts carrying packets from `from` to `to` through `line`: one thread
/// reads and judges each packet, one hands it over when it arrives (the
/// line's delay never reorders, so a queue in arrival order suffices).
/// The reader's handle returns the line's counts.
fn carry(
    from: Arc<Tun>,
    to: Arc<Tun>,
    mut line: Line,
    stop: Arc<AtomicBool>,
) -> anyhow::Result<JoinHandle<LineCounts>> {
    let (tx, rx) = mpsc::channel::<(Instant, Vec<u8>)>();
    let deliver_stop = stop.clone();
    std::thread::Builder::new()
        .name("farfield-wan-deliver".into())
        .spawn(move || {
            while !deliver_stop.load(Ordering::Relaxed) {
                let Ok((at, packet)) = rx.recv_timeout(POLL) else {
                    continue;
                };
                if let Some(wait) = at.checked_duration_since(Instant::now()) {
                    std::thread::sleep(wait);
                }
                // A packet the far end's kernel refuses is lost, as on a wire.
                let _ = to.write_packet(&packet);
            }
        })?;
    let reader = std::thread::Builder::new()
        .name("farfield-wan-read".into())
        .spawn(move || {
            let mut buf = vec![0u8; MAX_PACKET];
            while !stop.load(Ordering::Relaxed) {
                let n = match from.read_within(&mut buf, POLL) {
                    Ok(Some(n)) => n,
                    Ok(None) => continue,
                    Err(e) => {
                        tracing::warn!("the emulated link stopped reading: {e}");
                        break;
                    }
                };
                if let Fate::Arrives(at) = line.admit(Instant::now(), n) {
                    // The line's limit bounds what waits in the channel.
                    if tx.send((at, buf[..n].to_vec())).is_err() {
                        break;
                    }
                }
            }
            line.counts()
        })?;
    Ok(reader)
}

/// SIGINT and SIGTERM, the signals that stop a link.
fn stop_signals() -> libc::sigset_t {
    // SAFETY: a signal set on the stack, filled by sigemptyset/sigaddset.
    unsafe {
        let mut set: libc::sigset_t = std::mem::zeroed();
        libc::sigemptyset(&mut set);
        libc::sigaddset(&mut set, libc::SIGINT);
        libc::sigaddset(&mut set, libc::SIGTERM);
        set
    }
}

/// Blocks SIGINT and SIGTERM in this thread and the threads it starts
/// later, so that [`wait_for_stop`] receives them instead of the process
/// dying with its namespaces left behind. Call before starting a [`Wan`].
pub fn hold_stop_signals() {
    let set = stop_signals();
    // SAFETY: `set` is an initialised signal set.
    unsafe { libc::pthread_sigmask(libc::SIG_BLOCK, &set, std::ptr::null_mut()) };
}

/// Waits for SIGINT or SIGTERM, after [`hold_stop_signals`].
pub fn wait_for_stop() {
    let set = stop_signals();
    let mut signal = 0;
    // SAFETY: `set` is an initialised signal set; sigwait writes `signal`.
    unsafe { libc::sigwait(&set, &mut signal) };
}

/// A link's specification in a person's units: the round trip (split
/// evenly between the directions), megabits a second, percent lost.
pub fn spec(rtt_ms: f64, rate_mbit: Option<f64>, loss_percent: f64) -> anyhow::Result<LineSpec> {
    if !(rtt_ms.is_finite() && rtt_ms >= 0.0) {
        bail!("the round trip is a number of milliseconds, at least 0, not {rtt_ms}");
    }
    if let Some(rate) = rate_mbit
        && !(rate.is_finite() && rate > 0.0)
    {
        bail!("the rate is megabits a second, more than 0, not {rate}");
    }
    if !(0.0..=100.0).contains(&loss_percent) {
        bail!("loss is a percentage from 0 to 100, not {loss_percent}");
    }
    Ok(LineSpec {
        delay: Duration::from_secs_f64(rtt_ms / 2000.0),
        rate_bits_per_s: rate_mbit.map(|m| (m * 1e6) as u64),
        loss: loss_percent / 100.0,
        ..LineSpec::default()
    })
}
