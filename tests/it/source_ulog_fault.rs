//! A PX4 ULog that breaks part-way (cut short, as when the battery is pulled mid-write):
//! the messages before the fault are kept, the fault is counted once, and `replay` says
//! which file, that it is corrupt or truncated and how much was read. A record the
//! `yule_log` parser panics on in the definitions is an error. The log is the simulator's `.ulg` (`dronewatt simulate --autopilot px4`).

use crate::harness::{dronewatt, RunExt};
use std::path::Path;
use std::sync::atomic::Ordering::Relaxed;

use dronewatt::report::status::IngestStats;
use dronewatt::source::logs::decode_autopilot_log;
use dronewatt::source::logs::ulog::{read_ulog, UlogError};

fn simulate(path: &Path) {
    let _out = dronewatt()
        .args(["simulate", "--autopilot", "px4", "--vehicle", "x500"])
        .args(["--leg-m", "100", "--hover-s", "10", "--seed", "3"])
        .args(["--out", path.to_str().unwrap()])
        .ok();
}

/// A format definition whose array length overflows a usize: `yule_log` panics on it (an
/// `unwrap`; the input in `fuzz/regressions/ulog/` is the fuzzer's form of it).
fn panicking_record() -> Vec<u8> {
    let body = b"bad:float[99999999999999999999999] y;";
    let mut r = (body.len() as u16).to_le_bytes().to_vec();
    r.push(b'F');
    r.extend_from_slice(body);
    r
}

/// The first record boundary at or after `at` (the 16-byte header, then records of a
/// 2-byte size, a type byte and the body).
fn boundary(log: &[u8], at: usize) -> usize {
    let mut i = 16;
    while i < at {
        i += 3 + usize::from(u16::from_le_bytes([log[i], log[i + 1]]));
    }
    i
}

#[test]
fn a_log_that_breaks_part_way_keeps_what_came_before() {
    let dir = tempfile::tempdir().unwrap();
    let ulg = dir.path().join("whole.ulg");
    simulate(&ulg);
    let good = std::fs::read(&ulg).unwrap();
    let stats = IngestStats::default();
    let (all, fault) = read_ulog(&good, &stats).unwrap();
    assert!(fault.is_none() && all.len() > 1000, "{}", all.len());
    assert_eq!(stats.frames_bad.load(Relaxed), 0);
    let end = all.last().unwrap().t_s;

    // Cut in the middle of a record, 60 % of the way in.
    let at = boundary(&good, good.len() * 6 / 10);
    let cut = &good[..at + 5];
    let stats = IngestStats::default();
    let (part, fault) = read_ulog(cut, &stats).unwrap();
    assert!(
        matches!(fault, Some(UlogError::CutShort { at: a, .. }) if a == at),
        "{fault:?}"
    );
    assert!(part.len() > all.len() / 2 && part.len() < all.len());
    assert!(part.last().unwrap().t_s < end);
    assert_eq!(stats.frames_bad.load(Relaxed), 1);
    // What was kept is what the whole log gives up to there.
    for (a, b) in part.iter().zip(&all) {
        assert_eq!(
            (a.t_s, format!("{:?}", a.msg)),
            (b.t_s, format!("{:?}", b.msg))
        );
    }

    // The parser's panics found so far are in the definitions (a format it cannot read),
    // before any data: an error, with nothing to keep. This one (an array length over a
    // usize) is now refused before the parser sees it.
    let first = boundary(&good, 17);
    let mut early = good[..first].to_vec();
    early.extend(panicking_record());
    early.extend_from_slice(&good[first..]);
    let e = read_ulog(&early, &IngestStats::default()).unwrap_err();
    assert!(
        e.to_string()
            .contains("format bad: an array of 99999999999999999999999"),
        "{e}"
    );

    // The reader `learn` and `replay` use keeps it too, and `replay` says so, naming the file.
    let broken = dir.path().join("broken.ulg");
    std::fs::write(&broken, cut).unwrap();
    let kept = decode_autopilot_log(&broken, &IngestStats::default()).unwrap();
    assert_eq!(kept.len(), part.len());
    let out = dronewatt()
        .args(["replay", "--speed", "max", "-q", "--data-dir", "off"])
        .arg(&broken)
        .out();
    let said = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{said}");
    assert!(
        said.contains("broken.ulg: a corrupt or truncated PX4 ULog")
            && said.contains(&format!("{} messages", part.len()))
            && said.contains("the rest of the file skipped")
            && said.contains(&format!("the records end at byte {at}")),
        "{said}"
    );
}

/// Formats that made `yule_log` abort (a stack overflow on a type that contains itself, an
/// allocation without bound on an array of a type of no size), which `catch_unwind` cannot
/// contain: refused before parsing, naming the format.
#[test]
fn formats_that_would_abort_the_parser_are_refused() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/regressions/ulog");
    for (file, says) in [
        ("format-selfref", "format b contains itself"),
        ("format-cycle", "contains itself"),
        ("format-hugearray", "format t: an array of 1000000000000"),
    ] {
        let bytes = std::fs::read(dir.join(file)).unwrap();
        match read_ulog(&bytes, &IngestStats::default()) {
            Err(e @ UlogError::UnsafeFormats(_)) => {
                assert!(e.to_string().contains(says), "{file}: {e}")
            }
            r => panic!("{file}: {:?}", r.map(|(m, f)| (m.len(), f))),
        }
    }
}

/// How libFuzzer's corpus (`fuzz/corpus/ulog`, after `scripts/fuzz.sh ulog SECONDS`) fares:
/// how many inputs read, read in part, are errors, and on which the parser panicked (caught),
/// by panic message. The figures in docs/src/reliability.md come from it:
/// `cargo test --test it source_ulog_fault:: -- --ignored --nocapture corpus_faults`.
#[test]
#[ignore]
fn corpus_faults() {
    std::panic::set_hook(Box::new(|_| {}));
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/corpus/ulog");
    let (mut whole, mut part, mut errors) = (0, 0, 0);
    let mut panics = std::collections::BTreeMap::<String, usize>::new();
    for e in std::fs::read_dir(&dir).unwrap() {
        let bytes = std::fs::read(e.unwrap().path()).unwrap();
        let r = read_ulog(&bytes, &IngestStats::default());
        let fault = match r {
            Ok((_, None)) => {
                whole += 1;
                None
            }
            Ok((_, Some(f))) => {
                part += 1;
                Some(f)
            }
            Err(f) => {
                errors += 1;
                Some(f)
            }
        };
        if let Some(UlogError::ParserPanicked(why)) = fault {
            let why: String = why.chars().take(60).collect();
            *panics.entry(why).or_default() += 1;
        }
    }
    println!("read whole {whole}, in part {part}, errors {errors}; parser panics caught:");
    for (why, n) in panics {
        println!("  {n:5}  {why}");
    }
}
