//! The secured fleet's fixtures: nats-server on the shipped `config/nats-server.conf` (a free
//! loopback port), its users' password files, a `dronewatt gateway` and workers logged in
//! as those users, and raw NATS clients with their credentials.

use std::net::UdpSocket;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use crate::fleet_nats::server;
use crate::harness::{dronewatt, Monitor};
use crate::link_common::free_udp_port;

pub(crate) const CONFIG: &str = include_str!("../../config/nats-server.conf");

/// A client logged in as `user` (the shipped config's password), and the server's errors
/// it was told of (permissions violations).
pub(crate) async fn login(url: &str, user: &str) -> (async_nats::Client, Arc<Mutex<Vec<String>>>) {
    let errors = Arc::new(Mutex::new(Vec::new()));
    let seen = errors.clone();
    let c = async_nats::ConnectOptions::with_user_and_password(
        user.into(),
        format!("change-me-{user}"),
    )
    .event_callback(move |e| {
        let seen = seen.clone();
        async move {
            if let async_nats::Event::ServerError(e) = e {
                seen.lock().unwrap().push(e.to_string());
            }
        }
    })
    .connect(url)
    .await
    .unwrap_or_else(|e| panic!("{user}: {e}"));
    (c, errors)
}

/// A secured fleet's start: nats-server with the shipped config's users, a temp dir for their
/// password files, and a gateway on a free UDP port as the `gateway` user, listening. The
/// gateway is declared first, so that it stops before the server.
pub(crate) struct SecuredGateway {
    pub(crate) gateway: Monitor,
    pub(crate) port: u16,
    pub(crate) dir: tempfile::TempDir,
    pub(crate) nats: crate::fleet_nats::Server,
}

impl SecuredGateway {
    /// None where nats-server is not installed (allowed outside CI only).
    pub(crate) fn start() -> Option<Self> {
        let nats = server(Some(CONFIG))?;
        let dir = tempfile::tempdir().unwrap();
        let port = free_udp_port();
        let pw = private(dir.path(), "gateway.pw", "change-me-gateway\n");
        let gateway = gateway_as_user(&nats.url, port, &pw);
        Some(Self {
            gateway,
            port,
            dir,
            nats,
        })
    }

    /// The gateway, its UDP port and the server (the password files' folder goes: for a
    /// test that logs in with raw clients only).
    pub(crate) fn parts(self) -> (Monitor, u16, crate::fleet_nats::Server) {
        (self.gateway, self.port, self.nats)
    }

    /// `user`'s password file, as the shipped config sets it (`change-me-USER`).
    pub(crate) fn password(&self, user: &str) -> std::path::PathBuf {
        private(
            self.dir.path(),
            &format!("{user}.pw"),
            &format!("change-me-{user}\n"),
        )
    }

    /// `dronewatt monitor --nats` as `user`, writing `--json` to DIR/USER.jsonl.
    pub(crate) fn worker(&self, user: &str) -> Monitor {
        Monitor::spawn(
            dronewatt()
                .args([
                    "monitor",
                    "--nats",
                    &self.nats.url,
                    "--data-dir",
                    "off",
                    "-q",
                ])
                .args(["--nats-user", user, "--nats-password-file"])
                .arg(self.password(user))
                .arg("--json")
                .arg(self.dir.path().join(format!("{user}.jsonl")))
                .env("RUST_LOG", "dronewatt=info"),
        )
    }
}

/// A vehicle's socket on loopback, its reads timing out after 100 ms.
pub(crate) fn vehicle_socket() -> UdpSocket {
    let vehicle = UdpSocket::bind("127.0.0.1:0").unwrap();
    vehicle
        .set_read_timeout(Some(Duration::from_millis(100)))
        .unwrap();
    vehicle
}

/// `dronewatt gateway udpin:127.0.0.1:PORT` on the NATS server at `url` as the shipped
/// config's `gateway` user (its password in the file `pw`), listening.
pub(crate) fn gateway_as_user(url: &str, port: u16, pw: &std::path::Path) -> Monitor {
    let mut gateway = Monitor::spawn(
        dronewatt()
            .args(["gateway", &format!("udpin:127.0.0.1:{port}"), "--nats", url])
            .args(["--nats-user", "gateway", "--nats-password-file"])
            .arg(pw)
            .env("RUST_LOG", "dronewatt=info"),
    );
    gateway.wait_listening(port, false);
    gateway
}

/// A private file holding `text` (as the password files must be).
pub(crate) fn private(dir: &std::path::Path, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    std::fs::set_permissions(
        &p,
        <std::fs::Permissions as std::os::unix::fs::PermissionsExt>::from_mode(0o600),
    )
    .unwrap();
    p
}
