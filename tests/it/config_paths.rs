//! Files a configuration names: every path resolves against the config file's folder,
//! whatever the working directory, and every secret is refused unless private to its owner.

use std::path::Path;

use dronewatt::config::Config;

/// A config in `<tmp>/etc/dronewatt.toml` naming every path key relatively.
fn write_config(dir: &Path) -> std::path::PathBuf {
    let etc = dir.join("etc");
    std::fs::create_dir_all(&etc).unwrap();
    let p = etc.join("dronewatt.toml");
    std::fs::write(
        &p,
        r#"
vehicle = "vehicles/m100.toml"

[models.lstm]
path = "models/lstm"

[forecast.live]
calibrated_profile = "vehicles/cal.toml"

[sinks.web]
token_file = "secrets/web-token"

[sinks.mqtt]
username = "u"
password_file = "secrets/mqtt-password"
tls = true
ca_file = "secrets/ca.pem"

[link]
signing_key_file = "secrets/link.key"
"#,
    )
    .unwrap();
    p
}

#[test]
fn every_path_a_config_names_is_relative_to_the_config_file() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = Config::load(&write_config(dir.path())).unwrap_or_else(|e| panic!("{e}"));
    let etc = dir.path().join("etc");
    let want = |rel: &str| Some(etc.join(rel));
    assert_eq!(cfg.vehicle, want("vehicles/m100.toml"));
    assert_eq!(cfg.models.lstm.path, want("models/lstm"));
    assert_eq!(
        cfg.forecast.live.calibrated_profile,
        want("vehicles/cal.toml")
    );
    assert_eq!(cfg.sinks.web.token_file, want("secrets/web-token"));
    assert_eq!(cfg.sinks.mqtt.password_file, want("secrets/mqtt-password"));
    assert_eq!(cfg.sinks.mqtt.ca_file, want("secrets/ca.pem"));
    assert_eq!(cfg.link.signing_key_file, want("secrets/link.key"));
}

#[test]
fn absolute_paths_stay_as_written() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("d.toml");
    std::fs::write(&p, "[models.lstm]\npath = \"/opt/models/lstm\"\n").unwrap();
    let cfg = Config::load(&p).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        cfg.models.lstm.path.as_deref(),
        Some(Path::new("/opt/models/lstm"))
    );
}

/// The MQTT sink refuses a password file others can read, before it connects anywhere, as
/// the signing key and the web token are refused.
#[cfg(unix)]
#[tokio::test]
async fn an_mqtt_password_file_others_can_read_is_refused() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let pw = dir.path().join("pw");
    std::fs::write(&pw, "s3cret\n").unwrap();
    std::fs::set_permissions(&pw, std::fs::Permissions::from_mode(0o640)).unwrap();
    let cfg = dronewatt::sink::mqtt::MqttSinkConfig {
        enabled: true,
        username: Some("u".into()),
        password_file: Some(pw.clone()),
        ..Default::default()
    };
    let mut fanout = dronewatt::sink::Fanout::default();
    let e = match dronewatt::sink::mqtt::spawn(cfg.clone(), fanout.subscribe()) {
        Ok(task) => {
            task.abort();
            panic!("a group-readable password file was accepted")
        }
        Err(e) => format!("{e:#}"),
    };
    assert!(
        e.contains("sinks.mqtt.password_file") && e.contains("640") && e.contains("chmod 600"),
        "{e}"
    );
    std::fs::set_permissions(&pw, std::fs::Permissions::from_mode(0o600)).unwrap();
    let task = dronewatt::sink::mqtt::spawn(cfg, fanout.subscribe()).expect("a private file");
    task.abort();
}

/// `[[links]]`: the links `monitor` reads with no address on its command line; a bad
/// address is an error naming the table, like every other key.
#[test]
fn links_tables_are_read_and_a_bad_address_names_its_table() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("links.toml");
    std::fs::write(
        &p,
        "[[links]]\naddress = \"udpin:0.0.0.0:14550\"\n[[links]]\naddress = \"serial:/dev/ttyUSB0:57600\"\n",
    )
    .unwrap();
    let cfg = Config::load(&p).unwrap_or_else(|e| panic!("{e}"));
    let a: Vec<&str> = cfg.links.iter().map(|l| l.address.as_str()).collect();
    assert_eq!(a, ["udpin:0.0.0.0:14550", "serial:/dev/ttyUSB0:57600"]);
    std::fs::write(&p, "[[links]]\naddress = \"quic:host:1\"\n").unwrap();
    let e = Config::load(&p).unwrap_err().to_string();
    assert!(
        e.contains("links[0].address") && e.contains("quic:host:1"),
        "{e}"
    );
    std::fs::write(&p, "[[links]]\nadress = \"udpin:0.0.0.0:1\"\n").unwrap();
    let e = Config::load(&p).unwrap_err().to_string();
    assert!(e.contains("adress"), "{e}");
}

#[test]
fn the_files_a_config_names_are_read_once_at_start_and_a_bad_one_is_named() {
    use dronewatt::pipeline::{Resolved, VehicleChain};
    let dir = tempfile::tempdir().unwrap();
    let m100 = concat!(env!("CARGO_MANIFEST_DIR"), "/config/vehicles/m100.toml");
    let (vehicle, cal) = (dir.path().join("v.toml"), dir.path().join("cal.toml"));
    std::fs::copy(m100, &vehicle).unwrap();
    std::fs::copy(m100, &cal).unwrap();
    let cfg_path = dir.path().join("dw.toml");
    std::fs::write(
        &cfg_path,
        "vehicle = \"v.toml\"\n[models.lstm]\nenabled = false\n[forecast.live]\ncalibrated_profile = \"cal.toml\"\n",
    )
    .unwrap();
    let cfg = Config::load(&cfg_path).unwrap_or_else(|e| panic!("{e}"));
    let resolved = Resolved::load(&cfg).unwrap_or_else(|e| panic!("{e:#}"));
    assert!(resolved.calibrated.is_some());
    // Read once: with the files gone, every chain (a fleet's later ones too) still builds.
    std::fs::remove_file(&vehicle).unwrap();
    std::fs::remove_file(&cal).unwrap();
    VehicleChain::build(&cfg, &resolved).unwrap_or_else(|e| panic!("{e:#}"));
    VehicleChain::another(&cfg, &resolved).unwrap_or_else(|e| panic!("{e:#}"));
    // A file that does not read, or does not parse, fails the start and is named.
    let e = format!("{:#}", Resolved::load(&cfg).unwrap_err());
    assert!(e.contains("v.toml"), "{e}");
    std::fs::write(&vehicle, "not = [a profile").unwrap();
    let e = format!("{:#}", Resolved::load(&cfg).unwrap_err());
    assert!(e.contains("v.toml"), "{e}");
    std::fs::copy(m100, &vehicle).unwrap();
    let e = format!("{:#}", Resolved::load(&cfg).unwrap_err());
    assert!(e.contains("cal.toml"), "{e}");
}
