use super::*;

#[test]
fn validate_names_the_key() {
    let ok = MqttSinkConfig {
        enabled: true,
        ..Default::default()
    };
    assert_eq!(ok.validate(), Ok(()));
    let bad = |f: fn(&mut MqttSinkConfig), key: &str| {
        let mut c = ok.clone();
        f(&mut c);
        let e = c.validate().unwrap_err();
        assert!(e.contains(key), "{e} should name {key}");
    };
    bad(|c| c.prefix = "a/#".into(), "sinks.mqtt.prefix");
    bad(|c| c.prefix = "/a".into(), "sinks.mqtt.prefix");
    bad(|c| c.instance = Some("x/y".into()), "sinks.mqtt.instance");
    bad(|c| c.password_env = Some("P".into()), "sinks.mqtt.username");
    bad(
        |c| {
            c.username = Some("u".into());
            c.password_env = Some("P".into());
            c.password_file = Some("p".into());
        },
        "password_env or password_file",
    );
    bad(|c| c.ca_file = Some("ca.pem".into()), "sinks.mqtt.ca_file");
    bad(|c| c.queue = 0, "sinks.mqtt.queue");
    bad(|c| c.keep_alive_s = 0, "sinks.mqtt.keep_alive_s");
    bad(
        |c| c.state_interval_s = f64::NAN,
        "sinks.mqtt.state_interval_s",
    );
    bad(|c| c.reconnect_max_s = 0.1, "sinks.mqtt.reconnect_max_s");
}

#[test]
fn unknown_keys_are_errors() {
    let e = toml::from_str::<MqttSinkConfig>("prefx = \"a\"")
        .unwrap_err()
        .to_string();
    assert!(e.contains("prefx"), "{e}");
}

#[test]
fn credentials_come_from_the_environment_or_a_file_and_a_missing_one_names_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("pw");
    std::fs::write(&file, "s3cret\nignored\n").unwrap();
    let c = MqttSinkConfig {
        username: Some("u".into()),
        password_file: Some(file.clone()),
        ..Default::default()
    };
    #[cfg(unix)] // private, or refused (tests/it/config_paths.rs)
    std::fs::set_permissions(&file, std::os::unix::fs::PermissionsExt::from_mode(0o600)).unwrap();
    assert_eq!(c.password().unwrap().as_deref(), Some("s3cret"));
    let c = MqttSinkConfig {
        username: Some("u".into()),
        password_file: Some(dir.path().join("none")),
        ..Default::default()
    };
    assert!(format!("{:#}", c.password().unwrap_err()).contains("sinks.mqtt.password_file"));
    let c = MqttSinkConfig {
        username: Some("u".into()),
        password_env: Some("DRONEWATT_TEST_SURELY_UNSET_PW".into()),
        ..Default::default()
    };
    assert!(format!("{:#}", c.password().unwrap_err()).contains("DRONEWATT_TEST_SURELY_UNSET_PW"));
}

#[test]
fn a_ca_file_that_is_not_pem_is_an_error_naming_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let ca = dir.path().join("ca.pem");
    std::fs::write(&ca, "not a certificate").unwrap();
    let c = MqttSinkConfig {
        tls: true,
        ca_file: Some(ca),
        ..Default::default()
    };
    let e = format!("{:#}", c.tls_transport().err().expect("no certificates"));
    assert!(e.contains("sinks.mqtt.ca_file"), "{e}");
    assert_eq!(c.port(), 8883);
}

#[test]
fn topics() {
    assert_eq!(
        vehicle_topic("fleet/dw", 42.into(), "estimate"),
        "fleet/dw/42/estimate"
    );
    let on_two = crate::report::VehicleId {
        network: 2,
        system_id: 42,
    };
    assert_eq!(
        vehicle_topic("fleet/dw", on_two, "state"),
        "fleet/dw/2:42/state"
    );
    assert_eq!(status_topic("dronewatt", "gcs-1"), "dronewatt/status/gcs-1");
    assert_eq!(
        link_topic("dronewatt", "serial:/dev/ttyUSB0:57600"),
        "dronewatt/links/serial:_dev_ttyUSB0:57600/health"
    );
    assert_eq!(
        link_topic("dw", "udpin:0.0.0.0:14550"),
        "dw/links/udpin:0.0.0.0:14550/health"
    );
}
