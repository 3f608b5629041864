//! `dronewatt simulate --udp` delivers MAVLink frames to a real UDP socket on 127.0.0.1,
//! paced by `--rate`.

use crate::harness::dronewatt;
use std::net::UdpSocket;
use std::time::{Duration, Instant};

use dronewatt::MavMessage;

#[test]
fn streams_frames_to_a_udp_listener() {
    let sock = UdpSocket::bind("127.0.0.1:0").expect("bind");
    // Long enough for the binary to start; once frames flow, 0.5 s of quiet ends the stream.
    sock.set_read_timeout(Some(Duration::from_secs(20)))
        .expect("timeout");
    let port = sock.local_addr().expect("addr").port();
    let receiver = std::thread::spawn(move || {
        let mut got: Vec<MavMessage> = Vec::new();
        let mut buf = [0u8; 512];
        while let Ok(n) = sock.recv(&mut buf) {
            if got.is_empty() {
                let _ = sock.set_read_timeout(Some(Duration::from_millis(500)));
            }
            let mut r = mavlink::MavlinkReader::new(&buf[..n]);
            let (_, m) = r
                .read_any_message::<MavMessage>()
                .expect("one valid frame per datagram");
            got.push(m);
        }
        got
    });
    let start = Instant::now();
    // A ~40 s mission at 40× real time: about a second of wall clock.
    let out = dronewatt()
        .args([
            "simulate",
            "--udp",
            &format!("127.0.0.1:{port}"),
            "--rate",
            "40",
        ])
        .args(["--leg-m", "30", "--hover-s", "2", "--altitude-m", "5"])
        .output()
        .expect("run dronewatt simulate");
    let wall = start.elapsed();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let got = receiver.join().expect("receiver");
    let stderr = String::from_utf8_lossy(&out.stderr);
    let sent: usize = stderr
        .split("sent ")
        .nth(1)
        .and_then(|s| s.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no 'sent N frames' in: {stderr}"));
    assert!(sent > 500, "sent {sent}");
    assert_eq!(
        got.len(),
        sent,
        "every frame sent on loopback should arrive"
    );
    assert!(
        matches!(got[0], MavMessage::HEARTBEAT(_)),
        "the stream starts with a heartbeat"
    );
    assert!(got
        .iter()
        .any(|m| matches!(m, MavMessage::BATTERY_STATUS(_))));
    assert!(got
        .iter()
        .any(|m| matches!(m, MavMessage::GLOBAL_POSITION_INT(_))));
    // Paced, not flat out: a ~40 s flight at 40× takes about a second.
    assert!(
        wall > Duration::from_millis(600),
        "rate 40 should pace the stream, took {wall:?}"
    );
    assert!(wall < Duration::from_secs(10), "took {wall:?}");
}
