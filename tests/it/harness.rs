//! How the tests run the `dronewatt` binary, said once (the product's tests in `tests/it/`
//! and the lab's in `lab/tests/it/` share this file): [`dronewatt`] builds the command,
//! [`RunExt::ok`] runs it and fails the test with its command line and standard error when it
//! fails, [`Monitor`] is a spawned long-running `dronewatt` (killed if the test panics), and
//! [`json_lines`] reads what `--json` wrote.
#![allow(dead_code)]

use std::ffi::OsStr;
use std::path::Path;
use std::process::{Child, Command, ExitStatus, Output, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

/// The workspace's root (where `Cargo.lock` is), from either package's tests.
pub fn root() -> &'static Path {
    let mut dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    while !dir.join("Cargo.lock").is_file() {
        dir = dir.parent().expect("a Cargo.lock above the package");
    }
    dir
}

/// A binary of the workspace: beside the test binary's folder (`target/debug/deps/..`), where
/// `cargo test --workspace` builds every package's binaries before any test runs.
pub fn bin(name: &str) -> std::path::PathBuf {
    let exe = std::env::current_exe().expect("the test binary's path");
    let dir = exe.parent().and_then(Path::parent).expect("target/debug");
    let path = dir.join(name);
    assert!(
        path.is_file(),
        "{}: not built (`cargo test --workspace` builds it; or `cargo build --workspace`)",
        path.display()
    );
    path
}

/// The lab's binary (`dronewatt-lab`), as [`dronewatt`] sets it up, run from the workspace's
/// root as the product's tests run theirs (the lab's commands find the shipped calibration
/// relative to it).
pub fn lab() -> Command {
    let mut c = Command::new(bin("dronewatt-lab"));
    c.current_dir(root())
        .env("DRONEWATT_HOME", "off")
        .env("RUST_LOG", "dronewatt=info,warn");
    c
}

/// The binary under test, with no vehicle store (`DRONEWATT_HOME=off`: a test never reads or
/// writes the store of the user running it; a test of the store names its own, by
/// `--data-dir` or `DRONEWATT_HOME` again) and its own default log filter (`RUST_LOG`
/// pinned, so what a test reads on stderr does not depend on the caller's environment).
pub fn dronewatt() -> Command {
    let mut c = Command::new(bin("dronewatt"));
    c.env("DRONEWATT_HOME", "off")
        .env("RUST_LOG", "dronewatt=info,warn");
    c
}

/// [`dronewatt`] logging warnings and errors only (`RUST_LOG=warn`): for a test that reads
/// its standard error line by line.
pub fn quiet() -> Command {
    let mut c = dronewatt();
    c.env("RUST_LOG", "warn");
    c
}

/// `dronewatt monitor udpin:127.0.0.1:PORT -q`, its other arguments to add; then
/// [`Monitor::listening`] on `port`.
pub fn monitor_udp(port: u16) -> Command {
    let mut c = dronewatt();
    c.args(["monitor", &format!("udpin:127.0.0.1:{port}"), "-q"]);
    c
}

/// `tests/peers/SCRIPT ARGS` in the test venv (`.venv-py`, `scripts/setup-python.sh`): an
/// independent reader (pymavlink, pyulog, LightGBM); it must succeed. Its standard output.
pub fn peer<I, S>(script: &str, args: I) -> Vec<u8>
where
    I: IntoIterator<Item = S>,
    S: AsRef<OsStr>,
{
    let root = root();
    let out = Command::new(root.join(".venv-py/bin/python"))
        .arg(root.join("tests/peers").join(script))
        .args(args)
        .output()
        .expect("run .venv-py/bin/python (scripts/setup-python.sh creates it)");
    assert!(
        out.status.success(),
        "{script}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}

/// `dronewatt ARGS`, run to its end; it must succeed.
pub fn run(args: &[&str]) -> Output {
    dronewatt().args(args).ok()
}

/// `dronewatt ARGS`, run to its end, whatever its exit status.
pub fn output(args: &[&str]) -> Output {
    dronewatt().args(args).out()
}

/// `dronewatt replay --speed max -q --json - ARGS LOG`, not yet run (to set its environment).
pub fn replay_max(log: &Path, args: &[&str]) -> Command {
    let mut c = dronewatt();
    c.args(["replay", "--speed", "max", "-q", "--json", "-"])
        .args(args)
        .arg(log);
    c
}

/// `dronewatt replay --speed max -q --json - ARGS LOG`: every JSON line of the replay.
pub fn replay_json(log: &Path, args: &[&str]) -> Vec<Value> {
    json_lines_of(&replay_max(log, args).ok().stdout)
}

/// `dronewatt simulate` of the short X500 delivery the learning tests fly (no payload,
/// 200 m legs, 20 s hover; seed `seed`, wind `seed + 1` m/s) to `path`, with `extra`
/// arguments.
pub fn simulate_x500(path: &Path, seed: u32, extra: &[&str]) {
    let (seed, wind) = (seed.to_string(), (seed + 1).to_string());
    dronewatt()
        .args(["simulate", "--vehicle", "x500", "--payload-g", "0"])
        .args(["--leg-m", "200", "--hover-s", "20", "--seed", &seed])
        .args(["--wind-mps", &wind])
        .args(extra)
        .arg("--out")
        .arg(path)
        .ok();
}

/// `learn` on three simulated X500 flights written as `.EXT` (with `sim_args`) and again as
/// `.tlog`: both must score the same flights alike (each model's learned MAPE within 0.5
/// points, under 15 %), and `replay` of the third `.EXT` log must give over 500 in-flight
/// estimates with measured power. The autopilot's own log is read as the radio's would be.
pub fn learn_scores_as_on_tlog(ext: &str, sim_args: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let mut got = Vec::new();
    for ext in [ext, "tlog"] {
        let logs = dir.path().join(ext);
        std::fs::create_dir_all(&logs).unwrap();
        for seed in 1..=3 {
            simulate_x500(&logs.join(format!("x500-{seed}.{ext}")), seed, sim_args);
        }
        let out = run(&[
            "learn",
            logs.to_str().unwrap(),
            "--holdout-every",
            "3",
            "--out",
            dir.path().join(format!("learned-{ext}")).to_str().unwrap(),
            "--data-dir",
            "off",
        ]);
        let said = String::from_utf8_lossy(&out.stdout).into_owned();
        assert!(said.contains(&format!("x500-3.{ext}")), "{said}");
        got.push(learned_mape(&said));
    }
    let (log, tlog) = (&got[0], &got[1]);
    assert!(
        log.len() >= 5 && log.len() == tlog.len(),
        "{log:?}\n{tlog:?}"
    );
    for ((nl, ml), (nt, mt)) in log.iter().zip(tlog) {
        assert_eq!(nl, nt);
        assert!(
            (ml - mt).abs() <= 0.5 && *ml < 15.0,
            "{nl}: .{ext} {ml} % vs .tlog {mt} %"
        );
    }

    // replay FILE.EXT: the live pipeline on the autopilot's own log, with measured power.
    let lines = replay_json(&dir.path().join(format!("{ext}/x500-3.{ext}")), &[]);
    let measured = lines
        .iter()
        .filter(|l| l["type"] == "estimate" && l["measured_w"].as_f64().is_some_and(|m| m > 100.0))
        .count();
    assert!(measured > 500, "{measured} in-flight estimates");
}

/// The learned MAPE column of `learn`'s held-out table, by model (physics models only).
fn learned_mape(stdout: &str) -> Vec<(String, f64)> {
    stdout
        .lines()
        .filter_map(|l| {
            let c: Vec<&str> = l.split('|').map(str::trim).collect();
            let v = c.get(3)?.parse::<f64>().ok()?;
            (c[1] != "lstm").then(|| (c[1].to_string(), v))
        })
        .collect()
}

/// Running a built command to its end.
pub trait RunExt {
    /// Its output, whatever its exit status.
    fn out(&mut self) -> Output;
    /// Its output; the test fails unless it exits 0, with the command line and its stderr.
    fn ok(&mut self) -> Output;
}

impl RunExt for Command {
    fn out(&mut self) -> Output {
        self.output()
            .unwrap_or_else(|e| panic!("cannot run {}: {e}", line(self)))
    }

    fn ok(&mut self) -> Output {
        let out = self.out();
        assert!(
            out.status.success(),
            "{} ({}): {}",
            line(self),
            out.status,
            String::from_utf8_lossy(&out.stderr)
        );
        out
    }
}

/// The command line, for a failure message.
fn line(c: &Command) -> String {
    std::iter::once(
        Path::new(c.get_program())
            .file_name()
            .unwrap_or(c.get_program()),
    )
    .chain(c.get_args())
    .map(OsStr::to_string_lossy)
    .collect::<Vec<_>>()
    .join(" ")
}

/// Every line of a JSON-lines text (a `--json -` standard output).
pub fn json_lines_of(text: &[u8]) -> Vec<Value> {
    String::from_utf8_lossy(text)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("not JSON ({e}): {l}")))
        .collect()
}

/// Every line of a JSON-lines file (a `--json FILE`).
pub fn json_lines(path: &Path) -> Vec<Value> {
    let text = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    json_lines_of(&text)
}

/// The last `estimate` line of a `--json` output's text.
pub fn last_estimate(text: &str) -> Value {
    text.lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .rfind(|v| v["type"] == "estimate")
        .unwrap()
}

/// Wait (60 s at most) until a `--json FILE` holds the summary line, which a replay writes
/// once every report reached the sinks; the file's text.
pub fn summary_written(json: &Path) -> String {
    let start = Instant::now();
    loop {
        let t = std::fs::read_to_string(json).unwrap_or_default();
        if t.contains("\"type\":\"summary\"") {
            return t;
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "the replay did not finish"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// A `dronewatt` left running (a `monitor`, a paced `replay`): standard output dropped,
/// standard error kept for [`Monitor::stop`]. Killed when dropped before it is stopped, so
/// a failing test leaves no process behind.
pub struct Monitor {
    child: Option<Child>,
}

impl Monitor {
    /// Start `cmd` (a [`dronewatt`] with its arguments).
    pub fn spawn(cmd: &mut Command) -> Monitor {
        let child = cmd
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {}: {e}", line(cmd)));
        Monitor { child: Some(child) }
    }

    /// Start `cmd` and wait until it holds `port` (`tcp`: a connect succeeds; UDP: our bind
    /// fails), so no frame a peer sends is lost to a socket not bound yet.
    pub fn listening(cmd: &mut Command, port: u16, tcp: bool) -> Monitor {
        let mut m = Monitor::spawn(cmd);
        m.wait_listening(port, tcp);
        m
    }

    /// Wait until it holds `port` (see [`Monitor::listening`]); fails the test with its
    /// stderr if it exits first, or after 60 s.
    pub fn wait_listening(&mut self, port: u16, tcp: bool) {
        let start = Instant::now();
        loop {
            let up = if tcp {
                std::net::TcpStream::connect(("127.0.0.1", port)).is_ok()
            } else {
                std::net::UdpSocket::bind(("127.0.0.1", port)).is_err()
            };
            if up {
                return;
            }
            let child = self.child.as_mut().unwrap();
            if let Ok(Some(status)) = child.try_wait() {
                let mut err = String::new();
                let _ = std::io::Read::read_to_string(child.stderr.as_mut().unwrap(), &mut err);
                panic!("dronewatt exited with {status} before listening: {err}");
            }
            assert!(
                start.elapsed() < Duration::from_secs(60),
                "dronewatt never listened on port {port}"
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// Its process id.
    pub fn id(&self) -> u32 {
        self.child.as_ref().unwrap().id()
    }

    /// Stop it with SIGTERM (its own orderly shutdown) and wait: its exit status and stderr.
    pub fn stop(mut self) -> (ExitStatus, String) {
        let mut child = self.child.take().unwrap();
        let _ = Command::new("kill")
            .args(["-TERM", &child.id().to_string()])
            .status();
        let status = child.wait().unwrap();
        let mut stderr = String::new();
        std::io::Read::read_to_string(child.stderr.as_mut().unwrap(), &mut stderr).unwrap();
        (status, stderr)
    }
}

impl Monitor {
    /// Kill it (SIGKILL: no chance to say goodbye) and wait.
    pub fn kill(mut self) {
        let mut child = self.child.take().unwrap();
        child.kill().unwrap();
        child.wait().unwrap();
    }
}

impl Drop for Monitor {
    fn drop(&mut self) {
        if let Some(mut child) = self.child.take() {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// A JSON array of arrays of numbers (a peer's dump) as rows.
pub fn json_rows(v: &Value) -> Vec<Vec<f64>> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|r| {
            r.as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect()
        })
        .collect()
}

/// A log reader's SYS_STATUS, one for each of the log's battery rows (`bat`: time µs,
/// volts, amps, as the peer dumped them): at the row's time from the first, with its volts
/// and amps to the message's resolution.
pub fn assert_sys_status_is_the_logs_battery(
    msgs: &[dronewatt::source::TimedMessage],
    bat: &[Vec<f64>],
) {
    let power: Vec<(f64, f64, f64)> = msgs
        .iter()
        .filter_map(|m| {
            if let dronewatt::MavMessage::SYS_STATUS(s) = &m.msg {
                Some((
                    m.t_s,
                    s.voltage_battery as f64 * 1e-3,
                    s.current_battery as f64 * 0.01,
                ))
            } else {
                None
            }
        })
        .collect();
    assert_eq!(power.len(), bat.len());
    for (p, r) in power.iter().zip(bat) {
        assert!(
            (p.0 - (r[0] - bat[0][0]) * 1e-6 - power[0].0).abs() < 1e-6,
            "{p:?} vs {r:?}"
        );
        assert!(
            (p.1 - r[1]).abs() < 1e-3 && (p.2 - r[2]).abs() < 1e-2,
            "{p:?} vs {r:?}"
        );
    }
}

/// The JSON lines with the summary's wall-clock fields (its latency and queue peaks) taken
/// out: everything else must be the same bytes run after run.
pub fn without_wall_clock(stdout: &str) -> String {
    stdout
        .lines()
        .map(|l| {
            if !l.contains("\"type\":\"summary\"") {
                return l.to_string();
            }
            let mut v: Value = serde_json::from_str(l).expect("summary JSON");
            if let Some(o) = v.as_object_mut() {
                for k in ["latency", "queue_peak", "queue_peak_at_s"] {
                    o.remove(k);
                }
            }
            v.to_string()
        })
        .collect::<Vec<_>>()
        .join("\n")
}
