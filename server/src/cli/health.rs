//! `farfield-server health URL`: exits 0 when a server answers `GET
//! /healthz` with 200 within two seconds. The container images' healthcheck
//! (they hold no curl).

use std::io::{Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

use serde_json::json;

use super::{HealthArgs, Report};

const WAIT: Duration = Duration::from_secs(2);

pub fn run(args: &HealthArgs) -> anyhow::Result<Report> {
    let host = args
        .url
        .strip_prefix("http://")
        .ok_or_else(|| anyhow::anyhow!("{}: only http:// is checked", args.url))?
        .trim_end_matches('/');
    let addr = host
        .to_socket_addrs()?
        .next()
        .ok_or_else(|| anyhow::anyhow!("{host}: no address"))?;
    let mut stream = TcpStream::connect_timeout(&addr, WAIT)?;
    stream.set_read_timeout(Some(WAIT))?;
    stream.set_write_timeout(Some(WAIT))?;
    write!(stream, "GET /healthz HTTP/1.0\r\nHost: {host}\r\n\r\n")?;
    let mut answer = Vec::new();
    stream.take(4096).read_to_end(&mut answer)?;
    let status = String::from_utf8_lossy(&answer)
        .split_whitespace()
        .nth(1)
        .and_then(|s| s.parse::<u16>().ok());
    anyhow::ensure!(status == Some(200), "{host}: /healthz answered {status:?}");
    Ok(Report {
        json: json!({ "url": args.url, "healthy": true }),
        text: format!("{host}: healthy"),
        exit_code: 0,
        as_json: false,
    })
}
