//! `dronewatt check-config`: what a configuration file sets up, in words.

use crate::config::Config;

/// What `check-config` prints: what the file sets up, in words.
pub(crate) fn describe_config(file: Option<&std::path::Path>, cfg: &Config) -> String {
    let e = &cfg.energy;
    let mut out = match file {
        Some(f) => format!("{}: ok\n", f.display()),
        None => "no config file: the defaults\n".to_string(),
    };
    out += &format!(
        "energy: capacity {}, cells {}, reserve {}%, forecast model {}, smoothing {} s\n",
        e.capacity_wh.map_or(
            "from the vehicle, --pack or the store (else not known)".to_string(),
            |c| format!("{c:.2} Wh")
        ),
        e.cell_count.map_or(
            "from the vehicle (else from its voltage)".to_string(),
            |n| n.to_string()
        ),
        e.reserve_pct,
        e.model.as_deref().unwrap_or("lstm, else measured power"),
        e.smoothing_s
    );
    let defaults = cfg.default_alerts();
    out += &format!(
        "alerts: {} rule(s){}\n",
        cfg.alerts.len(),
        if defaults {
            " (the pilot's defaults: [[alerts]] in a config replace them all)"
        } else {
            ""
        }
    );
    for r in &cfg.alerts {
        out += &format!("  {}\n", r.describe());
    }
    let m = &cfg.sinks.mavlink;
    let mav_on = match m.enabled {
        Some(true) => "on",
        Some(false) => "off",
        None if m.address.is_some() => "on",
        None => "on when monitoring a link",
    };
    out += &format!(
        "sinks.mavlink: {mav_on}, to {}, as system {} component {}, estimates at {} Hz\n",
        m.address.as_deref().unwrap_or("the monitored link"),
        m.system_id
            .map_or("of each vehicle".to_string(), |id| id.to_string()),
        m.component_id,
        m.rate_hz
    );
    let w = &cfg.sinks.web;
    let guarded =
        if w.token_file.is_some() || std::env::var_os(crate::sink::web::TOKEN_ENV).is_some() {
            ", token required"
        } else {
            ""
        };
    out += &format!(
        "sinks.web: {}\n",
        if w.enabled {
            format!("on, http://{}/{guarded}", w.bind)
        } else {
            "off".into()
        }
    );
    let l = &cfg.link;
    out += &match &l.signing_key_file {
        Some(k) => format!(
            "link: MAVLink 2 signing with the key in {}, link id {}, unsigned frames {}\n",
            k.display(),
            l.signing_link_id,
            if l.require_signing {
                "refused"
            } else {
                "accepted"
            }
        ),
        None => "link: no signing\n".into(),
    };
    let f = &cfg.fleet;
    out += &format!(
        "fleet: vehicles {}, lost after {} s, dropped after {} s, batches wait up to {} ms, LSTM {}\n",
        f.vehicles.as_deref().unwrap_or("all"),
        f.lost_after_s,
        f.drop_after_s,
        f.batch_wait_ms,
        f.lstm_rate_hz.map_or("on every window".to_string(), |r| format!("at {r} Hz per vehicle"))
    );
    let q = &cfg.sinks.mqtt;
    out += &format!(
        "sinks.mqtt: {}\n",
        if q.enabled {
            format!(
                "on, {}://{}:{}/ under {}/ as instance {}{}",
                if q.tls { "mqtts" } else { "mqtt" },
                q.host,
                q.port(),
                q.prefix,
                q.instance(),
                q.username
                    .as_ref()
                    .map(|u| format!(", user {u}"))
                    .unwrap_or_default()
            )
        } else {
            "off".into()
        }
    );
    out
}
