//! Live MAVLink links: `udpin:`, `udpout:`, `tcpin:`, `tcpout:` and `serial:` addresses,
//! the grammar MAVProxy and rust-mavlink users already know.
//!
//! The sockets are tokio's and the frames go through our own
//! [`FrameDecoder`](crate::source::frame::FrameDecoder), not rust-mavlink's connections: those
//! drop frames with a bad CRC silently, and link health is exactly what an operator
//! needs to see. `t_s` is seconds since the source started (monotonic arrival time).
//!
//! A link that brings no good frame for [`SILENCE`] is reported (a `tracing` warning and
//! the terminal view), never fatal. `tcpout:` and `serial:` reconnect with exponential
//! back-off ([`BACKOFF_MIN`] doubling to [`BACKOFF_MAX`]). Every link attaches a writer
//! to the [`LinkHandle`], so a sink can send frames back on the same link: `udpin:` to
//! the last peer heard, `udpout:` to its target, `tcpin:` to every connected client,
//! `tcpout:`/`serial:` to the open connection (frames queued while it is down are dropped).

use super::address::LinkAddress;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use mavlink::{MavHeader, MavlinkVersion};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream, UdpSocket};
use tokio::sync::mpsc;
use tokio_util::sync::CancellationToken;
use tracing::{info, warn};

use crate::dialect::{MavAutopilot, MavModeFlag, MavState, MavType, HEARTBEAT_DATA};
use crate::report::status::{IngestStats, LinkHandle};
use crate::source::frame::timed::TimedReader;
use crate::source::frame::SharedVerifier;
use crate::source::TimedMessage;
use crate::MavMessage;

/// No good frame for this long and the link is reported silent.
pub const SILENCE: Duration = Duration::from_secs(5);
/// First reconnect delay.
pub const BACKOFF_MIN: Duration = Duration::from_millis(500);
/// Longest reconnect delay.
pub const BACKOFF_MAX: Duration = Duration::from_secs(10);
/// System id dronewatt uses on a link: 255, the ground-station convention.
pub const GCS_SYSTEM_ID: u8 = 255;
/// Component id dronewatt uses on a link: `MAV_COMP_ID_MISSIONPLANNER` (190).
pub const GCS_COMPONENT_ID: u8 = 190;

/// What a live link runs with: the channel its messages go to, its counters, the handle
/// frames are written back through, the signature check of a signed link, and its stop.
pub struct LinkIo {
    /// Where the link's messages go.
    pub tx: mpsc::Sender<TimedMessage>,
    /// The link's counters.
    pub stats: Arc<IngestStats>,
    /// The handle the link attaches its writer to.
    pub link: LinkHandle,
    /// Checks incoming signatures (a signed link).
    pub verifier: Option<SharedVerifier>,
    /// Stops the link.
    pub shutdown: CancellationToken,
}

/// Run one live link until `io.shutdown`. Fails only when the link cannot be set up at
/// all (a port that cannot be bound, a name that does not resolve, a serial device that
/// cannot be opened at the start).
pub async fn run(addr: LinkAddress, io: LinkIo) -> Result<()> {
    let (wtx, wrx) = mpsc::channel::<Vec<u8>>(WRITE_QUEUE);
    io.link.attach(wtx);
    serve(addr, io, wrx, true).await
}

/// Frames queued for a link's writer before [`LinkHandle::try_send`] drops them.
const WRITE_QUEUE: usize = 256;

/// Open `addr` as an uplink: a link only written to (the MAVLink sink's own `address`).
/// The returned handle is attached before this returns, so no frame sent on it is lost
/// to a start-up race. What the other side sends is read and dropped; no ground-station
/// heartbeat goes out (the sink sends its own). Frames are signed as `base` signs them (the
/// monitored link's key). Runs until `stop`.
pub fn spawn_uplink(
    addr: LinkAddress,
    base: &LinkHandle,
    stop: CancellationToken,
) -> (LinkHandle, tokio::task::JoinHandle<Result<()>>) {
    let (wtx, wrx) = mpsc::channel::<Vec<u8>>(WRITE_QUEUE);
    let link = LinkHandle::with_signer(base.signer());
    link.attach(wtx);
    let writer = link.clone();
    let task = tokio::spawn(async move {
        let (tx, mut rx) = mpsc::channel::<TimedMessage>(64);
        let drain = tokio::spawn(async move { while rx.recv().await.is_some() {} });
        let io = LinkIo {
            tx,
            stats: Arc::new(IngestStats::default()),
            link: writer,
            verifier: None,
            shutdown: stop,
        };
        let r = serve(addr, io, wrx, false).await;
        let _ = drain.await;
        r
    });
    (link, task)
}

/// Run one link's transport. A `monitored` link (the one the chain reads) watches for
/// silence and, on `udpout:`, sends a ground-station heartbeat each second so routers
/// learn where to send; an uplink does neither.
async fn serve(
    addr: LinkAddress,
    io: LinkIo,
    wrx: mpsc::Receiver<Vec<u8>>,
    monitored: bool,
) -> Result<()> {
    let mut ctx = Ctx {
        link: io.link,
        verifier: io.verifier,
        label: addr.to_string(),
        tx: io.tx,
        stats: io.stats,
        shutdown: io.shutdown,
        start: Instant::now(),
        watchdog: Watchdog {
            last_count: 0,
            last_change: Instant::now(),
            silent: false,
        },
        monitored,
    };
    match addr {
        LinkAddress::UdpIn(a) => udp(&mut ctx, &a, false, wrx).await,
        LinkAddress::UdpOut(a) => udp(&mut ctx, &a, true, wrx).await,
        LinkAddress::TcpIn(a) => tcp_in(&mut ctx, &a, wrx).await,
        LinkAddress::TcpOut(a) => tcp_out(&mut ctx, &a, wrx).await,
        LinkAddress::Serial { device, baud } => serial(&mut ctx, &device, baud, wrx).await,
    }
}

/// What every transport shares.
struct Ctx {
    /// Signs our heartbeat when the link has a key.
    link: LinkHandle,
    /// What every reader checks signatures with, when the link has a key.
    verifier: Option<SharedVerifier>,
    label: String,
    tx: mpsc::Sender<TimedMessage>,
    stats: Arc<IngestStats>,
    shutdown: CancellationToken,
    start: Instant,
    watchdog: Watchdog,
    monitored: bool,
}

impl Ctx {
    /// A reader timed by arrival that checks signatures when the link has a key.
    fn reader(&self) -> TimedReader {
        reader(self.start, self.verifier.clone())
    }
    /// Send everything `reader` has decoded. False when the run is over.
    async fn deliver(&self, reader: &mut TimedReader) -> bool {
        deliver(reader, &self.tx, &self.stats, &self.shutdown).await
    }
    fn tick(&mut self) {
        if self.monitored {
            self.watchdog.tick(&self.label, &self.stats);
        }
    }
}

fn reader(start: Instant, verifier: Option<SharedVerifier>) -> TimedReader {
    let mut r = TimedReader::arrival(start);
    if let Some(v) = verifier {
        r.set_verifier(v);
    }
    r
}

async fn deliver(
    reader: &mut TimedReader,
    tx: &mpsc::Sender<TimedMessage>,
    stats: &IngestStats,
    shutdown: &CancellationToken,
) -> bool {
    while let Some(m) = reader.next_message(stats) {
        if !crate::source::send(tx, m, stats, shutdown).await {
            return false;
        }
    }
    true
}

/// Notices a link that brings no good frame for [`SILENCE`], and its return.
struct Watchdog {
    last_count: u64,
    last_change: Instant,
    silent: bool,
}

impl Watchdog {
    /// Called about once a second.
    fn tick(&mut self, label: &str, stats: &IngestStats) {
        use std::sync::atomic::Ordering::Relaxed;
        let n = stats.frames_ok.load(Relaxed);
        if n != self.last_count {
            if self.silent {
                info!(
                    "{label}: frames again after {:.0} s of silence",
                    self.last_change.elapsed().as_secs_f64()
                );
                self.silent = false;
                stats.silent.store(false, Relaxed);
            }
            self.last_count = n;
            self.last_change = Instant::now();
        } else if !self.silent && self.last_change.elapsed() >= SILENCE {
            warn!(
                "{label}: silent: no valid MAVLink frame for {} s",
                SILENCE.as_secs()
            );
            self.silent = true;
            stats.silent.store(true, Relaxed);
            IngestStats::add(&stats.silences, 1);
        }
    }
}

async fn resolve(label: &str, hostport: &str) -> Result<SocketAddr> {
    let mut addrs = tokio::net::lookup_host(hostport)
        .await
        .with_context(|| format!("{label}: cannot resolve '{hostport}'"))?;
    match addrs.next() {
        Some(a) => Ok(a),
        None => bail!("{label}: '{hostport}' resolves to no address"),
    }
}

/// A GCS heartbeat, so routers (mavlink-router, MAVProxy) learn to send to us.
fn heartbeat(sequence: u8) -> Vec<u8> {
    let msg = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_GCS,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    });
    let header = MavHeader {
        system_id: GCS_SYSTEM_ID as u32,
        component_id: GCS_COMPONENT_ID,
        sequence,
    };
    let mut out = Vec::with_capacity(32);
    let _ = mavlink::write_versioned_msg(&mut out, MavlinkVersion::V2, header, &msg);
    out
}

async fn udp(
    ctx: &mut Ctx,
    hostport: &str,
    out: bool,
    mut wrx: mpsc::Receiver<Vec<u8>>,
) -> Result<()> {
    let label = ctx.label.clone();
    let there = resolve(&label, hostport).await?;
    let (sock, mut peer) = if out {
        let local: SocketAddr = if there.is_ipv6() {
            "[::]:0"
        } else {
            "0.0.0.0:0"
        }
        .parse()?;
        let s = UdpSocket::bind(local)
            .await
            .with_context(|| format!("{label}: cannot open a UDP socket"))?;
        (s, Some(there))
    } else {
        (
            UdpSocket::bind(there)
                .await
                .with_context(|| format!("{label}: cannot bind {there}"))?,
            None,
        )
    };
    let rcvbuf = super::rcvbuf::grow_receive_buffer(&sock);
    info!(
        "{label}: {} (receive buffer {} KiB)",
        if out {
            format!("sending to {there}")
        } else {
            format!("listening on {there}")
        },
        rcvbuf / 1024
    );
    let mut reader = ctx.reader();
    let mut buf = vec![0u8; 65_536];
    let mut tick = tokio::time::interval(Duration::from_secs(1));
    let mut seq = 0u8;
    loop {
        tokio::select! {
            _ = ctx.shutdown.cancelled() => return Ok(()),
            r = sock.recv_from(&mut buf) => match r {
                Ok((n, from)) => {
                    if !out {
                        peer = Some(from);
                    }
                    reader.push(&buf[..n]);
                    // What else the socket holds, read now: one wake-up for a burst.
                    let newest = super::rcvbuf::drain(&sock, &mut buf, &mut reader, &label);
                    if !out && newest.is_some() {
                        peer = newest;
                    }
                    if !ctx.deliver(&mut reader).await {
                        return Ok(());
                    }
                }
                // e.g. ICMP port unreachable bounced back from a send: the link lives on.
                Err(e) => tracing::debug!("{label}: receive: {e}"),
            },
            Some(frame) = wrx.recv() => {
                if let Some(p) = peer {
                    if let Err(e) = sock.send_to(&frame, p).await {
                        tracing::debug!("{label}: send to {p}: {e}");
                    }
                }
            }
            _ = tick.tick() => {
                ctx.tick();
                if out && ctx.monitored {
                    let mut hb = heartbeat(seq);
                    ctx.link.sign(&mut hb);
                    let _ = sock.send_to(&hb, there).await;
                    seq = seq.wrapping_add(1);
                }
            }
        }
    }
}

async fn tcp_in(ctx: &mut Ctx, hostport: &str, mut wrx: mpsc::Receiver<Vec<u8>>) -> Result<()> {
    let label = ctx.label.clone();
    let at = resolve(&label, hostport).await?;
    let listener = TcpListener::bind(at)
        .await
        .with_context(|| format!("{label}: cannot listen on {at}"))?;
    info!("{label}: listening on {at}");
    let mut clients: Vec<mpsc::Sender<Vec<u8>>> = Vec::new();
    let mut tasks = tokio::task::JoinSet::new();
    let mut tick = tokio::time::interval(Duration::from_secs(1));
    loop {
        tokio::select! {
            _ = ctx.shutdown.cancelled() => break,
            r = listener.accept() => match r {
                Ok((stream, peer)) => {
                    info!("{label}: client {peer} connected");
                    let (ctx_tx, ctx_rx) = mpsc::channel(256);
                    clients.push(ctx_tx);
                    let (tx, stats, shutdown) = (ctx.tx.clone(), ctx.stats.clone(), ctx.shutdown.clone());
                    let mut reader = ctx.reader();
                    let label = label.clone();
                    tasks.spawn(async move {
                        let why = pump(stream, &mut reader, ctx_rx, &tx, &stats, &shutdown).await;
                        info!("{label}: client {peer} {why}");
                    });
                }
                Err(e) => warn!("{label}: accept: {e}"),
            },
            Some(frame) = wrx.recv() => {
                clients.retain(|c| !c.is_closed());
                for c in &clients {
                    let _ = c.try_send(frame.clone());
                }
            }
            Some(_) = tasks.join_next() => {}
            _ = tick.tick() => ctx.tick(),
        }
    }
    // Clients see the same shutdown; wait so their senders are gone when we return.
    while tasks.join_next().await.is_some() {}
    Ok(())
}

async fn tcp_out(ctx: &mut Ctx, hostport: &str, mut wrx: mpsc::Receiver<Vec<u8>>) -> Result<()> {
    let label = ctx.label.clone();
    let mut backoff = BACKOFF_MIN;
    let mut reader = ctx.reader();
    loop {
        let conn = tokio::select! {
            _ = ctx.shutdown.cancelled() => return Ok(()),
            r = async { TcpStream::connect(resolve(&label, hostport).await?).await.map_err(anyhow::Error::from) } => r,
        };
        match conn {
            Ok(stream) => {
                info!("{label}: connected");
                backoff = BACKOFF_MIN;
                let why = pump_watched(ctx, stream, &mut reader, &mut wrx).await;
                if ctx.shutdown.is_cancelled() || ctx.tx.is_closed() {
                    return Ok(());
                }
                warn!(
                    "{label}: connection {why}; reconnecting in {:.1} s",
                    backoff.as_secs_f64()
                );
            }
            Err(e) => warn!(
                "{label}: cannot connect ({e:#}); retrying in {:.1} s",
                backoff.as_secs_f64()
            ),
        }
        if !wait_backoff(ctx, &mut backoff, &mut wrx).await {
            return Ok(());
        }
    }
}

async fn serial(
    ctx: &mut Ctx,
    device: &str,
    baud: u32,
    mut wrx: mpsc::Receiver<Vec<u8>>,
) -> Result<()> {
    use tokio_serial::SerialPortBuilderExt;
    let label = ctx.label.clone();
    let open = || tokio_serial::new(device, baud).open_native_async();
    let mut port = Some(open().with_context(|| format!("{label}: cannot open"))?);
    let mut backoff = BACKOFF_MIN;
    let mut reader = ctx.reader();
    loop {
        if let Some(p) = port.take() {
            info!("{label}: open");
            backoff = BACKOFF_MIN;
            let why = pump_watched(ctx, p, &mut reader, &mut wrx).await;
            if ctx.shutdown.is_cancelled() || ctx.tx.is_closed() {
                return Ok(());
            }
            warn!(
                "{label}: port {why}; reopening in {:.1} s",
                backoff.as_secs_f64()
            );
        }
        if !wait_backoff(ctx, &mut backoff, &mut wrx).await {
            return Ok(());
        }
        match open() {
            Ok(p) => port = Some(p),
            Err(e) => warn!(
                "{label}: cannot open ({e}); retrying in {:.1} s",
                backoff.as_secs_f64()
            ),
        }
    }
}

/// Sleep the back-off (dropping frames queued for a link that is down, keeping the
/// watchdog going) and double it. False on shutdown.
async fn wait_backoff(
    ctx: &mut Ctx,
    backoff: &mut Duration,
    wrx: &mut mpsc::Receiver<Vec<u8>>,
) -> bool {
    let until = tokio::time::Instant::now() + *backoff;
    *backoff = (*backoff * 2).min(BACKOFF_MAX);
    let mut tick = tokio::time::interval(Duration::from_secs(1));
    loop {
        tokio::select! {
            _ = ctx.shutdown.cancelled() => return false,
            _ = tokio::time::sleep_until(until) => return true,
            Some(_) = wrx.recv() => {}
            _ = tick.tick() => ctx.tick(),
        }
    }
}

/// [`pump`] one connection with the link's watchdog ticking. Returns why it ended.
async fn pump_watched<S: AsyncRead + AsyncWrite + Unpin>(
    ctx: &mut Ctx,
    stream: S,
    reader: &mut TimedReader,
    wrx: &mut mpsc::Receiver<Vec<u8>>,
) -> String {
    let (mut rd, mut wr) = tokio::io::split(stream);
    let mut buf = vec![0u8; 16_384];
    let mut tick = tokio::time::interval(Duration::from_secs(1));
    let why = loop {
        tokio::select! {
            _ = ctx.shutdown.cancelled() => break "closed".to_string(),
            r = rd.read(&mut buf) => match r {
                Ok(0) => break "closed by the other side".to_string(),
                Ok(n) => {
                    reader.push(&buf[..n]);
                    if !ctx.deliver(reader).await {
                        break "closed".to_string();
                    }
                }
                Err(e) => break format!("failed: {e}"),
            },
            Some(frame) = wrx.recv() => {
                if let Err(e) = wr.write_all(&frame).await {
                    break format!("failed on write: {e}");
                }
            }
            _ = tick.tick() => ctx.tick(),
        }
    };
    end_stream(reader, &ctx.tx, &ctx.stats, &ctx.shutdown).await;
    why
}

/// Read one TCP client until it leaves or `shutdown`, writing what `wrx` brings. Returns
/// why it ended.
async fn pump(
    stream: TcpStream,
    reader: &mut TimedReader,
    mut wrx: mpsc::Receiver<Vec<u8>>,
    tx: &mpsc::Sender<TimedMessage>,
    stats: &IngestStats,
    shutdown: &CancellationToken,
) -> String {
    let (mut rd, mut wr) = stream.into_split();
    let mut buf = vec![0u8; 16_384];
    let why = loop {
        tokio::select! {
            _ = shutdown.cancelled() => break "closed".to_string(),
            r = rd.read(&mut buf) => match r {
                Ok(0) => break "left".to_string(),
                Ok(n) => {
                    reader.push(&buf[..n]);
                    if !deliver(reader, tx, stats, shutdown).await {
                        break "closed".to_string();
                    }
                }
                Err(e) => break format!("failed: {e}"),
            },
            Some(frame) = wrx.recv() => {
                if let Err(e) = wr.write_all(&frame).await {
                    break format!("failed on write: {e}");
                }
            }
        }
    };
    end_stream(reader, tx, stats, shutdown).await;
    why
}

/// A stream ended: decode what is left (a cut frame counts bad), then forget it.
async fn end_stream(
    reader: &mut TimedReader,
    tx: &mpsc::Sender<TimedMessage>,
    stats: &IngestStats,
    shutdown: &CancellationToken,
) {
    reader.finish();
    deliver(reader, tx, stats, shutdown).await;
    reader.reset();
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn addresses_parse_and_print_back() {
        for s in [
            "udpin:0.0.0.0:14550",
            "udpout:127.0.0.1:14550",
            "tcpin:[::1]:5760",
            "tcpout:localhost:5760",
            "serial:/dev/ttyUSB0:57600",
        ] {
            let a: LinkAddress = s.parse().unwrap();
            assert_eq!(a.to_string(), s);
        }
    }

    #[test]
    fn bad_addresses_name_the_address_and_the_forms() {
        for s in [
            "bogus",
            "udpin:14550",
            "tcpout:host:notaport",
            "quic:host:1",
            "serial:/dev/ttyS0:fast",
            "udpin::14550",
        ] {
            let e = s.parse::<LinkAddress>().unwrap_err().to_string();
            assert!(
                e.contains(s) && e.contains("udpin:HOST:PORT") && e.contains("serial:DEVICE:BAUD"),
                "{e}"
            );
        }
    }
}
