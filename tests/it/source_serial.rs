//! `serial:` on a pseudo-terminal pair (no hardware): frames written at one end arrive
//! decoded at the other, and frames a sink queues go back out.

use crate::mavlink_common;

use std::sync::Arc;
use std::time::Duration;

use dronewatt::report::status::{IngestStats, LinkHandle};
use dronewatt::source::SourceSpec;
use mavlink::MavlinkVersion::{V1, V2};
use mavlink_common::*;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio_serial::SerialPort;
use tokio_util::sync::CancellationToken;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn serial_reads_frames_and_writes_back_on_a_pty() {
    let (mut ours, theirs) = tokio_serial::SerialStream::pair().expect("a pty pair");
    let device = theirs.name().expect("the pty has a name");
    let (tx, mut rx) = tokio::sync::mpsc::channel(256);
    let stats = Arc::new(IngestStats::default());
    let link = LinkHandle::default();
    let shutdown = CancellationToken::new();
    let task = tokio::spawn(dronewatt::source::run(
        SourceSpec::Link(format!("serial:{device}:57600")),
        tx,
        stats.clone(),
        link.clone(),
        None,
        shutdown.clone(),
    ));
    tokio::time::sleep(Duration::from_millis(300)).await;
    let recs = flight(30);
    for (i, (_, h, m)) in recs.iter().enumerate() {
        ours.write_all(&frame(*h, m, if i % 2 == 0 { V1 } else { V2 }))
            .await
            .unwrap();
    }
    let mut got = 0;
    while got < 30 {
        match tokio::time::timeout(Duration::from_secs(10), rx.recv()).await {
            Ok(Some(_)) => got += 1,
            _ => break,
        }
    }
    assert_eq!(got, 30);
    // A sink's frame goes out on the port.
    let hb = frame(
        mavlink::MavHeader {
            system_id: 255,
            component_id: 190,
            sequence: 0,
        },
        &recs[0].2,
        V2,
    );
    assert!(link.try_send(hb.clone()));
    let mut back = vec![0u8; hb.len()];
    tokio::time::timeout(Duration::from_secs(5), ours.read_exact(&mut back))
        .await
        .expect("frame back in time")
        .unwrap();
    assert_eq!(back, hb);
    shutdown.cancel();
    tokio::time::timeout(Duration::from_secs(5), task)
        .await
        .unwrap()
        .unwrap()
        .unwrap();
    assert_eq!(stats.snapshot().frames_bad, 0);
}
