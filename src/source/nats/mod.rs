//! The fleet past one machine, on NATS JetStream: `dronewatt gateway LINK… --nats URL`
//! reads MAVLink links and publishes each vehicle's frames, with their arrival times, to
//! one JetStream stream; `dronewatt monitor --nats URL` is a worker that takes a share of
//! the stream's partitions through leases in a JetStream key-value bucket and runs the
//! chains of their vehicles exactly as `monitor` does on a link. The design, the
//! alternatives weighed and the figures are in the book's fleet chapter
//! (`docs/src/fleet-nats.md`).
//!
//! ```text
//!  links ─▶ gateway ─publish─▶ stream DRONEWATT_FRAMES          KV dronewatt_leases
//!             ▲                 dronewatt.frames.<part>.<net>.<sys>   p<part> = worker
//!             │                        │ ordered consumer per held partition
//!  dronewatt.to.<user>.<inst>.<net>.<sys> ◀── worker (monitor --nats): chains, sinks, checkpoints
//! ```
//!
//! - **Partitions.** A vehicle (network, system id) belongs to partition
//!   `(system id + 17 × network) mod` [`PARTITIONS`] (consecutive ids spread over all
//!   partitions, and so do fleets on several networks that reuse ids); its frames go to
//!   `dronewatt.frames.<part>.<net>.<sys>`. One stream keeps every frame (file storage,
//!   limits retention, [`STREAM_MAX_AGE`]).
//! - **Leases** ([`lease`]): key `p<part>` in the bucket [`LEASES`], whose entries expire
//!   [`LEASE_TTL`] after their last write. A worker renews its leases every [`RENEW`] with a
//!   compare-and-set on the revision it holds; a lease not renewed expires and another
//!   worker creates it. Workers register as `w.<id>` in the same bucket and take at most
//!   their fair share (partitions ÷ live workers, rounded up), releasing what is over it
//!   (the marker `r.<id>.p<part>`, whose user the server vouches for, then the deletion).
//!   A lease is not taken while it runs: the gateway judges every lease write
//!   ([`holders`]) and refuses the frames of a worker that took one out of turn.
//! - **State on takeover** ([`checkpoint`]): each second a worker writes its partitions'
//!   checkpoints: each vehicle's chain state (energy used, the pack's state and history,
//!   the mission's progress, the alerts standing) with the stream sequence to replay from,
//!   and the last sequence and source time it handed on. A worker that takes a partition
//!   restores the vehicles and replays from there (a checkpoint of another chain card or
//!   layout is said, and the partition rebuilt from the stream's first frame); its reports
//!   up to the previous holder's last time are not sent again ([`quiet`]), so no alert is
//!   raised twice.
//! - **Reports out** ([`publish`]): each estimate and alert event, as `--json` writes it, on
//!   `dronewatt.estimates.<part>.<net>.<sys>` and `dronewatt.alerts.<part>.<net>.<sys>`,
//!   only for the partitions the worker holds.
//! - **Restarts.** The client reconnects by itself (said in the log); each reconnection
//!   ([`reconnects`]) makes the workers' consumers again from the next sequence.
//! - **Back to the vehicles.** What a worker's chains send a vehicle (STATUSTEXT,
//!   NAMED_VALUE_FLOAT, BATTERY_STATUS, parameter and stream requests) goes to
//!   `dronewatt.to.<user>.<instance>.<net>.<sys>` ([`identity`]: the NATS user is what the
//!   server's permissions let that user publish on, so the gateway can trust it); the
//!   gateway sends it on that network's links only if `<user>.<instance>` holds the
//!   vehicle's partition at that moment, and signs it there (signing keys never leave the
//!   gateway). The server-side permissions: `config/nats-server.conf`.
//! - **Viewers** ([`view`]): `dronewatt vehicles --nats URL` lists each vehicle's latest
//!   estimate heard on `dronewatt.estimates.>`; `dronewatt dashboard --nats URL`
//!   (`cli::dashboard`, above both this source and the web sink) serves the web dashboard of the whole fleet from the same subjects.
//! - **Security** ([`connect`]): off loopback, a gateway or worker refuses to start without
//!   credentials (user and password, or a `.creds` file, read as the signing key is: a
//!   private file) and TLS.

pub mod checkpoint;
pub mod holders;
pub mod identity;
pub mod lease;
pub mod publish;
pub mod view;
pub mod wire;
pub mod worker;

use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Duration;

use anyhow::{bail, Context as _, Result};
use async_nats::jetstream::{self, stream};
use async_nats::ConnectErrorKind;

/// The stream every gateway publishes to.
pub const STREAM: &str = "DRONEWATT_FRAMES";
/// Subject prefix of the frames: `dronewatt.frames.<part>.<net>.<sys>`.
pub const FRAMES: &str = "dronewatt.frames";
/// Subject prefix of what workers send vehicles: `dronewatt.to.<user>.<instance>.<net>.<sys>`.
pub const TO: &str = "dronewatt.to";
/// The lease bucket.
pub const LEASES: &str = "dronewatt_leases";
/// The checkpoint bucket.
pub const CHECKPOINTS: &str = "dronewatt_checkpoints";
/// How many partitions the vehicles are spread over.
pub const PARTITIONS: u32 = 16;
/// A lease (and a worker's registration) not renewed for this long expires.
pub const LEASE_TTL: Duration = Duration::from_secs(6);
/// How often a worker renews its leases and writes its checkpoints.
pub const RENEW: Duration = Duration::from_secs(1);
/// How long the stream keeps a frame.
pub const STREAM_MAX_AGE: Duration = Duration::from_secs(24 * 3600);

/// How to reach NATS: the `--nats` flags `gateway` and `monitor` share.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct NatsArgs {
    /// NATS server (JetStream on): `nats://HOST:PORT`, or `tls://HOST:PORT`. With
    /// `monitor`, run as a fleet worker on the stream that `dronewatt gateway` feeds (no
    /// link address then). With `vehicles`, list the fleet's latest estimates as a viewer;
    /// with `dashboard`, serve the fleet's web dashboard as a viewer.
    /// Off loopback, credentials and TLS are required.
    #[arg(long, value_name = "URL")]
    pub nats: Option<String>,
    /// A NATS `.creds` file (JWT and nkey seed), private to its owner as the signing key is.
    #[arg(long, value_name = "FILE", requires = "nats")]
    pub nats_creds: Option<PathBuf>,
    /// NATS user name (with --nats-password-file).
    #[arg(long, value_name = "USER", requires = "nats_password_file")]
    pub nats_user: Option<String>,
    /// A private file holding the NATS user's password (its first line).
    #[arg(long, value_name = "FILE", requires = "nats_user")]
    pub nats_password_file: Option<PathBuf>,
    /// The CA certificate (PEM) that signed the NATS server's certificate; implies TLS.
    #[arg(long, value_name = "FILE", requires = "nats")]
    pub nats_ca: Option<PathBuf>,
}

/// Whether `url`'s host is this machine (`127.0.0.0/8`, `::1`, `localhost`).
pub fn is_loopback(url: &str) -> bool {
    let rest = url.split_once("://").map_or(url, |(_, r)| r);
    let hostport = rest.rsplit_once('@').map_or(rest, |(_, h)| h);
    let host = if let Some(h) = hostport.strip_prefix('[') {
        h.split(']').next().unwrap_or("")
    } else {
        hostport.split(':').next().unwrap_or("")
    };
    host.eq_ignore_ascii_case("localhost")
        || host
            .parse::<std::net::IpAddr>()
            .is_ok_and(|ip| ip.is_loopback())
}

/// Connection attempts before giving up at start, the first delay, the longest.
const CONNECT_TRIES: u32 = 5;
pub(crate) const BACKOFF_MIN: Duration = Duration::from_millis(500);
pub(crate) const BACKOFF_MAX: Duration = Duration::from_secs(4);

/// Connect to `a.nats` as `name`: off loopback only with credentials and TLS; an
/// unreachable server is retried with back-off (each retry logged) before the error.
/// Once connected, the client reconnects by itself and the log says so.
pub async fn connect(a: &NatsArgs, name: &str) -> Result<async_nats::Client> {
    let url = a.nats.clone().context("no --nats URL")?;
    let tls = url.starts_with("tls://") || a.nats_ca.is_some();
    let creds = a.nats_creds.is_some() || a.nats_user.is_some();
    let secured = tls && creds;
    if !is_loopback(&url) && !secured {
        bail!(
            "{url}: NATS off this machine needs credentials (--nats-creds FILE, or --nats-user \
             with --nats-password-file) and TLS (tls:// or --nats-ca): what a gateway sends \
             back reaches vehicles, so NATS is never open"
        );
    }
    let mut delay = BACKOFF_MIN;
    for attempt in 1..=CONNECT_TRIES {
        match options(a, name, tls)?.connect(url.as_str()).await {
            Ok(c) => {
                tracing::info!("NATS: connected to {url}");
                return Ok(c);
            }
            // Refused credentials, a TLS or address error: no retry mends them.
            Err(e)
                if matches!(
                    e.kind(),
                    ConnectErrorKind::AuthorizationViolation
                        | ConnectErrorKind::Authentication
                        | ConnectErrorKind::Tls
                        | ConnectErrorKind::ServerParse
                ) =>
            {
                bail!("NATS {url}: {e} (not retried)")
            }
            Err(e) if attempt < CONNECT_TRIES => {
                tracing::warn!(
                    "NATS {url}: cannot connect ({e}); retry {attempt}/{} in {:.1} s",
                    CONNECT_TRIES - 1,
                    delay.as_secs_f64()
                );
                tokio::time::sleep(delay).await;
                delay = (delay * 2).min(BACKOFF_MAX);
            }
            Err(e) => {
                bail!("NATS {url}: cannot connect after {CONNECT_TRIES} attempts: {e}")
            }
        }
    }
    bail!("NATS {url}: cannot connect")
}

/// The client's options: its name, the credentials (private files), TLS, and a log line
/// when the connection drops and comes back.
fn options(a: &NatsArgs, name: &str, tls: bool) -> Result<async_nats::ConnectOptions> {
    let mut opts = async_nats::ConnectOptions::new()
        .name(name)
        .connection_timeout(Duration::from_secs(3))
        .event_callback(move |e| async move {
            match e {
                async_nats::Event::Connected => {
                    // The first is the connection `connect` reports itself.
                    let mut n = 0;
                    RECONNECTS.send_modify(|c| {
                        *c += 1;
                        n = *c;
                    });
                    if n > 1 {
                        tracing::info!("NATS: reconnected");
                    }
                }
                async_nats::Event::Disconnected => {
                    tracing::warn!("NATS: disconnected; reconnecting")
                }
                // A permissions violation among them: this client's user may not publish
                // there (config/nats-server.conf), and the server dropped it.
                async_nats::Event::ServerError(e) => tracing::warn!("NATS: the server says: {e}"),
                other => tracing::debug!("NATS: {other}"),
            }
        });
    if let Some(f) = &a.nats_creds {
        let text = crate::files::read_private_text(f)
            .map_err(|e| anyhow::anyhow!("--nats-creds {}: {e}", f.display()))?;
        opts = opts
            .credentials(&text)
            .with_context(|| format!("--nats-creds {}: not a NATS .creds file", f.display()))?;
    }
    if let (Some(u), Some(f)) = (&a.nats_user, &a.nats_password_file) {
        let text = crate::files::read_private_text(f)
            .map_err(|e| anyhow::anyhow!("--nats-password-file {}: {e}", f.display()))?;
        let pass = text.lines().next().unwrap_or("").to_string();
        opts = opts.user_and_password(u.clone(), pass);
    }
    if let Some(ca) = &a.nats_ca {
        opts = opts.add_root_certificates(ca.clone());
    }
    if tls {
        opts = opts.require_tls(true);
    }
    Ok(opts)
}

/// Bumped each time the client (re)connects: a worker's readings make their consumers
/// again (a server restarted loses them).
static RECONNECTS: std::sync::LazyLock<tokio::sync::watch::Sender<u64>> =
    std::sync::LazyLock::new(|| tokio::sync::watch::Sender::new(0));

/// Told of each (re)connection from now on.
pub fn reconnects() -> tokio::sync::watch::Receiver<u64> {
    RECONNECTS.subscribe()
}

/// The partition of vehicle (`network`, `system_id`).
pub fn partition(network: u8, system_id: u8) -> u32 {
    (u32::from(system_id) + 17 * u32::from(network)) % PARTITIONS
}

/// The subject of one vehicle's frames.
pub fn frames_subject(network: u8, system_id: u8) -> String {
    format!(
        "{FRAMES}.{}.{network}.{system_id}",
        partition(network, system_id)
    )
}

/// The frame stream, created if absent; one with another layout is refused, by name.
pub async fn frames_stream(js: &jetstream::Context) -> Result<stream::Stream> {
    let want = stream::Config {
        name: STREAM.into(),
        subjects: vec![format!("{FRAMES}.>")],
        storage: stream::StorageType::File,
        retention: stream::RetentionPolicy::Limits,
        max_age: STREAM_MAX_AGE,
        ..Default::default()
    };
    let mut s = js
        .get_or_create_stream(want.clone())
        .await
        .map_err(|e| anyhow::anyhow!("NATS stream {STREAM}: {e}"))?;
    let have = &s
        .info()
        .await
        .map_err(|e| anyhow::anyhow!("NATS stream {STREAM}: {e}"))?
        .config;
    if have.subjects != want.subjects || have.retention != want.retention {
        bail!(
            "NATS stream {STREAM} has another layout (subjects {:?}, retention {:?}; dronewatt \
             needs {:?}, limits): refusing it (delete it, or use another server)",
            have.subjects,
            have.retention,
            want.subjects
        );
    }
    Ok(s)
}

/// A key-value bucket, created if absent (`history` values a key, entries expire after
/// `ttl`, none with `ZERO`); one whose stream has another layout is refused, by name.
pub async fn bucket(
    js: &jetstream::Context,
    name: &str,
    ttl: Duration,
    history: i64,
) -> Result<jetstream::kv::Store> {
    // The bucket's stream is made here as the key-value layout has it (async-nats's
    // create_key_value first asks for the account's info, whose reply a 2.9 server words
    // in a way this client does not parse).
    let config = stream::Config {
        name: format!("KV_{name}"),
        subjects: vec![format!("$KV.{name}.>")],
        max_messages_per_subject: history,
        max_age: ttl,
        storage: stream::StorageType::File,
        allow_rollup: true,
        deny_delete: true,
        allow_direct: true,
        discard: stream::DiscardPolicy::New,
        num_replicas: 1,
        ..Default::default()
    };
    js.get_or_create_stream(config)
        .await
        .map_err(|e| anyhow::anyhow!("NATS bucket {name}: {e}"))?;
    let kv = js
        .get_key_value(name)
        .await
        .map_err(|e| anyhow::anyhow!("NATS bucket {name}: {e}"))?;
    let mut s = js
        .get_stream(format!("KV_{name}"))
        .await
        .map_err(|e| anyhow::anyhow!("NATS bucket {name}: {e}"))?;
    let have = &s
        .info()
        .await
        .map_err(|e| anyhow::anyhow!("NATS bucket {name}: {e}"))?
        .config;
    if have.max_age != ttl || have.max_messages_per_subject != history {
        bail!(
            "NATS bucket {name} has another layout (entries expire after {:?}, history {}; \
             dronewatt needs {ttl:?}, {history}): refusing it (delete it, or use another server)",
            have.max_age,
            have.max_messages_per_subject
        );
    }
    Ok(kv)
}

/// Per partition: reports up to this source time were already sent by the partition's
/// previous holder (its checkpoint), so this worker's replay sends them no more.
static QUIET: Mutex<Option<HashMap<u32, f64>>> = Mutex::new(None);

/// Hold back this process's reports of partition `part` up to `t_s` (a worker taking it).
pub fn set_quiet(part: u32, t_s: f64) {
    if let Ok(mut g) = QUIET.lock() {
        g.get_or_insert_with(HashMap::new).insert(part, t_s);
    }
}

/// Whether a report of `vehicle` at `t_s` was already sent by another worker (a replay
/// after a takeover): never outside a NATS worker.
pub fn quiet(vehicle: crate::report::VehicleId, t_s: f64) -> bool {
    QUIET.lock().is_ok_and(|g| {
        g.as_ref().is_some_and(|m| {
            m.get(&partition(vehicle.network, vehicle.system_id))
                .is_some_and(|&until| t_s <= until)
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loopback_hosts_are_told_from_others() {
        for u in [
            "nats://127.0.0.1:4222",
            "nats://localhost:4222",
            "tls://[::1]:4222",
            "nats://u:p@127.0.0.2:1",
        ] {
            assert!(is_loopback(u), "{u}");
        }
        for u in [
            "nats://10.0.0.5:4222",
            "nats://nats.example.com",
            "tls://[fe80::1]:4222",
        ] {
            assert!(!is_loopback(u), "{u}");
        }
    }

    #[test]
    fn partitions_spread_consecutive_ids_and_keep_networks_apart() {
        let parts: std::collections::HashSet<u32> = (1..=16).map(|s| partition(0, s)).collect();
        assert_eq!(parts.len(), 16);
        // Two networks reusing system ids do not pile onto the same partitions.
        assert_ne!(partition(1, 1), partition(0, 1));
        let net2: std::collections::HashSet<u32> = (1..=16).map(|s| partition(2, s)).collect();
        assert_eq!(net2.len(), 16);
        assert_eq!(frames_subject(0, 3), "dronewatt.frames.3.0.3");
    }

    #[test]
    fn off_loopback_without_credentials_and_tls_is_refused() {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        let a = NatsArgs {
            nats: Some("nats://10.0.0.5:4222".into()),
            ..Default::default()
        };
        let e = rt.block_on(connect(&a, "t")).unwrap_err().to_string();
        assert!(e.contains("needs credentials") && e.contains("TLS"), "{e}");
    }
}
