//! Live links on 127.0.0.1 with real sockets: pymavlink as the peer for UDP and TCP, a
//! tokio server that drops the connection for the tcpout reconnect test.

use crate::mavlink_common;

use std::sync::atomic::Ordering::Relaxed;
use std::sync::Arc;
use std::time::Duration;

use dronewatt::report::status::{IngestStats, LinkHandle};
use dronewatt::source::{SourceSpec, TimedMessage};
use mavlink::MavlinkVersion::V2;
use mavlink_common::*;
use tokio::io::AsyncWriteExt;
use tokio::sync::mpsc;
use tokio_util::sync::CancellationToken;

struct Running {
    rx: mpsc::Receiver<TimedMessage>,
    stats: Arc<IngestStats>,
    link: LinkHandle,
    shutdown: CancellationToken,
    task: tokio::task::JoinHandle<anyhow::Result<()>>,
}

fn start(address: String) -> Running {
    let (tx, rx) = mpsc::channel(1024);
    let stats = Arc::new(IngestStats::default());
    let link = LinkHandle::default();
    let shutdown = CancellationToken::new();
    let task = tokio::spawn(dronewatt::source::run(
        SourceSpec::Link(address),
        tx,
        stats.clone(),
        link.clone(),
        None,
        shutdown.clone(),
    ));
    Running {
        rx,
        stats,
        link,
        shutdown,
        task,
    }
}

impl Running {
    /// Receive until `n` messages matched `keep` or `secs` passed.
    async fn take(
        &mut self,
        n: usize,
        secs: u64,
        keep: impl Fn(&TimedMessage) -> bool,
    ) -> Vec<TimedMessage> {
        let mut got = Vec::new();
        let deadline = tokio::time::Instant::now() + Duration::from_secs(secs);
        while got.len() < n {
            match tokio::time::timeout_at(deadline, self.rx.recv()).await {
                Ok(Some(m)) if keep(&m) => got.push(m),
                Ok(Some(_)) => {}
                _ => break,
            }
        }
        got
    }
    async fn stop(self) -> Arc<IngestStats> {
        self.shutdown.cancel();
        let r = tokio::time::timeout(Duration::from_secs(5), self.task)
            .await
            .expect("source stops on shutdown");
        r.expect("no panic").expect("no error");
        self.stats
    }
}

fn from_peer(m: &TimedMessage) -> bool {
    m.header.system_id == 1
}

fn our_heartbeat() -> Vec<u8> {
    use dronewatt::dialect::*;
    let msg = dronewatt::MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavtype: MavType::MAV_TYPE_GCS,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        ..Default::default()
    });
    frame(
        mavlink::MavHeader {
            system_id: 255,
            component_id: 190,
            sequence: 0,
        },
        &msg,
        V2,
    )
}

/// Run the pymavlink peer on a thread; join for its JSON.
fn peer_thread(args: Vec<String>) -> std::thread::JoinHandle<serde_json::Value> {
    std::thread::spawn(move || run_peer(&args.iter().map(String::as_str).collect::<Vec<_>>()))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn udpin_reads_pymavlink_answers_the_sender_and_reports_silence() {
    let port = free_udp_port();
    let mut run = start(format!("udpin:127.0.0.1:{port}"));
    tokio::time::sleep(Duration::from_millis(300)).await;
    let peer = peer_thread(vec![
        "send".into(),
        format!("udpout:127.0.0.1:{port}"),
        "40".into(),
    ]);
    let got = run.take(40, 15, from_peer).await;
    assert_eq!(got.len(), 40);
    assert!(
        got.windows(2).all(|w| w[1].t_s >= w[0].t_s),
        "arrival time is monotonic"
    );
    assert!(run.link.is_attached());
    assert!(run.link.try_send(our_heartbeat()), "writer accepts a frame");
    let report = tokio::task::spawn_blocking(move || peer.join().unwrap())
        .await
        .unwrap();
    assert_eq!(report["reply"]["sysid"], 255, "the peer heard us: {report}");
    assert_eq!(run.stats.frames_bad.load(Relaxed), 0);
    // Nothing more comes: after 5 s the link is reported silent, and that is not fatal.
    let quiet_since = tokio::time::Instant::now();
    while !run.stats.silent.load(Relaxed) && quiet_since.elapsed() < Duration::from_secs(10) {
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    assert!(run.stats.silent.load(Relaxed), "silence reported");
    assert!(
        quiet_since.elapsed() >= Duration::from_secs(3),
        "not before about 5 s of silence"
    );
    assert_eq!(run.stats.silences.load(Relaxed), 1);
    assert!(!run.task.is_finished());
    run.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn udpout_sends_a_gcs_heartbeat_and_reads_the_answers() {
    let port = free_udp_port();
    let peer = peer_thread(vec![
        "gcs".into(),
        format!("udpin:127.0.0.1:{port}"),
        "20".into(),
    ]);
    tokio::time::sleep(Duration::from_millis(700)).await; // let pymavlink bind
    let mut run = start(format!("udpout:127.0.0.1:{port}"));
    let got = run.take(20, 15, from_peer).await;
    let report = tokio::task::spawn_blocking(move || peer.join().unwrap())
        .await
        .unwrap();
    assert_eq!(report["heartbeat"]["sysid"], 255, "{report}");
    assert_eq!(report["heartbeat"]["compid"], 190, "{report}");
    assert_eq!(report["heartbeat"]["type"], 6, "MAV_TYPE_GCS: {report}");
    assert_eq!(got.len(), 20);
    run.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tcpin_accepts_a_pymavlink_client_and_writes_back_to_it() {
    let port = free_tcp_port();
    let mut run = start(format!("tcpin:127.0.0.1:{port}"));
    tokio::time::sleep(Duration::from_millis(300)).await;
    let peer = peer_thread(vec![
        "send".into(),
        format!("tcp:127.0.0.1:{port}"),
        "30".into(),
    ]);
    let got = run.take(30, 15, from_peer).await;
    assert_eq!(got.len(), 30);
    assert!(run.link.try_send(our_heartbeat()));
    let report = tokio::task::spawn_blocking(move || peer.join().unwrap())
        .await
        .unwrap();
    assert_eq!(report["reply"]["sysid"], 255, "{report}");
    let stats = run.stop().await;
    assert_eq!(stats.frames_bad.load(Relaxed), 0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tcpout_reconnects_after_the_server_drops_it() {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let port = listener.local_addr().unwrap().port();
    let recs = flight(10);
    let server_recs = recs.clone();
    let server = tokio::spawn(async move {
        for half in [&server_recs[..5], &server_recs[5..]] {
            let (mut s, _) = listener.accept().await.unwrap();
            for (_, h, m) in half {
                s.write_all(&frame(*h, m, V2)).await.unwrap();
            }
            s.flush().await.unwrap();
            tokio::time::sleep(Duration::from_millis(100)).await;
            drop(s); // the server goes away; the client must come back
        }
    });
    let mut run = start(format!("tcpout:127.0.0.1:{port}"));
    let got = run.take(10, 15, |_| true).await;
    server.await.unwrap();
    assert_eq!(got.len(), 10, "both halves arrive, across a reconnect");
    assert!(got.iter().zip(&recs).all(|(a, b)| a.msg == b.2));
    let stats = run.stop().await;
    assert_eq!(stats.frames_bad.load(Relaxed), 0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tcpout_to_nobody_keeps_retrying_and_stops_on_shutdown() {
    let port = free_tcp_port(); // nothing listens there
    let mut run = start(format!("tcpout:127.0.0.1:{port}"));
    tokio::time::sleep(Duration::from_millis(1200)).await;
    assert!(!run.task.is_finished(), "a refused connection is not fatal");
    // Refused at 0 s and 0.5 s; the vehicle comes up now, and the next retry (1.5 s, the
    // back-off doubling from 0.5 s) must find it: frames sent on it arrive.
    let listener = tokio::net::TcpListener::bind(("127.0.0.1", port))
        .await
        .unwrap();
    let accept = tokio::time::timeout(
        dronewatt::source::links::link::BACKOFF_MAX,
        listener.accept(),
    )
    .await;
    let (mut conn, _) = accept
        .expect("no retry reached the vehicle once it listened")
        .unwrap();
    let recs = flight(5);
    for (_, h, m) in &recs {
        conn.write_all(&frame(*h, m, V2)).await.unwrap();
    }
    let got = run.take(5, 5, |_| true).await;
    assert_eq!(got.len(), 5, "frames over the retried connection");
    let stats = run.stop().await;
    assert_eq!(stats.frames_ok.load(Relaxed), 5);
}
