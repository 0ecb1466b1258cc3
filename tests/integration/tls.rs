//! The command line over TLS with a token, against a real server on port 0
//! serving the test certificate (`tests/data/tls`): without the token the
//! render is refused with the server's 401 reason; with it, the image is
//! the one rendered from the file.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};

use clap::Parser;
use farfield_client::cli::{Cli, run};
use farfield_image::files::compare_files;
use farfield_render::headless_or_skip;
use farfield_serve::tls::TlsFiles;

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
    let mut config = farfield_serve::ServerConfig::new(&dir, SocketAddr::from(([127, 0, 0, 1], 0)));
    config.tls = Some(TlsFiles {
        cert: tls_file("server.pem"),
        key: tls_file("server.key"),
    });
    config.access.tokens.insert("s3cret".into(), None);
    let server = rt
        .block_on(farfield_serve::start(config))
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
