//! The command line over TLS with a token, against a real server on port 0
//! serving the test certificate (`tests/data/tls`): without the token the
//! render is refused with the server's 401 reason; with it, the image is
//! the one rendered from the file. Then the certificates people make: the
//! usual self-signed one (an authority, as `openssl req -x509` makes it)
//! pinned, `farfield-server cert`'s accepted, an untrusted one refused at
//! once with what to do; and a token that never shows in a URL or an error.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};

use clap::Parser;
use farfield_cli::cli::{Cli, run};
use farfield_image::files::compare_files;
use farfield_memory_server::tls::TlsFiles;
use farfield_render::headless_or_skip;

use crate::streaming::{runtime, scenes};

fn tls_file(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("data/tls")
        .join(name)
}

fn render(args: &[&str]) -> anyhow::Result<()> {
    run(Cli::try_parse_from(
        [
            "farfield",
            "render",
            "--orbit",
            "azimuth=30,elevation=25,distance=2.5",
            "--size",
            "160x120",
        ]
        .iter()
        .chain(args),
    )?)
}

#[test]
fn the_cli_renders_over_tls_with_a_token_and_is_refused_without() {
    if headless_or_skip(16, 16).unwrap().is_none() {
        return;
    }
    let (dir, _) = scenes("tls");
    let rt = runtime();
    let mut config =
        farfield_memory_server::ServerConfig::new(&dir, SocketAddr::from(([127, 0, 0, 1], 0)));
    config.tls = Some(TlsFiles {
        cert: tls_file("server.pem"),
        key: tls_file("server.key"),
    });
    config.access.tokens.insert("s3cret".into(), None);
    let server = rt
        .block_on(farfield_memory_server::start(config))
        .expect("server starts");
    let url = format!("https://127.0.0.1:{}", server.local_addr().port());
    let ca = tls_file("ca.pem");
    let (streamed, from_file) = (dir.join("tls.png"), dir.join("file.png"));
    let ca_arg = ca.to_str().unwrap();

    let refused = render(&[
        "--server",
        &url,
        "--scene",
        "island",
        "--ca-cert",
        ca_arg,
        "--out",
        streamed.to_str().unwrap(),
    ])
    .expect_err("rendered without the token");
    let why = format!("{refused:#}");
    assert!(why.contains("token"), "{why}");

    // The public roots do not know the test authority: refused, and said.
    let untrusted = render(&[
        "--server",
        &url,
        "--scene",
        "island",
        "--token",
        "s3cret",
        "--timeout-s",
        "3",
        "--out",
        streamed.to_str().unwrap(),
    ])
    .expect_err("trusted a certificate no public root signed");
    assert!(
        format!("{untrusted:#}")
            .to_lowercase()
            .contains("certificate"),
        "{untrusted:#}"
    );

    render(&[
        "--server",
        &url,
        "--scene",
        "island",
        "--token",
        "s3cret",
        "--ca-cert",
        ca_arg,
        "--out",
        streamed.to_str().unwrap(),
    ])
    .expect("render over TLS");
    render(&[
        "--file",
        dir.join("island.ff").to_str().unwrap(),
        "--out",
        from_file.to_str().unwrap(),
    ])
    .expect("render from the file");
    let same = compare_files(&streamed, &from_file, 8).expect("compare");
    assert!(
        same.metrics.psnr_db >= 40.0,
        "over TLS the image differs: {same:?}"
    );
    rt.block_on(server.shutdown()).expect("shutdown");
}

/// Writes `cert.pem` and `key.pem` for localhost and 127.0.0.1 into `dir`,
/// marked as an authority or not.
fn self_signed(dir: &Path, authority: bool) -> TlsFiles {
    let mut params =
        rcgen::CertificateParams::new(vec!["localhost".to_owned(), "127.0.0.1".to_owned()])
            .expect("params");
    if authority {
        // What `openssl req -x509` writes by default: basicConstraints CA:TRUE.
        params.is_ca = rcgen::IsCa::Ca(rcgen::BasicConstraints::Unconstrained);
    }
    let key = rcgen::KeyPair::generate().expect("key");
    let cert = params.self_signed(&key).expect("certificate");
    std::fs::create_dir_all(dir).expect("mkdir");
    let files = TlsFiles {
        cert: dir.join("cert.pem"),
        key: dir.join("key.pem"),
    };
    std::fs::write(&files.cert, cert.pem()).expect("write cert");
    std::fs::write(&files.key, key.serialize_pem()).expect("write key");
    files
}

/// Opens a session to `island` on `server` trusting `ca`, until its header
/// arrives or it fails; how long that took.
fn session_to(
    server: &str,
    ca: Option<&Path>,
    token: Option<&str>,
) -> (Result<(), String>, std::time::Duration) {
    use farfield_net::websocket::WebSocketTransport;
    use farfield_net::{Session, SessionEvent, SessionOptions, stream_url};
    let started = std::time::Instant::now();
    let transport = WebSocketTransport::trusting(ca).expect("transport");
    let options = SessionOptions {
        token: token.map(str::to_owned),
        first_connect_grace: std::time::Duration::from_secs(8),
        ..SessionOptions::default()
    };
    let mut session = Session::open(transport, stream_url(server, "island"), options);
    let result = loop {
        match session.pump(std::time::Duration::from_millis(50)) {
            Ok(events) if events.iter().any(|e| matches!(e, SessionEvent::Header(_))) => {
                break Ok(());
            }
            Ok(_) if started.elapsed() > std::time::Duration::from_secs(20) => {
                break Err("no header within 20 s".to_owned());
            }
            Ok(_) => {}
            Err(e) => break Err(e.to_string()),
        }
    };
    (result, started.elapsed())
}

fn serve_tls(
    rt: &tokio::runtime::Runtime,
    dir: &Path,
    files: TlsFiles,
) -> farfield_memory_server::RunningServer {
    let mut config =
        farfield_memory_server::ServerConfig::new(dir, SocketAddr::from(([127, 0, 0, 1], 0)));
    config.tls = Some(files);
    rt.block_on(farfield_memory_server::start(config))
        .expect("server starts")
}

/// The usual self-signed certificate is an authority; given with
/// `--ca-cert` it is the server's own, and pinned. Another one is refused
/// at once, never retried, with what to do.
#[test]
fn the_usual_self_signed_certificate_is_pinned_and_an_untrusted_one_fails_at_once() {
    let (dir, _) = scenes("tls-pinned");
    let rt = runtime();
    let files = self_signed(&dir.join("own"), true);
    let server = serve_tls(&rt, &dir, files.clone());
    let url = format!("https://127.0.0.1:{}", server.local_addr().port());
    let (pinned, _) = session_to(&url, Some(&files.cert), None);
    pinned.expect("the server's own authority certificate, pinned");
    let localhost = format!("https://localhost:{}", server.local_addr().port());
    session_to(&localhost, Some(&files.cert), None)
        .0
        .expect("by its name too");

    let other = self_signed(&dir.join("other"), true);
    let (refused, took) = session_to(&url, Some(&other.cert), None);
    let why = refused.expect_err("trusted a certificate it was not given");
    assert!(
        why.contains("--ca-cert") && why.contains("farfield-server cert"),
        "{why}"
    );
    assert!(
        took < std::time::Duration::from_secs(3),
        "retried for {took:?}: {why}"
    );
    rt.block_on(server.shutdown()).expect("shutdown");
}

/// `farfield-server cert` writes a key (its owner's only) and a server
/// certificate the client takes as its authority.
#[test]
fn farfield_server_cert_makes_a_pair_the_client_accepts() {
    use std::os::unix::fs::PermissionsExt;
    let (dir, _) = scenes("tls-cert-command");
    let out = dir.join("made");
    crate::cli(&[
        "cert",
        "--name",
        "localhost",
        "--name",
        "127.0.0.1",
        "--out",
        out.to_str().unwrap(),
    ])
    .expect("cert");
    let files = TlsFiles {
        cert: out.join("cert.pem"),
        key: out.join("key.pem"),
    };
    let mode = std::fs::metadata(&files.key)
        .expect("key")
        .permissions()
        .mode();
    assert_eq!(mode & 0o077, 0, "key readable by others: {mode:o}");
    let rt = runtime();
    let server = serve_tls(&rt, &dir, files.clone());
    let url = format!("https://localhost:{}", server.local_addr().port());
    session_to(&url, Some(&files.cert), None)
        .0
        .expect("accepted");
    rt.block_on(server.shutdown()).expect("shutdown");
}

/// A native client's token goes in a header: the request line a server (or
/// a proxy) logs does not hold it, and neither does the error the client
/// reports when it is refused, nor its options' `Debug`.
#[test]
fn a_token_is_in_no_url_and_no_error() {
    use std::io::{BufRead, BufReader, Write};
    const TOKEN: &str = "s3cret-never-shown";
    let listener = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = listener.local_addr().expect("address");
    let heads = std::thread::spawn(move || {
        let mut heads = Vec::new();
        // The session gives up at the first refusal: one request.
        let (stream, _) = listener.accept().expect("accept");
        let mut reader = BufReader::new(stream.try_clone().expect("clone"));
        let mut head = String::new();
        loop {
            let mut line = String::new();
            if reader.read_line(&mut line).expect("read") == 0 || line == "\r\n" {
                break;
            }
            head.push_str(&line);
        }
        let body = format!("{{\"error\":\"refused {TOKEN}\"}}").replace(TOKEN, "the token");
        let mut stream = stream;
        write!(
            stream,
            "HTTP/1.1 401 Unauthorized\r\ncontent-type: application/json\r\ncontent-length: {}\r\nconnection: close\r\n\r\n{body}",
            body.len()
        )
        .expect("answer");
        heads.push(head);
        heads
    });
    let (result, _) = session_to(&format!("http://{addr}"), None, Some(TOKEN));
    let error = result.expect_err("a 401 is a refusal");
    let heads = heads.join().expect("server thread");
    let head = &heads[0];
    let request_line = head.lines().next().unwrap_or_default();
    assert!(!request_line.contains(TOKEN), "{request_line}");
    assert!(
        head.lines()
            .any(|l| l.eq_ignore_ascii_case(&format!("authorization: Bearer {TOKEN}"))),
        "{head}"
    );
    assert!(!error.contains(TOKEN), "{error}");
    let options = farfield_net::SessionOptions {
        token: Some(TOKEN.into()),
        ..Default::default()
    };
    assert!(!format!("{options:?}").contains(TOKEN));
}
