use super::*;

#[test]
fn refuses_what_it_cannot_read() {
    let dir = tempfile::tempdir().unwrap();
    // A .ulg that is not ULog is taken, and reading it is an error naming it.
    let ulg = dir.path().join("log_1.ulg");
    std::fs::write(&ulg, b"x").unwrap();
    let err = format!(
        "{:#}",
        log_windows(&ulg, 1, &Config::default()).unwrap_err()
    );
    assert!(
        err.contains("log_1.ulg") && err.contains("not a readable PX4 ULog"),
        "{err}"
    );
    let txt = dir.path().join("notes.txt");
    std::fs::write(&txt, b"x").unwrap();
    let err = collect_logs(&[txt]).unwrap_err().to_string();
    assert!(
        err.contains("notes.txt")
            && err.contains(".tlog, ArduPilot DataFlash .bin and PX4 ULog .ulg"),
        "{err}"
    );
    assert!(collect_logs(&[dir.path().join("missing.tlog")])
        .unwrap_err()
        .to_string()
        .contains("no such file"));
    // A .bin that is not DataFlash is taken, and reading it is an error naming it.
    let bin = dir.path().join("00000001.BIN");
    std::fs::write(&bin, b"not a log").unwrap();
    let err = format!(
        "{:#}",
        log_windows(&bin, 1, &Config::default()).unwrap_err()
    );
    assert!(
        err.contains("00000001.BIN") && err.contains("not an ArduPilot DataFlash log"),
        "{err}"
    );
    // A folder: its .tlog and .bin files in name order, the rest skipped.
    for n in ["b.tlog", "a.TLOG", "c.ulg"] {
        std::fs::write(dir.path().join(n), b"").unwrap();
    }
    let got = collect_logs(&[dir.path().to_path_buf()]).unwrap();
    let names: Vec<_> = got
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        ["00000001.BIN", "a.TLOG", "b.tlog", "c.ulg", "log_1.ulg"]
    );
}
