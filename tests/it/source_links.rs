//! One vehicle over two radios: `dronewatt monitor udpin:…:P1 udpin:…:P2` against pymavlink
//! (`tests/peers/redundant.py`) sending the same frames, with the same sequence numbers, on
//! both links, each losing 30 % independently. The merged stream must hand on every frame
//! that at least one link brought, each exactly once; the per-link health must say what
//! each link brought; estimates must keep coming while one link is cut.

use crate::link_common;

use std::process::{Command, Stdio};

use serde_json::Value;

/// Run `monitor` on two free ports with `config`; (peer JSON, dronewatt's JSON lines, its
/// stderr).
fn run_with(config: &str, peer_args: &[&str]) -> (Value, Vec<Value>, String) {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("out.jsonl");
    let cfg = dir.path().join("dw.toml");
    std::fs::write(&cfg, config).unwrap();
    let ports = [link_common::free_udp_port(), link_common::free_udp_port()];
    let mut dw = Command::new(env!("CARGO_BIN_EXE_dronewatt"))
        .arg("monitor")
        .args(ports.map(|p| format!("udpin:127.0.0.1:{p}")))
        .arg("-q")
        .arg("--config")
        .arg(&cfg)
        .arg("--json")
        .arg(&json)
        .env("RUST_LOG", "dronewatt=info")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    for p in ports {
        link_common::wait_listening(p, false, &mut dw);
    }
    let ports = format!("{},{}", ports[0], ports[1]);
    let args: Vec<&str> = ["--ports", ports.as_str()]
        .into_iter()
        .chain(peer_args.iter().copied())
        .collect();
    let (peer, stderr) = link_common::peer_then_stop(dw, "redundant.py", &args);
    let lines = std::fs::read_to_string(&json)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    (peer, lines, stderr)
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

/// The `t` of every estimate that carries model output.
fn estimate_times(lines: &[Value]) -> Vec<f64> {
    lines
        .iter()
        .filter(|l| {
            l["type"] == "estimate" && l["models"].as_object().is_some_and(|m| !m.is_empty())
        })
        .map(|l| l["t"].as_f64().unwrap())
        .collect()
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
fn estimates_keep_coming_while_one_link_is_cut() {
    // Link 0 cut from 4 s to 10 s; link 1 loses 30 %.
    let (peer, lines, stderr) = run(&[
        "--seconds",
        "14",
        "--loss",
        "0.0,0.3",
        "--seed",
        "3",
        "--cut",
        "0:4:6",
    ]);
    let s = summary(&lines);
    let ctx = format!("peer: {peer}\nsummary: {s}\ndronewatt: {stderr}");
    assert_eq!(s["frames_ok"].as_u64(), peer["union"].as_u64(), "{ctx}");
    let t = estimate_times(&lines);
    let holes: Vec<(f64, f64)> = t
        .windows(2)
        .filter(|w| w[1] - w[0] > 1.0)
        .map(|w| (w[0], w[1]))
        .collect();
    assert!(
        t.len() > 50 && holes.is_empty(),
        "{} estimates, holes {holes:?}: {ctx}",
        t.len()
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
