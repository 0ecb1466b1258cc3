//! `farfield wan`: an emulated wide-area network between two namespaces.

use crate::cli::WanArgs;

#[cfg(target_os = "linux")]
pub fn run(args: &WanArgs) -> anyhow::Result<()> {
    use farfield_tools::wan;
    let spec = wan::spec(args.rtt_ms, args.rate_mbit, args.loss_percent)?;
    wan::hold_stop_signals();
    let link = wan::Wan::start(&args.name, spec)?;
    println!(
        "ready: server namespace {} at {}, clients namespace {} at {}",
        link.server_namespace(),
        wan::SERVER_ADDR,
        link.client_namespace(),
        wan::CLIENT_ADDR
    );
    use std::io::Write;
    std::io::stdout().flush()?;
    wan::wait_for_stop();
    let counts = link.stop();
    println!("{}", serde_json::to_string(&counts)?);
    Ok(())
}

#[cfg(not(target_os = "linux"))]
pub fn run(_: &WanArgs) -> anyhow::Result<()> {
    anyhow::bail!("`farfield wan` needs Linux (network namespaces and TUN devices)")
}
