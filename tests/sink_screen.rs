//! The terminal screen (`src/sink/screen/`) through a pseudo-terminal: `dronewatt replay
//! replay/demo.tlog` with the demo config (its web sink off) runs under `script` (util-linux,
//! which gives it a real pty, 160×45), draws for a few seconds, and must show the tiles'
//! titles with numbers after entering the alternate screen; then it is stopped, by the `q`
//! key through the pty or by SIGINT sent to its process, and must exit 0 with
//! the terminal given back: the alternate screen left and the cursor shown after its last
//! frame, and the run's closing lines printed after that. Skips loudly without `script`.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

const ENTER_ALT: &str = "\x1b[?1049h";
const LEAVE_ALT: &str = "\x1b[?1049l";
const SHOW_CURSOR: &str = "\x1b[?25h";
const HIDE_CURSOR: &str = "\x1b[?25l";

fn have_script() -> bool {
    Command::new("script")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success())
}

/// The demo config with the dashboard off, its vehicle profile named from the repository.
fn config(dir: &Path) -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let demo = std::fs::read_to_string(root.join("config/demo.toml")).unwrap();
    let vehicles = format!(
        "calibrated_profile = \"{}/",
        root.join("config/vehicles").display()
    );
    let cfg = dir.join("demo.toml");
    std::fs::write(
        &cfg,
        demo.replace(
            "[sinks.web]\nenabled = true",
            "[sinks.web]\nenabled = false",
        )
        .replace("calibrated_profile = \"vehicles/", &vehicles),
    )
    .unwrap();
    assert!(
        std::fs::read_to_string(&cfg)
            .unwrap()
            .contains("enabled = false"),
        "the web sink must be off"
    );
    cfg
}

/// Text with the escape sequences and whitespace taken out: the screen draws only the cells
/// that changed, with cursor moves between them, so words and numbers meet without spaces.
fn squeezed(s: &str) -> String {
    let mut out = String::new();
    let mut chars = s.chars();
    while let Some(c) = chars.next() {
        if c == '\x1b' {
            if chars.next() == Some('[') {
                for c in chars.by_ref() {
                    if ('@'..='~').contains(&c) {
                        break;
                    }
                }
            }
        } else if !c.is_whitespace() && !c.is_control() {
            out.push(c);
        }
    }
    out
}

/// Whether `word` is followed (`after`) or preceded by a digit somewhere in `s`.
fn number_beside(s: &str, word: &str, after: bool) -> bool {
    s.match_indices(word).any(|(i, _)| {
        if after {
            s[i + word.len()..]
                .chars()
                .next()
                .is_some_and(|c| c.is_ascii_digit() || c == '-' || c == '+')
        } else {
            s[..i]
                .chars()
                .next_back()
                .is_some_and(|c| c.is_ascii_digit())
        }
    })
}

/// Run `command` under `script` (a pty of 160×45); once the screen shows its tiles with
/// numbers, `stop` is called with script's stdin (the pty's keyboard) and the command's
/// process id. Returns the exit status and everything the pty showed.
fn under_pty(
    command: &str,
    stop: impl FnOnce(&mut std::process::ChildStdin, u32),
) -> (i32, String) {
    let dir = tempfile::tempdir().unwrap();
    let pid_file = dir.path().join("pid");
    let mut child = Command::new("script")
        .args([
            "-qfec",
            &format!(
                "stty cols 160 rows 45; echo $$ > {}; exec {command}",
                pid_file.display()
            ),
            "/dev/null",
        ])
        .env("TERM", "xterm-256color")
        .env("RUST_LOG", "dronewatt=info,warn")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("script runs");
    let out = Arc::new(Mutex::new(Vec::new()));
    let reader = {
        let out = out.clone();
        let mut stdout = child.stdout.take().unwrap();
        std::thread::spawn(move || {
            let mut buf = [0u8; 8192];
            while let Ok(n) = stdout.read(&mut buf) {
                if n == 0 {
                    break;
                }
                out.lock().unwrap().extend_from_slice(&buf[..n]);
            }
        })
    };
    let text = || String::from_utf8_lossy(&out.lock().unwrap()).into_owned();
    let drawn = |t: &str| {
        let s = squeezed(t);
        t.contains(ENTER_ALT)
            && number_beside(&s, "Wmeasured", false)
            && number_beside(&s, "msg/s", false)
            && number_beside(&s, "Wh", false)
    };
    let start = Instant::now();
    while !drawn(&text()) {
        if start.elapsed() > Duration::from_secs(60) || child.try_wait().unwrap().is_some() {
            let _ = child.kill();
            panic!(
                "the screen never showed its tiles with numbers; the pty showed:\n{:?}",
                text()
            );
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    // Let it draw a little longer (power history, alerts).
    std::thread::sleep(Duration::from_secs(2));
    let mut stdin = child.stdin.take().unwrap();
    let pid = std::fs::read_to_string(&pid_file).unwrap();
    stop(&mut stdin, pid.trim().parse().unwrap());
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if start.elapsed() > Duration::from_secs(30) {
            let _ = child.kill();
            panic!("it did not end once stopped; the pty showed:\n{:?}", text());
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    drop(stdin);
    reader.join().unwrap();
    (status.code().unwrap_or(-1), text())
}

/// The screen drew its tiles, then gave the terminal back after its last frame.
fn check(code: i32, out: &str) {
    assert_eq!(code, 0, "exit status; the pty showed:\n{out:?}");
    let s = squeezed(out);
    for title in [
        "Timeleft",
        "Stateofcharge",
        "Voltage",
        "Margins",
        "Power",
        "Packmodel",
        "Link",
        "Alerts",
        "last5min",
    ] {
        assert!(s.contains(title), "no {title} tile: {out:?}");
    }
    assert!(
        s.contains("restingvoltage"),
        "the state of charge's source: {s}"
    );
    assert!(number_beside(&s, "home", true), "home margin: {s}");
    assert!(number_beside(&s, "Whleft", false), "energy left: {s}");
    let entered = out.rfind(ENTER_ALT).expect("the alternate screen entered");
    let left = out.rfind(LEAVE_ALT).expect("the alternate screen left");
    assert!(
        left > entered,
        "left the alternate screen after entering it"
    );
    let shown = out.rfind(SHOW_CURSOR).expect("the cursor shown");
    assert!(shown > left, "the cursor shown as the screen is left");
    assert!(
        out.rfind(HIDE_CURSOR).is_none_or(|h| h < left),
        "nothing hides the cursor again"
    );
    // Only the closing lines after that: the run's counters, no more drawing.
    let tail = &out[shown + SHOW_CURSOR.len()..];
    assert!(tail.contains("done: frames ok"), "closing lines: {tail:?}");
    assert!(
        !tail.contains("\x1b[?"),
        "no terminal mode changes after: {tail:?}"
    );
    // Raw mode off: the closing lines end in the usual CR LF of a cooked terminal.
    assert!(tail.contains("\r\n"), "{tail:?}");
}

fn replay_command(cfg: &Path) -> String {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    format!(
        "{} replay {} --speed 20 --config {} --data-dir off",
        env!("CARGO_BIN_EXE_dronewatt"),
        root.join("replay/demo.tlog").display(),
        cfg.display()
    )
}

#[test]
fn the_screen_draws_and_q_restores_the_terminal() {
    if !have_script() {
        eprintln!("\n!!!!!!!! SKIPPED: no `script` (util-linux): the terminal screen is NOT tested !!!!!!!!\n");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let cfg = config(dir.path());
    let (code, out) = under_pty(&replay_command(&cfg), |stdin, _| {
        stdin.write_all(b"q").unwrap();
        stdin.flush().unwrap();
    });
    check(code, &out);
}

#[test]
fn sigint_restores_the_terminal() {
    if !have_script() {
        eprintln!("\n!!!!!!!! SKIPPED: no `script` (util-linux): the terminal screen is NOT tested !!!!!!!!\n");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let cfg = config(dir.path());
    let (code, out) = under_pty(&replay_command(&cfg), |_, pid| {
        let killed = Command::new("kill")
            .args(["-INT", &pid.to_string()])
            .status()
            .unwrap();
        assert!(killed.success());
    });
    check(code, &out);
}
