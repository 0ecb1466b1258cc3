//! `farfield-server serve`: runs the memory server until SIGINT or SIGTERM.
//!
//! The command line is synchronous, so this builds a tokio runtime, starts
//! [`farfield_memory_server`] in it, prints `listening on ADDR` as the first line of
//! stdout at once (scripts and tests pass port 0 and read the real port
//! from it), and blocks until a signal. The returned report holds the
//! final counters.

use std::io::Write;
use std::time::Duration;

use serde_json::json;

use super::{Report, ServeArgs};
use anyhow::Context as _;
use farfield_memory_server::access::Access;
use farfield_memory_server::origin::Origin;
use farfield_memory_server::tls::TlsFiles;
use farfield_memory_server::{ServerConfig, start};

pub fn run(args: &ServeArgs) -> anyhow::Result<Report> {
    let origin = if farfield_objects::is_store_url(&args.scenes) {
        let (bucket, _) = args.store.bucket(&args.scenes, Default::default())?;
        Origin::Objects(bucket)
    } else {
        // `file:///srv/scenes` is the folder `/srv/scenes`.
        let folder = args.scenes.strip_prefix("file://").unwrap_or(&args.scenes);
        Origin::Folder(folder.into())
    };
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .thread_name("farfield-memory-server")
        .build()?;
    let snapshot = runtime.block_on(async {
        // Handlers go in before the address is printed, so a script that
        // signals as soon as it reads the line never kills us uncleanly.
        let mut signals = Signals::new()?;
        let server = start(ServerConfig {
            cache_bytes: args.cache_bytes,
            rescan_interval: Duration::from_secs_f64(args.rescan_seconds),
            limits: args.limits.limits(),
            access: access(args)?,
            tls: match (&args.tls_cert, &args.tls_key) {
                (Some(cert), Some(key)) => Some(TlsFiles {
                    cert: cert.clone(),
                    key: key.clone(),
                }),
                _ => None,
            },
            web: args.web.clone(),
            ..ServerConfig::with_origin(origin, args.listen)
        })
        .await?;
        {
            let mut out = std::io::stdout().lock();
            writeln!(out, "listening on {}", server.local_addr())?;
            out.flush()?;
        }
        tokio::select! {
            () = signals.recv() => tracing::info!("signal received, shutting down"),
            () = server.shutdown_requested() => {}
        }
        anyhow::Ok(server.shutdown().await?)
    })?;
    let text = format!(
        "served {} pages ({} bytes, {} pushed) over {} connections; cache {} hits, {} misses; \
         {} malformed frames, {} corrupt pages",
        snapshot.pages_served,
        snapshot.bytes_served,
        snapshot.pages_pushed,
        snapshot.connections_total,
        snapshot.cache_hits,
        snapshot.cache_misses,
        snapshot.malformed_frames,
        snapshot.corrupt_pages,
    );
    Ok(Report {
        json: json!({ "scenes": args.scenes, "metrics": snapshot }),
        text,
        exit_code: 0,
        as_json: args.json,
    })
}

/// The access policy the flags describe.
fn access(args: &ServeArgs) -> anyhow::Result<Access> {
    let mut tokens = match &args.tokens_file {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("reading {}", path.display()))?;
            Access::parse_tokens(&text).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?
        }
        None => Default::default(),
    };
    for token in &args.tokens {
        tokens.insert(token.clone(), None);
    }
    Ok(Access {
        tokens,
        allowed_origins: args.allowed_origins.clone(),
        allowed_hosts: args.allowed_hosts.clone(),
    })
}

/// SIGINT (Ctrl-C) and, on Unix, SIGTERM, registered when created.
struct Signals {
    #[cfg(unix)]
    interrupt: tokio::signal::unix::Signal,
    #[cfg(unix)]
    terminate: tokio::signal::unix::Signal,
}

impl Signals {
    fn new() -> std::io::Result<Self> {
        #[cfg(unix)]
        {
            use tokio::signal::unix::{SignalKind, signal};
            Ok(Self {
                interrupt: signal(SignalKind::interrupt())?,
                terminate: signal(SignalKind::terminate())?,
            })
        }
        #[cfg(not(unix))]
        {
            Ok(Self {})
        }
    }

    async fn recv(&mut self) {
        #[cfg(unix)]
        {
            tokio::select! {
                _ = self.interrupt.recv() => {}
                _ = self.terminate.recv() => {}
            }
        }
        #[cfg(not(unix))]
        {
            let _ = tokio::signal::ctrl_c().await;
        }
    }
}
