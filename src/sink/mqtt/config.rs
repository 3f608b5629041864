//! The `[sinks.mqtt]` table: the broker, its credentials and TLS, the topics, and the checks
//! that name each key.

use super::*;

/// The `[sinks.mqtt]` table.
#[derive(Debug, Clone, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct MqttSinkConfig {
    /// On or off. Default off.
    pub enabled: bool,
    /// Broker host name or IP address. Default `127.0.0.1`.
    pub host: String,
    /// Broker port. Default 1883, or 8883 with `tls`.
    pub port: Option<u16>,
    /// Topic prefix, one or more levels (`fleet/dronewatt`), no wildcards. Default `dronewatt`.
    pub prefix: String,
    /// This instance's name: `<prefix>/status/<instance>`, and the MQTT client id
    /// `dronewatt-<instance>` (unique per broker). Default: the host name.
    pub instance: Option<String>,
    /// User name. Default none (anonymous).
    pub username: Option<String>,
    /// Name of the environment variable holding the password.
    pub password_env: Option<String>,
    /// File whose first line is the password; refused unless private to its owner (mode
    /// 0600). Relative to the config file.
    pub password_file: Option<PathBuf>,
    /// Connect with TLS (rustls). Default false.
    pub tls: bool,
    /// CA certificates to trust for TLS, PEM, relative to the config file. Default the system bundle
    /// (`/etc/ssl/certs/ca-certificates.crt`).
    pub ca_file: Option<PathBuf>,
    /// MQTT keep-alive, s: how soon the broker notices a dead connection (and publishes
    /// the Last Will) when no TCP close reaches it. Default 15.
    pub keep_alive_s: u64,
    /// Messages the queue to the broker holds (about 0.5 KiB each). Default 10000.
    pub queue: usize,
    /// Least flight time between two retained `state` messages, s. Default 1.
    pub state_interval_s: f64,
    /// Longest wait between reconnection attempts, s. Default 30.
    pub reconnect_max_s: f64,
}

impl Default for MqttSinkConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            host: "127.0.0.1".into(),
            port: None,
            prefix: "dronewatt".into(),
            instance: None,
            username: None,
            password_env: None,
            password_file: None,
            tls: false,
            ca_file: None,
            keep_alive_s: 15,
            queue: 10_000,
            state_interval_s: 1.0,
            reconnect_max_s: 30.0,
        }
    }
}

/// Whether `s` may stand in a topic: no wildcards, no NUL.
fn topic_safe(s: &str) -> bool {
    !s.contains(['+', '#', '\0'])
}

impl MqttSinkConfig {
    /// Range and shape checks; the message names the key.
    pub fn validate(&self) -> Result<(), String> {
        use crate::validate::in_range;
        if self.host.trim().is_empty() {
            return Err("sinks.mqtt.host: must not be empty".into());
        }
        if let Some(port) = self.port {
            in_range("sinks.mqtt.port", port, 1..=65_535, "")?;
        }
        let p = &self.prefix;
        if p.is_empty()
            || p.starts_with('/')
            || p.ends_with('/')
            || p.contains("//")
            || !topic_safe(p)
        {
            return Err(format!("sinks.mqtt.prefix = '{p}': must be topic levels like 'dronewatt' or 'fleet/dronewatt' (no leading, trailing or double '/', no '+' or '#')"));
        }
        if let Some(i) = &self.instance {
            if i.is_empty() || i.contains('/') || !topic_safe(i) {
                return Err(format!("sinks.mqtt.instance = '{i}': must be one non-empty topic level (no '/', '+' or '#')"));
            }
        }
        if self.password_env.is_some() && self.password_file.is_some() {
            return Err("sinks.mqtt: set password_env or password_file, not both".into());
        }
        if self.username.is_none() && (self.password_env.is_some() || self.password_file.is_some())
        {
            return Err("sinks.mqtt.username: required when a password is given (password_env or password_file)".into());
        }
        if self.ca_file.is_some() && !self.tls {
            return Err(
                "sinks.mqtt.ca_file: set, but tls = false (set tls = true to use it)".into(),
            );
        }
        in_range(
            "sinks.mqtt.keep_alive_s",
            self.keep_alive_s,
            1..=65_535,
            "s",
        )?;
        in_range("sinks.mqtt.queue", self.queue, 10..=10_000_000, "messages")?;
        in_range(
            "sinks.mqtt.state_interval_s",
            self.state_interval_s,
            0.0..,
            "s",
        )?;
        in_range(
            "sinks.mqtt.reconnect_max_s",
            self.reconnect_max_s,
            RECONNECT_MIN.as_secs_f64()..,
            "s",
        )
    }

    /// The port to connect to.
    pub fn port(&self) -> u16 {
        self.port.unwrap_or(if self.tls { 8883 } else { 1883 })
    }

    /// The instance name: configured, else the host name, else `dronewatt`.
    pub fn instance(&self) -> String {
        if let Some(i) = &self.instance {
            return i.clone();
        }
        let host = std::fs::read_to_string("/proc/sys/kernel/hostname")
            .ok()
            .or_else(|| std::env::var("HOSTNAME").ok())
            .unwrap_or_default();
        let host: String = host
            .trim()
            .chars()
            .filter(|c| !matches!(c, '/' | '+' | '#' | '\0'))
            .collect();
        if host.is_empty() {
            "dronewatt".into()
        } else {
            host
        }
    }

    /// The password, from the environment or the file; `None` when neither is set.
    pub(super) fn password(&self) -> Result<Option<String>> {
        if let Some(var) = &self.password_env {
            let v = std::env::var(var).with_context(|| {
                format!(
                    "sinks.mqtt.password_env: environment variable {var} is not set (or not UTF-8)"
                )
            })?;
            return Ok(Some(v));
        }
        if let Some(file) = &self.password_file {
            let text = crate::files::read_private_text(file)
                .map_err(|e| anyhow::anyhow!("sinks.mqtt.password_file: {e}"))?;
            return Ok(Some(text.lines().next().unwrap_or("").to_string()));
        }
        Ok(None)
    }

    /// The rustls transport: the CA file's certificates as the only roots.
    pub(super) fn tls_transport(&self) -> Result<Transport> {
        use rustls::pki_types::pem::PemObject;
        use rustls::pki_types::CertificateDer;
        let ca = self
            .ca_file
            .clone()
            .unwrap_or_else(|| SYSTEM_CA_FILE.into());
        let what = || format!("sinks.mqtt.ca_file: {}", ca.display());
        let mut roots = rustls::RootCertStore::empty();
        for cert in CertificateDer::pem_file_iter(&ca)
            .with_context(|| format!("{}: cannot read", what()))?
        {
            let cert = cert.with_context(|| format!("{}: not a PEM certificate file", what()))?;
            roots
                .add(cert)
                .with_context(|| format!("{}: a certificate rustls cannot use", what()))?;
        }
        anyhow::ensure!(!roots.is_empty(), "{}: no certificates in it", what());
        let provider = Arc::new(rustls::crypto::ring::default_provider());
        let config = rustls::ClientConfig::builder_with_provider(provider)
            .with_safe_default_protocol_versions()
            .context("sinks.mqtt: TLS set-up")?
            .with_root_certificates(roots)
            .with_no_client_auth();
        Ok(Transport::tls_with_config(
            rumqttc::TlsConfiguration::Rustls(Arc::new(config)),
        ))
    }

    /// The client's options: id, credentials, keep-alive, Last Will, transport.
    pub(super) fn options(&self, instance: &str) -> Result<MqttOptions> {
        let mut o = MqttOptions::new(
            format!("dronewatt-{instance}"),
            self.host.clone(),
            self.port(),
        );
        o.set_keep_alive(Duration::from_secs(self.keep_alive_s));
        o.set_clean_session(true);
        // A report's estimate line is ~0.5 KiB; leave room for many models.
        o.set_max_packet_size(256 * 1024, 256 * 1024);
        o.set_last_will(LastWill::new(
            status_topic(&self.prefix, instance),
            "offline",
            QoS::AtLeastOnce,
            true,
        ));
        if let Some(user) = &self.username {
            o.set_credentials(user.clone(), self.password()?.unwrap_or_default());
        }
        if self.tls {
            o.set_transport(self.tls_transport()?);
        }
        Ok(o)
    }
}
