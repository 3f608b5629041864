//! The one address grammar for MAVLink links, the one MAVProxy and rust-mavlink users
//! already know: `udpin:HOST:PORT`, `udpout:HOST:PORT`, `tcpin:HOST:PORT`,
//! `tcpout:HOST:PORT`, `serial:DEVICE:BAUD` (`udp:` and `tcp:` are accepted for `udpin:`
//! and `tcpout:`). The monitored link (`monitor ADDRESS`), the MAVLink sink's own
//! `address` and the simulator's output all parse it here, and `source::links::link` runs every
//! transport. Imports nothing of ours.

use anyhow::Result;

const ACCEPTED: &str =
    "udpin:HOST:PORT, udpout:HOST:PORT, tcpin:HOST:PORT, tcpout:HOST:PORT or serial:DEVICE:BAUD";

/// A parsed link address.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LinkAddress {
    /// Bind `HOST:PORT` and listen for datagrams; answer the last sender.
    UdpIn(String),
    /// Send to `HOST:PORT` (a heartbeat once a second so routers learn us) and read replies.
    UdpOut(String),
    /// Listen on `HOST:PORT` and accept any number of clients.
    TcpIn(String),
    /// Connect to `HOST:PORT`; reconnect with back-off.
    TcpOut(String),
    /// A serial device at a baud rate.
    Serial { device: String, baud: u32 },
}

impl std::str::FromStr for LinkAddress {
    type Err = anyhow::Error;
    /// Errors name the address and list the accepted forms.
    fn from_str(s: &str) -> Result<Self> {
        let fail = |why: &str| {
            anyhow::anyhow!(
                "link address '{}': {why}; expected {ACCEPTED}",
                s.escape_debug()
            )
        };
        let Some((kind, rest)) = s.split_once(':') else {
            return Err(fail("no transport"));
        };
        let Some((host, port)) = rest.rsplit_once(':') else {
            return Err(fail("no port (or baud rate) after the host (or device)"));
        };
        if host.is_empty() {
            return Err(fail("empty host (or device)"));
        }
        if kind == "serial" {
            return match port.parse::<u32>() {
                Ok(baud) if baud > 0 => Ok(Self::Serial {
                    device: host.to_string(),
                    baud,
                }),
                _ => Err(fail(&format!(
                    "baud rate '{port}' is not a positive number"
                ))),
            };
        }
        if port.parse::<u16>().is_err() {
            return Err(fail(&format!("port '{port}' is not a number 0–65535")));
        }
        let hp = rest.to_string();
        match kind {
            "udpin" | "udp" => Ok(Self::UdpIn(hp)),
            "udpout" => Ok(Self::UdpOut(hp)),
            "tcpin" => Ok(Self::TcpIn(hp)),
            "tcpout" | "tcp" => Ok(Self::TcpOut(hp)),
            _ => Err(fail(&format!("unknown transport '{kind}'"))),
        }
    }
}

impl std::fmt::Display for LinkAddress {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::UdpIn(a) => write!(f, "udpin:{a}"),
            Self::UdpOut(a) => write!(f, "udpout:{a}"),
            Self::TcpIn(a) => write!(f, "tcpin:{a}"),
            Self::TcpOut(a) => write!(f, "tcpout:{a}"),
            Self::Serial { device, baud } => write!(f, "serial:{device}:{baud}"),
        }
    }
}
