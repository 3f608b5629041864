//! Several live links in one source: `monitor ADDR ADDR …` or the config's `[[links]]`.
//!
//! Each link runs as [`link::run`] does alone, with its own counters. Their messages
//! meet in one merged stream, keyed by the vehicle's system id across links (the same
//! vehicle over a radio and LTE is one vehicle), or by network and system id where the
//! config names separate networks ([`Networks`]: two fleets may both use system id 1):
//!
//! - **Networks.** Links that share a `network` name (by default all of them) are one
//!   network: deduplicated together, one vehicle per system id. Links on different networks
//!   never merge: every message carries its network's number
//!   ([`super::TimedMessage::network`]), the fleet keys vehicles by
//!   [`crate::report::VehicleId`], and what dronewatt sends a vehicle goes out on its own
//!   network's links only (one writer per network: [`LinkHandle::network`]).
//! - **Deduplicated.** A message whose (system id, component id, sequence, message id) and
//!   content ([`fingerprint`]: its payload's bytes) were already handed on is a copy from a
//!   redundant link and is dropped (counted in `duplicates`). The 8-bit sequence is unwrapped
//!   into a count of the sender's frames, on each link from that link's own previous number
//!   (a link carries a sender's frames in order, however far it lags the others), so a copy
//!   is recognised by the frame it is, not by when it came: a link that lags the first copy by
//!   many milliseconds under load still has its copies dropped, and a new frame that reuses a
//!   sequence number after a wrap (a stuck sensor's same bytes, 256 frames later) has another
//!   count and is never taken for a copy, at any rate. A copy must also come within
//!   [`DEDUP_WINDOW_S`] of the first (a sender that restarts its numbering is heard anew).
//! - **Per-link health** ([`LinkHealth`]), refreshed every second and published with the
//!   source's counters (the JSON summary's `links`): frames, rate, loss (the share of the
//!   merged stream this link did not bring), latency (how far behind the first copy its
//!   copies came), seconds since last heard, live or silent. A link that goes silent and
//!   comes back is logged once each way by its own transport.
//! - **Failover.** The merged stream flows while any link lives. dronewatt's own frames (the
//!   sink, the parameter reader, the mission client, all numbered by the one writer of their
//!   identity) go out on the best live link of the vehicle's network: the live one with the
//!   least loss, the first given on a tie; or on every link of it with
//!   `[link] every_link = true`.
//!
//! The merged stream's counters are the source's: `frames_ok` counts messages handed on
//! (each once), `gaps` breaks in the merged sequence of a sender (what no link brought);
//! bad frames, junk and signature counters are the links' summed.

pub mod address;
pub mod link;
mod rcvbuf;
pub mod signing;

use std::collections::HashMap as StdHashMap;

/// The merge's maps, looked up on every message: foldhash (several times faster than std's
/// SipHash on these small keys; the keys are senders and sequence numbers, bounded, so a
/// flood of keys is not a concern).
type HashMap<K, V> = StdHashMap<K, V, foldhash::fast::RandomState>;
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Result;
use mavlink::Message;
use tokio::sync::mpsc;

use super::TimedMessage;
use crate::report::status::{IngestStats, LinkHandle, LinkHealth};
use address::LinkAddress;
use link::{LinkIo, SILENCE};

/// The `[link]` table: signing on the live link `monitor` watches.
#[derive(Debug, Clone, Default, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct LinkConfig {
    /// File holding the 32-byte MAVLink 2 signing key (raw, hex or base64; mode 600). A
    /// relative path is resolved against the config file's folder. With a key, signed
    /// frames are verified and everything dronewatt sends is signed. Default: none.
    pub signing_key_file: Option<std::path::PathBuf>,
    /// Drop unsigned frames (MAVLink 1 included) instead of accepting them. Needs
    /// `signing_key_file`. Default false.
    pub require_signing: bool,
    /// Link id dronewatt puts in the frames it signs, 0–255. Default 0.
    pub signing_link_id: u8,
    /// Several links: dronewatt's own frames (the MAVLink sink's, the parameter reader's,
    /// the mission client's) go on every link instead of the best live one. Default false.
    pub every_link: bool,
    /// Never ask the vehicle anything: no parameter reads, no stream requests
    /// (MAV_CMD_SET_MESSAGE_INTERVAL, REQUEST_DATA_STREAM); only listen (and publish to
    /// the ground station as `[sinks.mavlink]` says). `monitor --listen-only`. Default false.
    pub listen_only: bool,
}

impl LinkConfig {
    /// Cross-field checks; the message names the key.
    pub fn validate(&self) -> Result<(), String> {
        if self.require_signing && self.signing_key_file.is_none() {
            return Err(
                "link.require_signing = true needs link.signing_key_file (the key to verify with)"
                    .into(),
            );
        }
        Ok(())
    }

    /// Read the key file, if one is configured. Errors name the key and the file.
    pub fn load(&self) -> Result<Option<signing::Signing>, String> {
        let Some(path) = &self.signing_key_file else {
            return Ok(None);
        };
        let key = signing::read_key_file(path)
            .map_err(|e| format!("link.signing_key_file = '{}': {e}", path.display()))?;
        Ok(Some(signing::Signing {
            key,
            require: self.require_signing,
            link_id: self.signing_link_id,
        }))
    }
}

/// A copy of a message heard again later than this many seconds after the first is taken
/// as new (a sender that restarted its numbering; a link more than a second behind).
pub const DEDUP_WINDOW_S: f64 = 1.0;

/// What the merge remembers of one sender: for each of its 256 sequence numbers, the last
/// frame handed on with it (its unwrapped count, message id, content and arrival time), and
/// the highest count handed on.
struct SenderMemory {
    slots: [(i64, u32, u64, f64); 256],
    head: Option<i64>,
    last_seq: Option<u8>,
}

impl SenderMemory {
    fn new() -> Box<Self> {
        Box::new(Self {
            slots: [(i64::MIN, u32::MAX, 0, f64::NEG_INFINITY); 256],
            head: None,
            last_seq: None,
        })
    }
}

/// `seq` unwrapped to the count nearest `near` (the count that has `seq` as its low byte).
fn unwrap_near(near: i64, seq: u8) -> i64 {
    // The low byte's difference read as a signed step (the `as` casts keep 8 bits on purpose).
    near + i64::from(seq.wrapping_sub(near as u8) as i8)
}

/// How far ahead of the head a link heard for the first time may be: its number is read as at
/// most this many frames ahead, else behind (a link that joins late lags, up to a wrap).
const JOIN_AHEAD: u8 = 16;

/// `seq` unwrapped to the count in (`head` − 256 + [`JOIN_AHEAD`], `head` + [`JOIN_AHEAD`]].
fn unwrap_behind(head: i64, seq: u8) -> i64 {
    let top = head + i64::from(JOIN_AHEAD);
    top - i64::from((top as u8).wrapping_sub(seq))
}

/// A message's content as a 64-bit fingerprint (FNV-1a over its MAVLink 2 payload): two
/// frames with the same header numbers but other bytes are two frames.
pub fn fingerprint(msg: &crate::MavMessage) -> u64 {
    let mut payload = [0u8; 255];
    let n = msg.ser(mavlink::MavlinkVersion::V2, &mut payload);
    payload[..n.min(255)]
        .iter()
        .fold(0xcbf2_9ce4_8422_2325_u64, |h, &b| {
            (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
        })
}

/// A sender: (network, system, component).
type Sender = (u8, u32, u8);

/// Which network each link is on: links sharing a name are one network.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Networks {
    /// Each link's network number, in link order: all 0 when every link is one network,
    /// else 1.. in the order the names first appear.
    pub of_link: Vec<u8>,
    /// The names, by number − 1 (empty when there is one network).
    pub names: Vec<String>,
}

impl Networks {
    /// Number the networks `names` gives each link (`""`: the network named `default`). One name
    /// (the usual case) is one network, numbered 0, and every vehicle reads as its system
    /// id alone. Fails beyond 255 networks.
    pub fn number(names: &[String]) -> Result<Self> {
        // The unnamed network reads `default` beside named ones.
        let names: Vec<String> = names
            .iter()
            .map(|n| {
                if n.is_empty() {
                    "default".into()
                } else {
                    n.clone()
                }
            })
            .collect();
        let mut distinct: Vec<String> = Vec::new();
        for n in &names {
            if !distinct.contains(n) {
                distinct.push(n.clone());
            }
        }
        if distinct.len() <= 1 {
            return Ok(Self {
                of_link: vec![0; names.len()],
                names: Vec::new(),
            });
        }
        if distinct.len() > 255 {
            anyhow::bail!("links: {} networks named; at most 255", distinct.len());
        }
        let of_link = names
            .iter()
            .map(|n| {
                let i = distinct.iter().position(|d| d == n).unwrap_or(0);
                u8::try_from(i + 1).unwrap_or(u8::MAX)
            })
            .collect();
        Ok(Self {
            of_link,
            names: distinct,
        })
    }
    /// Network `n`'s name (`None` on the only network).
    pub fn name(&self, n: u8) -> Option<&str> {
        usize::from(n)
            .checked_sub(1)
            .and_then(|i| self.names.get(i))
            .map(String::as_str)
    }
}

/// The merge's memory of what it handed on: per sender (network, system, component), the
/// last frame handed on for each of the 256 sequence numbers (its `SenderMemory`), and per link
/// and sender the count that link last brought (how it unwraps its next number).
#[derive(Default)]
pub struct Dedup {
    seen: HashMap<Sender, Box<SenderMemory>>,
    on_link: HashMap<(usize, Sender), i64>,
}

/// What the merge made of one message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Heard {
    /// The first copy: handed on; `gap` when the sender's sequence broke before it.
    First { gap: bool },
    /// A copy of a message already handed on.
    Duplicate,
}

impl Dedup {
    /// Whether this message (`msg_id`, content `fp`: [`fingerprint`]), heard at `t_s` on
    /// link `link` of `network`, is new or a copy.
    pub fn hear(
        &mut self,
        t_s: f64,
        link: usize,
        network: u8,
        header: &mavlink::MavHeader,
        msg_id: u32,
        fp: u64,
    ) -> Heard {
        let key = (network, header.system_id, header.component_id);
        let seq = header.sequence;
        let mem = self.seen.entry(key).or_insert_with(SenderMemory::new);
        let slot = mem.slots[usize::from(seq)];
        let same = slot.1 == msg_id && slot.2 == fp && t_s - slot.3 < DEDUP_WINDOW_S;
        // The frame's count: from this link's previous one, while that stays within a wrap of
        // the head; a link heard for the first time, or again after missing more than a wrap
        // (cut, or silent), is placed by content (a copy of the frame in its slot), else at
        // or behind the head.
        let from_link = self
            .on_link
            .get(&(link, key))
            .map(|&prev| unwrap_near(prev, seq))
            .filter(|&c| {
                mem.head
                    .is_none_or(|h| c > h - 256 + i64::from(JOIN_AHEAD) && c <= h + 128)
            });
        let count = match from_link {
            Some(c) => c,
            None if same => slot.0,
            None => mem.head.map_or(i64::from(seq), |h| unwrap_behind(h, seq)),
        };
        self.on_link.insert((link, key), count);
        if same && slot.0 == count {
            return Heard::Duplicate;
        }
        mem.slots[usize::from(seq)] = (count, msg_id, fp, t_s);
        mem.head = Some(mem.head.map_or(count, |h| h.max(count)));
        let gap = mem
            .last_seq
            .replace(seq)
            .is_some_and(|last| seq != last.wrapping_add(1));
        Heard::First { gap }
    }
}

/// One link's running tally, turned into its [`LinkHealth`] each second.
struct Tally {
    name: String,
    network: u8,
    frames: u64,
    duplicates: u64,
    /// This second: messages brought, their summed delay behind the first copy.
    got: u64,
    delay_s: f64,
    last_heard: Option<Instant>,
    stats: Arc<IngestStats>,
    out: LinkHandle,
    health: LinkHealth,
}

/// Run every link in `addrs` until `shutdown`, handing the merged, deduplicated stream to
/// `tx`. `networks` names each link's network (`""`: the default; [`Networks::number`]).
/// `link` is the chain's handle: what is sent on it goes out on the best live link, or on
/// each with `every_link`; with separate networks, on each network's best live link, and
/// [`LinkHandle::network`] gives the handle of one network's links.
/// Fails only when a link cannot be set up at all.
pub async fn run(
    addrs: Vec<LinkAddress>,
    networks: &[String],
    every_link: bool,
    io: LinkIo,
) -> Result<()> {
    let start = Instant::now();
    let nets = Networks::number(networks)?;
    for (n, name) in nets.names.iter().enumerate() {
        tracing::info!(
            "links: network {} is {name:?} (its vehicles read {}:SYSID)",
            n + 1,
            n + 1
        );
    }
    let (merged_tx, mut merged_rx) = mpsc::channel::<(usize, TimedMessage)>(1024);
    let (mut tallies, mut tasks) = spawn_links(addrs, &nets, &io, &merged_tx);
    drop(merged_tx);
    let count = nets.names.len();
    let best = attach_writers(&io, &tallies, count, every_link);

    let mut dedup = Dedup::default();
    let mut tick = tokio::time::interval(Duration::from_secs(1));
    let mut first_arrival: HashMap<(u8, u32, u8, u8, u32), Instant> = HashMap::default();
    // Messages handed on this second, per network.
    let mut unique = vec![0u64; count + 1];
    let mut last_t = 0.0f64;
    loop {
        tokio::select! {
            _ = io.shutdown.cancelled() => break,
            Some(r) = tasks.join_next() => {
                if let Ok(Err(e)) = r {
                    io.shutdown.cancel();
                    return Err(e);
                }
            }
            m = merged_rx.recv() => {
                let Some((i, mut m)) = m else { break };
                // One clock for the merged stream, never backwards (two links' messages
                // can reach the merge a few microseconds out of their arrival order).
                m.t_s = m.arrived.saturating_duration_since(start).as_secs_f64().max(last_t);
                last_t = m.t_s;
                let id = m.msg.message_id();
                let key = (m.network, m.header.system_id, m.header.component_id, m.header.sequence, id);
                let t = &mut tallies[i];
                t.frames += 1;
                t.got += 1;
                t.last_heard = Some(m.arrived);
                match dedup.hear(m.t_s, i, m.network, &m.header, id, fingerprint(&m.msg)) {
                    Heard::Duplicate => {
                        t.duplicates += 1;
                        if let Some(first) = first_arrival.get(&key) {
                            t.delay_s += m.arrived.saturating_duration_since(*first).as_secs_f64();
                        }
                        IngestStats::add(&io.stats.duplicates, 1);
                    }
                    Heard::First { gap } => {
                        first_arrival.insert(key, m.arrived);
                        unique[usize::from(m.network)] += 1;
                        IngestStats::add(&io.stats.frames_ok, 1);
                        if gap {
                            IngestStats::add(&io.stats.gaps, 1);
                        }
                        if !super::send(&io.tx, m, &io.stats, &io.shutdown).await {
                            break;
                        }
                    }
                }
            }
            _ = tick.tick() => {
                let cutoff = Instant::now() - Duration::from_secs_f64(DEDUP_WINDOW_S * 2.0);
                first_arrival.retain(|_, t| *t >= cutoff);
                publish(&mut tallies, &nets, &unique, &io.stats, &best);
                unique.iter_mut().for_each(|u| *u = 0);
            }
        }
    }
    publish(&mut tallies, &nets, &unique, &io.stats, &best);
    tasks.shutdown().await;
    Ok(())
}

/// Start each link's task, and a forwarder stamping its messages with the link's network
/// into the merge; each link's tally (its counters and its handle).
fn spawn_links(
    addrs: Vec<LinkAddress>,
    nets: &Networks,
    io: &LinkIo,
    merged_tx: &mpsc::Sender<(usize, TimedMessage)>,
) -> (Vec<Tally>, tokio::task::JoinSet<Result<()>>) {
    let mut tallies = Vec::new();
    let mut tasks = tokio::task::JoinSet::new();
    for (i, addr) in addrs.into_iter().enumerate() {
        let network = nets.of_link.get(i).copied().unwrap_or(0);
        let (ltx, mut lrx) = mpsc::channel::<TimedMessage>(256);
        let own = Arc::new(IngestStats::default());
        let out = LinkHandle::with_signer(io.link.signer());
        tallies.push(Tally {
            name: addr.to_string(),
            network,
            frames: 0,
            duplicates: 0,
            got: 0,
            delay_s: 0.0,
            last_heard: None,
            stats: own.clone(),
            out: out.clone(),
            health: LinkHealth::default(),
        });
        let fwd = merged_tx.clone();
        tokio::spawn(async move {
            while let Some(mut m) = lrx.recv().await {
                m.network = network;
                if fwd.send((i, m)).await.is_err() {
                    break;
                }
            }
        });
        let own_io = LinkIo {
            tx: ltx,
            stats: own,
            link: out,
            verifier: io.verifier.clone(),
            shutdown: io.shutdown.clone(),
        };
        tasks.spawn(link::run(addr, own_io));
    }
    (tallies, tasks)
}

/// What the chain sends goes to the best live link (of each network: the main handle's
/// own frames, with separate networks, go to every network's best link): a writer task per
/// handle; the best link of each network, as the merge will keep it.
fn attach_writers(
    io: &LinkIo,
    tallies: &[Tally],
    count: usize,
    every_link: bool,
) -> Arc<Vec<AtomicUsize>> {
    let best: Arc<Vec<AtomicUsize>> = Arc::new(
        (0..=count)
            .map(|n| AtomicUsize::new(first_of(tallies, n as u8).unwrap_or(0)))
            .collect(),
    );
    let outs: Vec<(u8, LinkHandle)> = tallies.iter().map(|t| (t.network, t.out.clone())).collect();
    let writer = |net: Option<u8>, handle: &LinkHandle| {
        let (wtx, mut wrx) = mpsc::channel::<Vec<u8>>(256);
        handle.attach(wtx);
        let (outs, best) = (outs.clone(), best.clone());
        tokio::spawn(async move {
            while let Some(frame) = wrx.recv().await {
                // Already numbered and signed by the chain's writer: sent as it is.
                route(&outs, &best, net, every_link, frame);
            }
        });
    };
    if count == 0 {
        writer(Some(0), &io.link);
    } else {
        writer(None, &io.link);
        let mut handles = vec![io.link.clone()];
        for n in 1..=count {
            let h = LinkHandle::with_signer(io.link.signer());
            writer(u8::try_from(n).ok(), &h);
            handles.push(h);
        }
        io.link.set_networks(handles);
    }
    best
}

/// The first link of network `net`.
fn first_of(tallies: &[Tally], net: u8) -> Option<usize> {
    tallies.iter().position(|t| t.network == net)
}

/// Send one of dronewatt's frames: on network `net`'s best live link (every network's with
/// `None`), or on each of its links with `every_link`.
fn route(
    outs: &[(u8, LinkHandle)],
    best: &[AtomicUsize],
    net: Option<u8>,
    every_link: bool,
    frame: Vec<u8>,
) {
    let mine = |n: u8| net.is_none_or(|w| w == n);
    if every_link {
        for (_, o) in outs.iter().filter(|(n, _)| mine(*n)) {
            let _ = o.try_send(frame.clone());
        }
        return;
    }
    let picks = match net {
        Some(n) => vec![best.get(usize::from(n)).map(|b| b.load(Relaxed))],
        None => best.iter().skip(1).map(|b| Some(b.load(Relaxed))).collect(),
    };
    for i in picks.into_iter().flatten() {
        if let Some((_, o)) = outs.get(i) {
            let _ = o.try_send(frame.clone());
        }
    }
}

/// Refresh every link's health, the summed counters and each network's best live link.
fn publish(
    tallies: &mut [Tally],
    nets: &Networks,
    unique: &[u64],
    stats: &IngestStats,
    best: &[AtomicUsize],
) {
    let now = Instant::now();
    for t in tallies.iter_mut() {
        let unique = unique.get(usize::from(t.network)).copied().unwrap_or(0);
        let last = t
            .last_heard
            .map(|l| now.saturating_duration_since(l).as_secs_f64());
        t.health = LinkHealth {
            name: t.name.clone(),
            network: nets.name(t.network).map(|n| (n.to_string(), t.network)),
            frames: t.frames,
            duplicates: t.duplicates,
            rate_hz: t.got as f64,
            loss_pct: if unique > 0 {
                100.0 * (1.0 - (t.got as f64 / unique as f64).min(1.0))
            } else {
                0.0
            },
            latency_ms: if t.got > 0 {
                1000.0 * t.delay_s / t.got as f64
            } else {
                0.0
            },
            last_heard_s: last,
            live: last.is_some_and(|s| s < SILENCE.as_secs_f64()),
        };
        t.got = 0;
        t.delay_s = 0.0;
    }
    for (n, b) in best.iter().enumerate() {
        let pick = tallies
            .iter()
            .enumerate()
            .filter(|(_, t)| usize::from(t.network) == n && t.health.live)
            .min_by(|a, b| a.1.health.loss_pct.total_cmp(&b.1.health.loss_pct))
            .map(|(i, _)| i)
            .or_else(|| first_of(tallies, n as u8));
        if let Some(p) = pick {
            b.store(p, Relaxed);
        }
    }
    // The links' own counters of what never made a message, summed.
    let sum = |f: fn(&IngestStats) -> &std::sync::atomic::AtomicU64| {
        tallies
            .iter()
            .map(|t| f(&t.stats).load(Relaxed))
            .sum::<u64>()
    };
    stats.frames_bad.store(sum(|s| &s.frames_bad), Relaxed);
    stats.unknown.store(sum(|s| &s.unknown), Relaxed);
    stats.junk_bytes.store(sum(|s| &s.junk_bytes), Relaxed);
    stats.signed_ok.store(sum(|s| &s.signed_ok), Relaxed);
    stats
        .signature_bad
        .store(sum(|s| &s.signature_bad), Relaxed);
    stats
        .signature_replay
        .store(sum(|s| &s.signature_replay), Relaxed);
    stats
        .unsigned_refused
        .store(sum(|s| &s.unsigned_refused), Relaxed);
    stats.silences.store(sum(|s| &s.silences), Relaxed);
    stats.silent.store(
        tallies.iter().all(|t| t.stats.silent.load(Relaxed)),
        Relaxed,
    );
    if let Ok(mut g) = stats.links.lock() {
        *g = tallies.iter().map(|t| t.health.clone()).collect();
    }
}

#[cfg(test)]
mod tests;
