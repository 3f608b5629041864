//! Reading the official `flights.csv[.gz]`: plain and gzip (by magic bytes), columns by
//! name, CRLF, and what happens to bad rows. Pieces of the real data set are cut into a
//! temp dir (never committed).

use std::io::{Read, Write};
use std::path::Path;

use dronewatt::offline::data::list_flights;
use dronewatt::source::logs::dataset::{flight_tlog, read_flights};

/// Header and the lines of flights 276 and 277 of the real file.
fn real_lines() -> (String, Vec<String>) {
    let mut text = String::new();
    flate2::read::MultiGzDecoder::new(
        std::fs::File::open(dronewatt::default_data_path()).expect("data set"),
    )
    .read_to_string(&mut text)
    .expect("gunzip");
    let mut lines = text.lines();
    let header = lines.next().unwrap().to_string();
    let keep = lines
        .filter(|l| l.starts_with("276,") || l.starts_with("277,"))
        .map(str::to_string)
        .collect();
    (header, keep)
}

fn write(path: &Path, text: &str, gz: bool) {
    let f = std::fs::File::create(path).unwrap();
    if gz {
        let mut e = flate2::write::GzEncoder::new(f, flate2::Compression::fast());
        e.write_all(text.as_bytes()).unwrap();
        e.finish().unwrap();
    } else {
        let mut f = f;
        f.write_all(text.as_bytes()).unwrap();
    }
}

#[test]
fn plain_crlf_gzip_and_reordered_columns_read_the_same() {
    let dir = tempfile::tempdir().unwrap();
    let (header, lines) = real_lines();
    let lf = format!("{header}\n{}\n", lines.join("\n"));
    let crlf = lf.replace('\n', "\r\n");
    // Columns in reverse order: found by name.
    let rev = |l: &str| l.split(',').rev().collect::<Vec<_>>().join(",");
    let reversed = format!(
        "{}\n{}\n",
        rev(&header),
        lines.iter().map(|l| rev(l)).collect::<Vec<_>>().join("\n")
    );
    let cases = [
        ("a.csv", &crlf, false),
        ("b.csv.gz", &lf, true),
        ("c.csv", &reversed, false),
        ("plain-named.gz", &lf, false),
    ];
    let reference = read_flights(&dronewatt::default_data_path(), Some(&[276, 277])).unwrap();
    assert_eq!(reference.flights.len(), 2);
    for (name, text, gz) in cases {
        let p = dir.path().join(name);
        write(&p, text, gz);
        let ds = read_flights(&p, None).unwrap();
        assert!(ds.skipped.is_empty(), "{name}: {:?}", ds.skipped);
        assert_eq!(ds.flights.len(), 2, "{name}");
        for (a, b) in ds.flights.iter().zip(&reference.flights) {
            assert_eq!(
                (a.flight, &a.route, a.speed_m_s, a.payload_g, a.altitude_m),
                (b.flight, &b.route, b.speed_m_s, b.payload_g, b.altitude_m)
            );
            assert_eq!(a.rows, b.rows, "{name}: flight {}", a.flight);
        }
    }
    let f276 = &reference.flights[0];
    assert_eq!(
        (
            f276.rows.len(),
            f276.route.as_str(),
            f276.speed_m_s,
            f276.payload_g,
            f276.altitude_m
        ),
        (984, "R1", 10.0, 500.0, 25.0)
    );
}

#[test]
fn bad_rows_are_skipped_and_named_bad_files_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let (header, mut lines) = real_lines();
    // Line 12 (1-based, header = line 1): a sensor cell that is not a number.
    let mut cells: Vec<String> = lines[10].split(',').map(str::to_string).collect();
    cells[15] = "1.2.3".into(); // velocity_z
    lines[10] = cells.join(",");
    // Line 21: a truncated row. Line 31: time going backwards.
    lines[19] = lines[19].split(',').take(10).collect::<Vec<_>>().join(",");
    let mut cells: Vec<String> = lines[29].split(',').map(str::to_string).collect();
    cells[1] = "0.05".into();
    lines[29] = cells.join(",");
    let p = dir.path().join("bad.csv");
    write(&p, &format!("{header}\n{}\n", lines.join("\n")), false);
    let ds = read_flights(&p, None).unwrap();
    let lines_skipped: Vec<usize> = ds.skipped.iter().map(|s| s.line).collect();
    assert_eq!(lines_skipped, vec![12, 21, 31]);
    assert!(
        ds.skipped[0].reason.contains("velocity_z") && ds.skipped[0].reason.contains("1.2.3"),
        "{:?}",
        ds.skipped[0]
    );
    assert!(
        ds.skipped[1].reason.contains("10 fields"),
        "{:?}",
        ds.skipped[1]
    );
    assert!(ds.skipped[2].reason.contains("time"), "{:?}", ds.skipped[2]);
    assert_eq!(ds.flights[0].rows.len(), 984 - 3);

    // A missing column is an error naming the file, the line and the column.
    let p2 = dir.path().join("nocol.csv");
    let drop = |l: &str| {
        l.split(',')
            .enumerate()
            .filter(|(i, _)| *i != 15)
            .map(|(_, c)| c)
            .collect::<Vec<_>>()
            .join(",")
    };
    write(
        &p2,
        &format!("{}\n{}\n", drop(&header), drop(&lines[0])),
        false,
    );
    let e = format!("{:#}", read_flights(&p2, None).unwrap_err());
    assert!(
        e.contains("nocol.csv") && e.contains("line 1") && e.contains("'velocity_z'"),
        "{e}"
    );

    // A damaged gzip, and a flight that is not there.
    let p3 = dir.path().join("cut.csv.gz");
    write(&p3, &format!("{header}\n{}\n", lines.join("\n")), true);
    let bytes = std::fs::read(&p3).unwrap();
    std::fs::write(&p3, &bytes[..bytes.len() / 2]).unwrap();
    let e = format!("{:#}", read_flights(&p3, None).unwrap_err());
    assert!(e.contains("cut.csv.gz") && e.contains("gzip"), "{e}");
    let e = format!("{:#}", flight_tlog(&p, 5).unwrap_err());
    assert!(
        e.contains("flight 5 is not in this file") && e.contains("276-277"),
        "{e}"
    );
}

#[test]
fn list_and_convert_a_flight() {
    let dir = tempfile::tempdir().unwrap();
    let (header, lines) = real_lines();
    let p = dir.path().join("two.csv.gz");
    write(&p, &format!("{header}\n{}\n", lines.join("\n")), true);
    let list = list_flights(&p).unwrap();
    assert_eq!(
        list.iter().map(|f| f.flight).collect::<Vec<_>>(),
        vec![276, 277]
    );
    assert_eq!(list[0].rows, 984);
    assert!(
        (list[0].duration_s - 147.9).abs() < 0.2,
        "{}",
        list[0].duration_s
    );
    // `dronewatt-lab convert` writes the tlog that flight_tlog builds.
    let out = dir.path().join("276.tlog");
    let status = crate::harness::lab()
        .args([
            "convert",
            p.to_str().unwrap(),
            "--flight",
            "276",
            "-o",
            out.to_str().unwrap(),
        ])
        .status()
        .unwrap();
    assert!(status.success());
    let bytes = std::fs::read(&out).unwrap();
    assert_eq!(bytes, flight_tlog(&p, 276).unwrap());
    // First record: 2019-10-24 9:32 read as UTC.
    let t0 = u64::from_be_bytes(bytes[..8].try_into().unwrap());
    assert_eq!(t0, 1_571_909_520_000_000);

    // pymavlink, the independent peer, reads every record: one burst per row.
    let py = crate::harness::root().join(".venv-py/bin/python");
    let script = "import sys,json,collections\nfrom pymavlink import mavutil\n\
m=mavutil.mavlink_connection(sys.argv[1],dialect='ardupilotmega')\nc=collections.Counter()\n\
while True:\n x=m.recv_match()\n if x is None: break\n c[x.get_type()]+=1\nprint(json.dumps(c))";
    let o = std::process::Command::new(&py)
        .args(["-c", script, out.to_str().unwrap()])
        .output()
        .unwrap_or_else(|e| panic!("{}: {e} (run scripts/setup-python.sh)", py.display()));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let counts: std::collections::BTreeMap<String, u64> =
        serde_json::from_slice(&o.stdout).unwrap();
    for t in [
        "ATTITUDE",
        "ATTITUDE_QUATERNION",
        "HIGHRES_IMU",
        "LOCAL_POSITION_NED",
        "GLOBAL_POSITION_INT",
        "WIND",
        "VFR_HUD",
        "SYS_STATUS",
        "BATTERY_STATUS",
    ] {
        assert_eq!(counts.get(t), Some(&984), "{t}: {counts:?}");
    }
    assert_eq!(counts.get("HOME_POSITION"), Some(&1));
    assert_eq!(counts.get("BAD_DATA"), None);
    assert!(counts["HEARTBEAT"] >= 140 && counts["NAMED_VALUE_FLOAT"] == 3 * counts["HEARTBEAT"]);
}
