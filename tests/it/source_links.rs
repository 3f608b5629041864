//! One vehicle over two radios: `dronewatt monitor udpin:…:P1 udpin:…:P2` against pymavlink
//! (`tests/peers/redundant.py`) sending the same frames, with the same sequence numbers, on
//! both links, each losing 30 % independently. The merged stream must hand on every frame
//! that at least one link brought, each exactly once; the per-link health must say what
//! each link brought; estimates must keep coming while one link is cut.
//!
//! And two fleets whose vehicles share system id 1, on separate networks (`[[links]]
//! network`): the redundant pair is one network, a third link another. Each vehicle gets
//! its own estimates from its own telemetry, never the other's, and dronewatt answers each
//! on its own network's links only.

use crate::harness::{dronewatt, Monitor};
use crate::link_common;

use serde_json::{json, Value};

/// Run `monitor` on two free ports with `config`; (peer JSON, dronewatt's JSON lines, its
/// stderr).
fn run_with(config: &str, peer_args: &[&str]) -> (Value, Vec<Value>, String) {
    let r = run_links(config, peer_args, false);
    (r.peer, r.lines, r.stderr)
}

/// One run: what the peer said, dronewatt's JSON lines and stderr, the ports of its links.
struct Run {
    peer: Value,
    lines: Vec<Value>,
    stderr: String,
    ports: Vec<u16>,
}

/// Run `monitor` on two free ports (on its command line), or with `fleet` three, from the
/// config's `[[links]]`: the pair on the default network, the third on network `fleet2`
/// (the peer's second fleet).
fn run_links(config: &str, peer_args: &[&str], fleet: bool) -> Run {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("out.jsonl");
    let cfg = dir.path().join("dw.toml");
    let n = if fleet { 3 } else { 2 };
    let ports: Vec<u16> = (0..n).map(|_| link_common::free_udp_port()).collect();
    let addrs: Vec<String> = ports
        .iter()
        .map(|p| format!("udpin:127.0.0.1:{p}"))
        .collect();
    let mut config = config.to_string();
    if fleet {
        for (i, a) in addrs.iter().enumerate() {
            let net = if i == 2 { "network = \"fleet2\"\n" } else { "" };
            config.push_str(&format!("[[links]]\naddress = \"{a}\"\n{net}"));
        }
    }
    std::fs::write(&cfg, config).unwrap();
    let mut dw = Monitor::spawn(
        dronewatt()
            .arg("monitor")
            .args(if fleet { &addrs[..0] } else { &addrs[..] })
            .arg("-q")
            .arg("--config")
            .arg(&cfg)
            .arg("--json")
            .arg(&json)
            .env("RUST_LOG", "dronewatt=info"),
    );
    for &p in &ports {
        dw.wait_listening(p, false);
    }
    let pair = format!("{},{}", ports[0], ports[1]);
    let third = ports.get(2).map(u16::to_string);
    let mut args: Vec<&str> = vec!["--ports", pair.as_str()];
    if let Some(p) = &third {
        args.extend(["--fleet", p.as_str()]);
    }
    args.extend(peer_args.iter().copied());
    let (peer, stderr) = link_common::peer_then_stop(dw, "redundant.py", &args);
    let lines = std::fs::read_to_string(&json)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    Run {
        peer,
        lines,
        stderr,
        ports,
    }
}

fn run(peer_args: &[&str]) -> (Value, Vec<Value>, String) {
    run_with("", peer_args)
}

fn summary(lines: &[Value]) -> &Value {
    lines
        .iter()
        .find(|l| l["type"] == "summary")
        .expect("a summary line")
}

/// Every estimate that carries model output.
fn estimates(lines: &[Value]) -> impl Iterator<Item = &Value> {
    lines.iter().filter(|l| {
        l["type"] == "estimate" && l["models"].as_object().is_some_and(|m| !m.is_empty())
    })
}

/// The `t` of every estimate that carries model output.
fn estimate_times(lines: &[Value]) -> Vec<f64> {
    estimates(lines).map(|l| l["t"].as_f64().unwrap()).collect()
}

/// How many lines of `stderr` hold both `a` and `b`.
fn logged(stderr: &str, a: &str, b: &str) -> usize {
    stderr
        .lines()
        .filter(|l| l.contains(a) && l.contains(b))
        .count()
}

#[test]
fn two_lossy_links_merge_into_one_stream_without_duplicates_or_holes() {
    let (peer, lines, stderr) = run(&["--seconds", "12", "--loss", "0.3,0.3", "--seed", "7"]);
    let s = summary(&lines);
    let ctx = format!("peer: {peer}\nsummary: {s}\ndronewatt: {stderr}");
    let get = |v: &Value, k: &str| v[k].as_u64().unwrap_or_else(|| panic!("{k}: {ctx}"));
    let (packed, union, both) = (
        get(&peer, "packed"),
        get(&peer, "union"),
        get(&peer, "both"),
    );
    // Every frame that one link brought is handed on once: no copies, nothing one link
    // filled lost (loopback UDP loses nothing of its own).
    assert_eq!(get(s, "frames_ok"), union, "{ctx}");
    assert_eq!(get(s, "duplicates"), both, "{ctx}");
    // So the merged stream loses only what both links lost: 0.3 × 0.3 = 9 % expected; the
    // seeded draw here is what it is (printed), and the merge adds nothing to it.
    let merged_loss = 1.0 - union as f64 / packed as f64;
    assert!(
        merged_loss < 0.3 * 0.3 + 0.05,
        "merged loss {merged_loss:.3}: {ctx}"
    );
    // Per link: what it brought, and the share of the merged stream it missed (~30 %).
    let links = s["links"]
        .as_array()
        .unwrap_or_else(|| panic!("no links: {ctx}"));
    assert_eq!(links.len(), 2, "{ctx}");
    for (i, l) in links.iter().enumerate() {
        assert_eq!(
            l["frames"].as_u64(),
            peer["sent"][i].as_u64(),
            "link {i}: {ctx}"
        );
        assert!(
            l["name"].as_str().unwrap().starts_with("udpin:127.0.0.1:"),
            "{ctx}"
        );
    }
    println!(
        "packed {packed}, union {union} (merged loss {:.1} %), on both {both}, per link {} / {}",
        100.0 * merged_loss,
        peer["sent"][0],
        peer["sent"][1]
    );
    // dronewatt answered on one of the links (its best live one).
    let back = peer["heard_back"].as_array().unwrap();
    assert!(back.iter().any(|n| n.as_u64().unwrap() > 0), "{ctx}");
}

#[test]
fn estimates_keep_coming_at_their_rate_while_one_link_is_cut_for_10_s() {
    // Link 0 cut from 4 s to 14 s (longer than the 5 s a link takes to be called silent);
    // link 1 loses 30 % throughout.
    let r = run_links(
        "",
        &[
            "--seconds",
            "20",
            "--loss",
            "0.0,0.3",
            "--seed",
            "3",
            "--cut",
            "0:4:10",
        ],
        false,
    );
    let (peer, lines, stderr) = (&r.peer, &r.lines, &r.stderr);
    let s = summary(lines);
    let ctx = format!("peer: {peer}\nsummary: {s}\ndronewatt: {stderr}");
    assert_eq!(s["frames_ok"].as_u64(), peer["union"].as_u64(), "{ctx}");
    let t = estimate_times(lines);
    assert!(t.len() > 150, "{} estimates: {ctx}", t.len());
    // The rate, one-second bins from the first estimate to the last full second: the
    // telemetry's 10 Hz in every one, the cut's included. The cut is [4, 14) s on the peer's
    // clock, whose 0 is at most a window before the first estimate: [first + 4, first + 12)
    // lies inside it whatever that lead.
    let first = t[0];
    let bins = ((t[t.len() - 1] - first).floor() as usize).max(1);
    let mut per_s = vec![0u32; bins];
    for &x in &t {
        if let Some(b) = per_s.get_mut((x - first).floor() as usize) {
            *b += 1;
        }
    }
    let cut: Vec<u32> = per_s[4..12.min(bins)].to_vec();
    println!("estimates per second: {per_s:?} (cut: {cut:?})");
    // (A second's bin may lose one to its neighbour when a window falls on its edge.)
    assert!(
        per_s.iter().all(|&n| n >= 8),
        "estimates per second {per_s:?}: {ctx}"
    );
    let mean = f64::from(cut.iter().sum::<u32>()) / cut.len().max(1) as f64;
    assert!(
        cut.len() == 8 && cut.iter().all(|&n| n >= 8) && mean >= 9.5,
        "during the cut {cut:?}: {ctx}"
    );
    // The cut link's silence and return are logged once each way; the other link's never.
    let (cut_link, other) = (
        format!("udpin:127.0.0.1:{}:", r.ports[0]),
        format!("udpin:127.0.0.1:{}:", r.ports[1]),
    );
    assert_eq!(
        logged(stderr, &cut_link, "silent: no valid MAVLink frame"),
        1,
        "{ctx}"
    );
    assert_eq!(logged(stderr, &cut_link, "frames again after"), 1, "{ctx}");
    assert_eq!(
        logged(stderr, &other, "silent: no valid MAVLink frame"),
        0,
        "{ctx}"
    );
    assert_eq!(logged(stderr, &other, "frames again after"), 0, "{ctx}");
    assert_eq!(s["silences"].as_u64(), Some(1), "{ctx}");
}

#[test]
fn two_fleets_with_the_same_system_id_on_separate_networks_are_never_mixed() {
    // The vehicles send no capacity: the config gives their pack (none is assumed).
    let r = run_links(
        "[energy]\ncapacity_wh = 130.0\n",
        &["--seconds", "12", "--loss", "0.3,0.3", "--seed", "7"],
        true,
    );
    let (peer, lines, stderr) = (&r.peer, &r.lines, &r.stderr);
    let s = summary(lines);
    let ctx = format!("peer: {peer}\nsummary: {s}\ndronewatt: {stderr}");
    let get = |v: &Value, k: &str| v[k].as_u64().unwrap_or_else(|| panic!("{k}: {ctx}"));
    // The redundant pair merges with no copies and no holes; the other fleet's frames all
    // count once beside them.
    let (union, both, fleet) = (
        get(peer, "union"),
        get(peer, "both"),
        get(peer, "fleet_sent"),
    );
    assert_eq!(get(s, "frames_ok"), union + fleet, "{ctx}");
    assert_eq!(get(s, "duplicates"), both, "{ctx}");
    let merged_loss = 1.0 - union as f64 / get(peer, "packed") as f64;
    assert!(
        merged_loss < 0.3 * 0.3 + 0.05,
        "merged loss {merged_loss:.3}: {ctx}"
    );
    // Each vehicle (both system id 1) has its own estimates, from its own power: network 1
    // (the pair, 500 W), network 2 (the third link, 300 W). Never one without its network.
    let mut seen = [0usize; 3];
    for e in estimates(lines) {
        assert_eq!(e["system_id"], 1, "{e}");
        let net = e["network"]
            .as_u64()
            .unwrap_or_else(|| panic!("no network: {e}"));
        let w = e["measured_w"].as_f64().unwrap_or(f64::NAN);
        let want = match net {
            1 => 500.0,
            2 => 300.0,
            _ => panic!("network {net}: {e}"),
        };
        assert!((w - want).abs() < 2.0, "network {net} measured {w} W: {e}");
        seen[net as usize] += 1;
    }
    assert!(
        seen[1] > 80 && seen[2] > 80,
        "estimates per network {seen:?}: {ctx}"
    );
    // Their batteries: the pair's 80 %, the other's 60 %, each in its own energy line.
    for (net, pct) in [(1, 80.0), (2, 60.0)] {
        let last = estimates(lines)
            .filter(|e| e["network"] == net)
            .last()
            .unwrap();
        let rem = last["remaining_wh"].as_f64().unwrap();
        let cap = last["capacity_wh"].as_f64().unwrap();
        let got = 100.0 * rem / cap;
        assert!(
            (got - pct).abs() < 15.0,
            "network {net}: {got:.0} % left: {last}"
        );
    }
    // Each link says its network.
    let links = s["links"]
        .as_array()
        .unwrap_or_else(|| panic!("no links: {ctx}"));
    let nets: Vec<&Value> = links.iter().map(|l| &l["network"]).collect();
    assert_eq!(
        nets,
        [
            &json!(["default", 1]),
            &json!(["default", 1]),
            &json!(["fleet2", 2])
        ],
        "{ctx}"
    );
    assert!(stderr.contains("network 2 is \"fleet2\""), "{ctx}");
    // What dronewatt sent back: the pair's vehicle's estimates on the pair's links only,
    // the other's on the third link only (both as system id 1).
    let back = |i: usize| -> Option<(f64, f64)> {
        let m = &peer["meas_back"][i];
        Some((m[0].as_f64()?, m[1].as_f64()?))
    };
    let near = |(lo, hi): (f64, f64), w: f64| (lo - w).abs() < 2.0 && (hi - w).abs() < 2.0;
    let third = back(2).unwrap_or_else(|| panic!("nothing back on the third link: {ctx}"));
    assert!(near(third, 300.0), "third link heard {third:?}: {ctx}");
    let pair: Vec<(f64, f64)> = (0..2).filter_map(back).collect();
    assert!(
        !pair.is_empty() && pair.iter().all(|&b| near(b, 500.0)),
        "the pair heard {pair:?}: {ctx}"
    );
}

#[test]
fn with_every_link_dronewatt_answers_on_both_links() {
    let (peer, _, stderr) = run_with(
        "[link]\nevery_link = true\n",
        &["--seconds", "6", "--loss", "0.3,0.3", "--seed", "5"],
    );
    let back: Vec<u64> = peer["heard_back"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_u64().unwrap())
        .collect();
    // Every frame on both: about as many on each (a link answers once it has heard its
    // peer; the peer stops counting at its end while dronewatt still sends).
    let (lo, hi) = (back[0].min(back[1]), back[0].max(back[1]));
    assert!(
        lo > 20 && lo as f64 >= 0.85 * hi as f64,
        "heard back {back:?}; peer {peer}; dronewatt {stderr}"
    );
}
