//! Replays the fuzz corpus through the fuzz targets' own property checks
//! (`dronewatt::fuzz_props`), on plain stable `cargo test`: no nightly, no sanitizer.
//! Every committed seed (`fuzz/seeds/TARGET/`) and every input that once broke a property
//! or crashed (`fuzz/regressions/TARGET/`) must pass, so a fixed crash stays fixed.
//!
//! The seeds are made by this project's own encoder and by hand (nothing cut from the M100
//! data set); `cargo test --test it fuzz_props:: -- --ignored write_seeds` rewrites them.

use crate::harness::{dronewatt, RunExt};
use std::path::{Path, PathBuf};

use dronewatt::dialect::*;
use dronewatt::fuzz_props;
use dronewatt::MavMessage;
use mavlink::{MavHeader, MavlinkVersion};

type Check = fn(&[u8]) -> Result<(), String>;

const TARGETS: [(&str, Check); 9] = [
    ("decoder", fuzz_props::check_decoder),
    ("tlog", fuzz_props::check_tlog),
    ("raw", fuzz_props::check_raw),
    ("csv", fuzz_props::check_csv),
    ("config", fuzz_props::check_config),
    ("plan", fuzz_props::check_plan),
    ("dataflash", fuzz_props::check_dataflash),
    ("ulog", fuzz_props::check_ulog),
    ("trees", fuzz_props::check_trees),
];

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz")
}

fn files(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = match std::fs::read_dir(dir) {
        Ok(rd) => rd
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.is_file())
            .collect(),
        Err(_) => Vec::new(),
    };
    v.sort();
    v
}

#[test]
fn every_seed_and_regression_input_keeps_the_properties() {
    let mut failures = Vec::new();
    for (target, check) in TARGETS {
        let seeds = files(&fuzz_dir().join("seeds").join(target));
        // An empty or missing corpus would make this test pass hollow.
        assert!(
            seeds.len() >= 10,
            "fuzz/seeds/{target}: {} seeds, expected at least 10",
            seeds.len()
        );
        let regressions = files(&fuzz_dir().join("regressions").join(target));
        for path in seeds.iter().chain(&regressions) {
            let data = std::fs::read(path).expect("read corpus file");
            match std::panic::catch_unwind(|| check(&data)) {
                Ok(Ok(())) => {}
                Ok(Err(e)) => failures.push(format!("{}: {e}", path.display())),
                Err(_) => failures.push(format!("{}: panicked", path.display())),
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} corpus inputs break a property:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// The checks do catch what they promise to: a stream with a lost byte still accounts for
/// every byte, and a frame hidden in garbage is found (positive controls on hand-made input).
#[test]
fn the_checks_see_frames_in_garbage_and_count_every_byte() {
    let frame = fuzz_props::encode_frame(
        MavHeader {
            system_id: 1,
            component_id: 1,
            sequence: 9,
        },
        &heartbeat(),
        MavlinkVersion::V2,
        true,
    );
    let mut stream = vec![0x00, 7, 200]; // stream framing, chunk sizes
    stream.extend_from_slice(&[0xFD, 0x09, 0x33, 0xFE, 0x01]);
    stream.extend_from_slice(&frame);
    stream.extend_from_slice(&[0xFE, 0x10]);
    fuzz_props::check_decoder(&stream).unwrap();

    let stats = dronewatt::report::status::IngestStats::default();
    let mut d =
        dronewatt::source::frame::FrameDecoder::new(dronewatt::source::frame::Framing::Stream);
    d.push(&stream[3..]);
    d.finish();
    let mut n = 0;
    while d.next_frame(&stats).is_some() {
        n += 1;
    }
    let s = stats.snapshot();
    let t = d.byte_tally();
    assert_eq!(n, 1);
    assert_eq!(t.ok, frame.len() as u64);
    assert_eq!(
        t.ok + t.bad + t.unknown + s.junk_bytes,
        (stream.len() - 3) as u64,
        "{s:?} {t:?}"
    );
}

fn heartbeat() -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavlink_version: 3,
        ..Default::default()
    })
}

fn attitude(ms: u32) -> MavMessage {
    MavMessage::ATTITUDE(ATTITUDE_DATA {
        time_boot_ms: ms,
        roll: 0.05,
        pitch: -0.1,
        yaw: 1.0,
        ..Default::default()
    })
}

fn sys_status() -> MavMessage {
    MavMessage::SYS_STATUS(SYS_STATUS_DATA {
        voltage_battery: 22_800,
        current_battery: 1_250,
        ..Default::default()
    })
}

fn hdr(seq: u8) -> MavHeader {
    MavHeader {
        system_id: 1,
        component_id: 1,
        sequence: seq,
    }
}

fn frames(n: usize, version: MavlinkVersion, signed: bool, t0_ms: u32) -> Vec<u8> {
    let mut out = Vec::new();
    for i in 0..n {
        let msg = match i % 3 {
            0 => heartbeat(),
            1 => attitude(t0_ms + 100 * i as u32),
            _ => sys_status(),
        };
        out.extend(fuzz_props::encode_frame(
            hdr(i as u8),
            &msg,
            version,
            signed,
        ));
    }
    out
}

fn tlog(n: usize, t0_us: u64, version: MavlinkVersion) -> Vec<u8> {
    let mut out = Vec::new();
    for i in 0..n {
        let msg = if i % 2 == 0 {
            attitude(100 * i as u32)
        } else {
            sys_status()
        };
        dronewatt::source::logs::tlog::write_record(
            &mut out,
            t0_us + 100_000 * i as u64,
            hdr(i as u8),
            &msg,
            version,
        );
    }
    out
}

fn flip(mut b: Vec<u8>, every: usize) -> Vec<u8> {
    for i in (every / 2..b.len()).step_by(every) {
        b[i] ^= 0x5A;
    }
    b
}

const T0: u64 = 1_600_000_000_000_000;

fn decoder_seeds() -> Vec<Vec<u8>> {
    let with = |mode: u8, body: Vec<u8>| [vec![mode, 13, 77], body].concat();
    let v1 = frames(6, MavlinkVersion::V1, false, 0);
    let v2 = frames(6, MavlinkVersion::V2, false, 0);
    let signed = frames(6, MavlinkVersion::V2, true, 0);
    let unknown = [0xFD, 2, 0, 0, 5, 1, 1, 0x60, 0xEA, 0, 1, 2, 0x11, 0x22].to_vec(); // id 60000
    vec![
        with(0, v1.clone()),
        with(2, v2.clone()),
        with(4, signed.clone()),
        with(
            0,
            [
                b"garbage\xfe\x03".to_vec(),
                v2.clone(),
                b"\xfd\xfd\xfe".to_vec(),
            ]
            .concat(),
        ),
        with(6, [v1.clone(), v2.clone(), signed.clone()].concat()),
        with(0, flip(v2.clone(), 17)),
        with(8, [unknown.clone(), v2.clone(), unknown.clone()].concat()),
        with(0, v2[..v2.len() - 5].to_vec()),
        with(1, tlog(8, T0, MavlinkVersion::V2)),
        with(3, tlog(8, T0, MavlinkVersion::V1)),
        with(1, flip(tlog(12, T0, MavlinkVersion::V2), 23)),
        with(
            5,
            [
                tlog(3, T0, MavlinkVersion::V2),
                vec![0; 11],
                tlog(3, T0 + 400_000, MavlinkVersion::V2),
            ]
            .concat(),
        ),
        with(1, tlog(4, T0, MavlinkVersion::V2)[..50].to_vec()),
        with(10, (0u8..=255).collect()),
    ]
}

fn tlog_seeds() -> Vec<Vec<u8>> {
    let mut zero_stamp = tlog(6, T0, MavlinkVersion::V2);
    zero_stamp[0..8].copy_from_slice(&[0; 8]);
    let mut backwards = tlog(3, T0 + 10_000_000, MavlinkVersion::V2);
    backwards.extend(tlog(3, T0, MavlinkVersion::V2));
    vec![
        tlog(10, T0, MavlinkVersion::V2),
        tlog(10, T0, MavlinkVersion::V1),
        flip(tlog(20, T0, MavlinkVersion::V2), 31),
        flip(tlog(20, T0, MavlinkVersion::V2), 97),
        zero_stamp,
        backwards,
        [
            tlog(4, T0, MavlinkVersion::V2),
            tlog(4, T0 + 3_600_000_000, MavlinkVersion::V2),
        ]
        .concat(),
        tlog(5, T0, MavlinkVersion::V2)[..70].to_vec(),
        [vec![0xAA; 5], tlog(5, T0, MavlinkVersion::V2)].concat(),
        frames(6, MavlinkVersion::V2, false, 0),
        vec![0; 64],
        [
            tlog(2, T0, MavlinkVersion::V2),
            frames(2, MavlinkVersion::V2, true, 0),
            tlog(2, T0 + 300_000, MavlinkVersion::V2),
        ]
        .concat(),
    ]
}

fn raw_seeds() -> Vec<Vec<u8>> {
    vec![
        frames(12, MavlinkVersion::V2, false, 1000),
        frames(12, MavlinkVersion::V1, false, 1000),
        frames(12, MavlinkVersion::V2, true, 1000),
        [
            frames(6, MavlinkVersion::V2, false, 50_000),
            frames(6, MavlinkVersion::V2, false, 10),
        ]
        .concat(), // reboot
        [
            frames(6, MavlinkVersion::V2, false, u32::MAX - 500),
            frames(6, MavlinkVersion::V2, false, 0),
        ]
        .concat(), // wrap
        flip(frames(20, MavlinkVersion::V2, false, 0), 13),
        [
            b"\x00\x01noise".to_vec(),
            frames(5, MavlinkVersion::V1, false, 0),
        ]
        .concat(),
        frames(5, MavlinkVersion::V2, false, 0)[..40].to_vec(),
        tlog(6, T0, MavlinkVersion::V2),
        vec![0xFD; 40],
        vec![0xFE, 0x00, 0x00, 0x01, 0x01, 0x00, 0x00, 0x00],
    ]
}

/// A made-up row (not from the data set): hovering, a little wind.
fn csv_row(flight: u32, t: f64, v: f64) -> String {
    format!(
        "{flight},{t},0.5,90,{v},20.1,-79.78,40.44,290,0,0,0.7071,0.7071,0.1,0,0,0,0,0,0,0,-9.8,12,250,25,2019-04-07,10:15,R1"
    )
}

fn csv_seeds() -> Vec<Vec<u8>> {
    let h = dronewatt::source::logs::dataset::csv_header();
    let rows = |f: u32, n: usize| {
        (0..n)
            .map(|i| csv_row(f, 0.1 * i as f64, 24.0 - 0.01 * i as f64))
            .collect::<Vec<_>>()
            .join("\n")
    };
    let s = |text: String| text.into_bytes();
    vec![
        s(format!("{h}\n{}\n", rows(1, 5))),
        s(format!("{h}\r\n{}\r\n", rows(2, 3).replace('\n', "\r\n"))),
        s(format!("{h}\n{}\n{}\n", rows(3, 3), rows(4, 3))),
        s(format!("{h}\n{}\n1,0.5,NaN\n", rows(5, 2))),
        s(format!("{h}\n{}\n{}\n", rows(6, 3), csv_row(6, 0.05, 24.0))),
        s(format!(
            "{h}\n{}\n",
            csv_row(7, 0.0, 24.0).replace(",25,", ",20-25,")
        )),
        s(format!(
            "{h}\n{}\n",
            csv_row(8, 0.0, 24.0).replace("2019-04-07", "xx")
        )),
        s(format!("{h}\nx,0,1\n\n{}\n", rows(9, 2))),
        s(format!("{h}\n{}\n", csv_row(10, 0.0, 1e308))),
        s("flight,time\n1,0\n".to_string()),
        s(format!("{h}\n")),
        s(format!("{h}\n{}\n", csv_row(11, -1e9, 24.0))),
    ]
}

fn config_seeds() -> Vec<Vec<u8>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut v: Vec<Vec<u8>> = ["config/demo.toml", "config/dronewatt.toml"]
        .iter()
        .filter_map(|p| std::fs::read(root.join(p)).ok())
        .collect();
    for text in [
        "",
        "[telemetry]\nrate_hz = 10.0\nwindow = 20\n",
        "[telemetry]\nrate_hz = 0.0\nwindow = 0\n[energy]\ncapacity_wh = -1.0\n",
        "[energy]\ncapacity_wh = 97.7\nreserve_pct = 150\ncell_count = 6\n",
        "[[alerts]]\nname = \"low\"\nkind = \"remaining_below\"\nbelow_pct = 20.0\n",
        "[[alerts]]\nname = \"a\"\nkind = \"power_above\"\nabove_w = 500.0\nclear_w = 600.0\n[[alerts]]\nname = \"a\"\nkind = \"telemetry_lost\"\nfor_s = 0.0\n",
        "[sinks.web]\nenabled = true\nbind = \"nowhere\"\nhistory = 1\n",
        "[sinks.mavlink]\nsystem_id = 0\ncomponent_id = 1\nrate_hz = 1000.0\naddress = \"carrier-pigeon:1\"\n",
        "[mission]\nspeed_m_s = 10.0\npayload_g = 250.0\naltitude_m = 25.0\n",
        "unknown_key = 1\n",
        "[telemetry\nrate_hz = \n",
    ] {
        v.push(text.as_bytes().to_vec());
    }
    v
}

/// Plans written by hand per the formats (QGroundControl's `.plan` JSON, `QGC WPL 110`),
/// good and bad: each reader sees every seed.
fn plan_seeds() -> Vec<Vec<u8>> {
    let wpl = "QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t40.44\t-79.94\t290.0\t1\n1\t0\t3\t22\t0\t0\t0\t0\t0\t0\t25\t1\n\
2\t0\t3\t178\t1\t10\t-1\t0\t0\t0\t0\t1\n3\t0\t3\t16\t5\t0\t0\t0\t40.4405\t-79.9385\t25\t1\n4\t0\t3\t19\t10\t0\t0\t0\t40.4389\t-79.9396\t25\t1\n\
5\t0\t3\t206\t25\t0\t1\t0\t0\t0\t0\t1\n6\t0\t0\t16\t0\t0\t0\t0\t40.4401\t-79.9401\t320\t1\n7\t0\t10\t16\t0\t0\t0\t0\t40.4402\t-79.9402\t30\t1\n\
8\t0\t3\t21\t0\t0\t0\t0\t40.44\t-79.94\t0\t1\n9\t0\t3\t20\t0\t0\t0\t0\t0\t0\t0\t1\n";
    let item = |cmd: u32, p: [f64; 7]| {
        format!(
            r#"{{"type":"SimpleItem","command":{cmd},"frame":3,"params":[{},{},{},{},{},{},{}],"autoContinue":true,"doJumpId":1}}"#,
            p[0], p[1], p[2], p[3], p[4], p[5], p[6]
        )
    };
    let plan = |items: &str| {
        format!(
            r#"{{"fileType":"Plan","version":1,"groundStation":"QGroundControl","mission":{{"version":2,"firmwareType":3,"vehicleType":2,"cruiseSpeed":10,"hoverSpeed":5,"plannedHomePosition":[40.44,-79.94,290],"items":[{items}]}},"geoFence":{{}},"rallyPoints":{{}}}}"#
        )
    };
    let simple = [
        item(22, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 25.0]),
        item(16, [5.0, 0.0, 0.0, 0.0, 40.4405, -79.9385, 25.0]),
        item(178, [1.0, 8.0, -1.0, 0.0, 0.0, 0.0, 0.0]),
        item(19, [10.0, 0.0, 0.0, 0.0, 40.4389, -79.9396, 25.0]),
        item(20, [0.0; 7]),
    ]
    .join(",");
    let survey = r#"{"type":"ComplexItem","complexItemType":"survey","TransectStyleComplexItem":{"Items":[{"type":"SimpleItem","command":16,"frame":3,"params":[0,0,0,0,40.441,-79.941,30],"autoContinue":true},{"type":"SimpleItem","command":16,"frame":3,"params":[0,0,0,0,40.442,-79.941,30],"autoContinue":true}]}}"#;
    let mut v: Vec<Vec<u8>> = vec![
        wpl.into(),
        plan(&simple).into_bytes(),
        plan(&format!(
            "{},{survey}",
            item(22, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 25.0])
        ))
        .into_bytes(),
        plan("").into_bytes(),
        plan(&item(31337, [0.0; 7])).into_bytes(),
        plan(&item(16, [0.0, 0.0, 0.0, 0.0, 95.0, 0.0, 10.0])).into_bytes(),
        wpl.replace("40.4405", "140.4405").into_bytes(),
        wpl.replace("\t206\t", "\t9999\t").into_bytes(),
        b"QGC WPL 110\n".to_vec(),
        b"QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\tnan\t0\t0\t1\n".to_vec(),
        b"{\"fileType\":\"Plan\",\"mission\":".to_vec(),
    ];
    v.push(
        plan(&simple)
            .replace(
                "\"plannedHomePosition\":[40.44,-79.94,290]",
                "\"plannedHomePosition\":[40.44,-79.94]",
            )
            .into_bytes(),
    );
    v
}

/// LightGBM text models written by hand to its layout (`src/model/trees/`), good and bad, and
/// the head of the shipped model's (our own trees, nothing of the data set): every missing
/// type and default direction, a one-leaf tree, refused objectives, categorical and linear
/// trees, children out of place.
fn trees_seeds() -> Vec<Vec<u8>> {
    let model = |objective: &str, decisions: &str, left: &str, extra: &str| {
        format!(
            "tree\nversion=v4\nnum_class=1\nnum_tree_per_iteration=1\nlabel_index=0\nmax_feature_idx=2\n\
objective={objective}\nfeature_names=a b c\nfeature_infos=[0:3] [0:1] [-1:1]\ntree_sizes=1 1 1\n\n\
Tree=0\nnum_leaves=3\nnum_cat=0\nsplit_feature=0 1\nsplit_gain=1 1\nthreshold=1 0.5\n\
decision_type={decisions}\nleft_child={left}\nright_child=-1 -3\nleaf_value=10 20 30\n{extra}shrinkage=1\n\n\n\
Tree=1\nnum_leaves=1\nnum_cat=0\nshrinkage=1\nleaf_value=0.5\n\n\nend of trees\n\nparameters:\nend of parameters\n"
        )
        .into_bytes()
    };
    let mut v = vec![
        model("regression", "2 10", "1 -2", ""),
        model("regression", "0 4", "1 -2", ""),
        model("regression", "2 2", "1 -2", "is_linear=0\n"),
        model("huber", "6 8", "1 -2", ""),
        model("poisson", "2 2", "1 -2", ""),
        model("regression", "3 2", "1 -2", ""),
        model("regression", "2 2", "0 -2", ""),
        model("regression", "2 2", "1 -9", ""),
        model("regression", "2 2", "1 -2", "is_linear=1\n"),
    ];
    let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/models/lstm-m100/trees.txt");
    if let Ok(text) = std::fs::read(shipped) {
        // The fuzzer's inputs are at most 4 kB: the header and the first tree's start.
        v.push(text[..text.len().min(4000)].to_vec());
    }
    v
}

/// Rewrite `fuzz/seeds/` from the generators above (run by hand when they change).
#[test]
#[ignore]
fn write_seeds() {
    let sets: [(&str, Vec<Vec<u8>>); 9] = [
        ("decoder", decoder_seeds()),
        ("tlog", tlog_seeds()),
        ("raw", raw_seeds()),
        ("csv", csv_seeds()),
        ("config", config_seeds()),
        ("plan", plan_seeds()),
        ("dataflash", autopilot_log_seeds("bin", "ardupilot")),
        ("ulog", autopilot_log_seeds("ulg", "px4")),
        ("trees", trees_seeds()),
    ];
    for (target, seeds) in sets {
        let dir = fuzz_dir().join("seeds").join(target);
        std::fs::create_dir_all(&dir).unwrap();
        for (i, s) in seeds.iter().enumerate() {
            std::fs::write(dir.join(format!("seed-{i:02}")), s).unwrap();
        }
    }
}

/// An autopilot's own log as the simulator writes it (`simulate --out F.bin`, ArduPilot
/// DataFlash; `F.ulg`, PX4 ULog), a short flight: its head cut at several lengths (the
/// fuzzer's inputs are at most 4 kB), each also with a byte flipped in its records, and the
/// whole header alone.
fn autopilot_log_seeds(ext: &str, autopilot: &str) -> Vec<Vec<u8>> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(format!("seed.{ext}"));
    let _out = dronewatt()
        .args([
            "simulate",
            "--autopilot",
            autopilot,
            "--leg-m",
            "50",
            "--hover-s",
            "2",
            "--seed",
            "3",
            "--out",
        ])
        .arg(&path)
        .ok();
    let log = std::fs::read(&path).unwrap();
    let mut seeds = Vec::new();
    for len in [16, 200, 600, 1200, 2000, 3000, 4096] {
        let head = log[..len.min(log.len())].to_vec();
        let mut flipped = head.clone();
        let at = flipped.len() * 2 / 3;
        flipped[at] ^= 0x5a;
        seeds.push(head);
        seeds.push(flipped);
    }
    seeds
}

/// The plan seeds reach past the readers' first error: the good ones read, in each format.
#[test]
fn the_good_plan_seeds_read() {
    use dronewatt::mission::plan::{parse_qgc_plan, parse_waypoints};
    let seeds = plan_seeds();
    let text = |i: usize| String::from_utf8(seeds[i].clone()).expect("utf-8 seed");
    let wpl = parse_waypoints(&text(0), "seed-00").expect("the .waypoints seed reads");
    assert_eq!(wpl.items.len(), 9, "home is line 0; nine items follow");
    assert_eq!(
        wpl.not_modelled().len(),
        1,
        "the camera trigger (206) is listed"
    );
    let plan = parse_qgc_plan(&text(1), "seed-01").expect("the .plan seed reads");
    assert_eq!(plan.items.len(), 5);
    assert_eq!(plan.cruise_speed_m_s, Some(10.0));
    let survey = parse_qgc_plan(&text(2), "seed-02").expect("the survey seed reads");
    assert_eq!(
        survey.items.len(),
        3,
        "takeoff and the survey's two waypoints"
    );
}
