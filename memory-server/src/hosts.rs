//! The names the server answers to, against DNS rebinding.
//!
//! A page on `evil.example` whose name is made to resolve to 127.0.0.1 is
//! same-origin with the server as far as the browser knows: its requests
//! carry `Host: evil.example:P` and a matching `Origin`, so an origin check
//! alone lets it read the scene list and stream scenes from a server on
//! loopback. Every request's `Host` is therefore checked against the names
//! the server is known by (as Vite's and webpack's dev servers, and
//! Jupyter, do): the address it listens on; `localhost` and loopback
//! addresses when it listens on loopback; any address, its machine's own
//! name and `localhost` when it listens on every interface; the names in
//! its TLS certificate; and each `--allowed-host NAME` (a reverse proxy's
//! public name; `*` turns the check off). Anything else is answered 421
//! (Misdirected Request). The port is not compared: a forwarded or mapped
//! port changes it without changing whom the request is for.

use std::collections::BTreeSet;
use std::net::{IpAddr, SocketAddr};

/// The hosts a server answers to.
#[derive(Debug, Clone, Default)]
pub struct Hosts {
    /// Any host at all (`--allowed-host '*'`).
    any: bool,
    /// Names (lower case, no trailing dot) besides the address rules.
    names: BTreeSet<String>,
    /// The address the server listens on.
    listen: Option<IpAddr>,
}

impl Hosts {
    /// The hosts a server listening on `listen` answers to, with the DNS
    /// names of its certificate (`cert_names`) and the operator's
    /// `allowed` names.
    pub fn new(listen: SocketAddr, cert_names: &[String], allowed: &[String]) -> Self {
        let mut names: BTreeSet<String> = cert_names
            .iter()
            .chain(allowed)
            .map(|n| normalize(n))
            .filter(|n| !n.is_empty())
            .collect();
        let any = names.contains("*");
        names.remove("*");
        if listen.ip().is_unspecified()
            && let Some(name) = machine_name()
        {
            names.insert(normalize(&name));
        }
        Self {
            any,
            names,
            listen: Some(listen.ip()),
        }
    }

    /// Whether a request whose `Host` header is `host` is for this server;
    /// a request without one (HTTP/1.0, not a browser) is.
    pub fn allows(&self, host: Option<&str>) -> bool {
        let Some(host) = host else { return true };
        if self.any {
            return true;
        }
        let name = normalize(strip_port(host));
        if let Ok(ip) = name.trim_matches(['[', ']']).parse::<IpAddr>() {
            // An address cannot be rebound: it is the server's own, or
            // another (a mistake, or a request meant elsewhere).
            return match self.listen {
                Some(listen) if listen.is_unspecified() => true,
                Some(listen) if listen.is_loopback() => ip.is_loopback(),
                Some(listen) => ip == listen,
                None => false,
            };
        }
        let local_name = name == "localhost" || name.ends_with(".localhost");
        let listens_locally = self
            .listen
            .is_some_and(|l| l.is_loopback() || l.is_unspecified());
        (local_name && listens_locally) || self.names.contains(&name)
    }

    /// The names a refusal suggests, for the log and the client.
    pub fn describe(&self) -> String {
        let mut known: Vec<String> = Vec::new();
        if let Some(listen) = self.listen {
            known.push(if listen.is_unspecified() {
                "any address".into()
            } else {
                listen.to_string()
            });
            if listen.is_loopback() || listen.is_unspecified() {
                known.push("localhost".into());
            }
        }
        known.extend(self.names.iter().cloned());
        known.join(", ")
    }
}

/// `host` without a trailing `:port` (an IPv6 address keeps its brackets).
fn strip_port(host: &str) -> &str {
    if let Some(end) = host.rfind(']') {
        return &host[..=end];
    }
    match host.rsplit_once(':') {
        // A bare IPv6 address has several colons and no port.
        Some((name, port)) if !name.contains(':') && port.bytes().all(|b| b.is_ascii_digit()) => {
            name
        }
        _ => host,
    }
}

/// Lower case, without a trailing dot (`Example.COM.` is `example.com`).
fn normalize(name: &str) -> String {
    name.trim().trim_end_matches('.').to_ascii_lowercase()
}

/// This machine's host name, where it has one.
fn machine_name() -> Option<String> {
    let name = std::fs::read_to_string("/proc/sys/kernel/hostname").ok()?;
    let name = name.trim();
    (!name.is_empty()).then(|| name.to_owned())
}

/// The DNS names a PEM certificate is for (its subject alternative names).
pub fn certificate_names(cert: &rustls::pki_types::CertificateDer<'_>) -> Vec<String> {
    match webpki::EndEntityCert::try_from(cert) {
        Ok(cert) => cert.valid_dns_names().map(str::to_owned).collect(),
        Err(_) => Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn on(listen: &str, allowed: &[&str]) -> Hosts {
        let allowed: Vec<String> = allowed.iter().map(|s| s.to_string()).collect();
        Hosts::new(listen.parse().unwrap(), &[], &allowed)
    }

    #[test]
    fn on_loopback_the_loopback_names_and_addresses_are_answered() {
        let hosts = on("127.0.0.1:7878", &[]);
        for host in [
            "127.0.0.1:7878",
            "127.0.0.1",
            "localhost:7878",
            "LOCALHOST.",
            "app.localhost:9",
            "[::1]:7878",
            "127.0.0.2:1",
        ] {
            assert!(hosts.allows(Some(host)), "{host}");
        }
        for host in [
            "evil.example:7878",
            "evil.example",
            "10.0.0.1:7878",
            "localhost.evil.example",
        ] {
            assert!(!hosts.allows(Some(host)), "{host}");
        }
        assert!(hosts.allows(None), "no Host header: not a browser");
    }

    #[test]
    fn named_hosts_are_answered_and_a_star_answers_all() {
        let hosts = on("10.1.2.3:443", &["viewer.example.org"]);
        assert!(hosts.allows(Some("Viewer.Example.Org:443")));
        assert!(hosts.allows(Some("10.1.2.3")));
        assert!(
            !hosts.allows(Some("localhost")),
            "not listening on loopback"
        );
        assert!(!hosts.allows(Some("10.1.2.4")));
        assert!(!hosts.allows(Some("evil.example")));
        assert!(on("10.1.2.3:443", &["*"]).allows(Some("anything.example")));
    }

    #[test]
    fn on_every_interface_any_address_is_answered_but_not_any_name() {
        let hosts = on("0.0.0.0:7878", &[]);
        assert!(hosts.allows(Some("192.168.1.20:7878")));
        assert!(hosts.allows(Some("[fe80::1]:7878")));
        assert!(hosts.allows(Some("localhost:7878")));
        assert!(!hosts.allows(Some("evil.example:7878")));
    }

    #[test]
    fn ports_are_cut_off_only_where_they_are() {
        assert_eq!(strip_port("example.org:80"), "example.org");
        assert_eq!(strip_port("[::1]:80"), "[::1]");
        assert_eq!(strip_port("::1"), "::1");
        assert_eq!(strip_port("example.org"), "example.org");
    }
}
