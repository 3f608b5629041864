//! What is known of the pack and where each figure came from: [`BatteryFacts`], each value
//! [`Sourced`] with its [`Provenance`], and the M100's pack, named as only the M100's.

use std::fmt;

use serde::{Serialize, Serializer};

/// How far (points) the autopilot's battery % may differ from the resting voltage's state
/// of charge before it is called a disagreement.
pub const BATTERY_PCT_AGREE: f64 = 10.0;

/// Where a battery figure came from: said beside it in the terminal, the JSON lines and the
/// dashboard.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub enum Provenance {
    /// The configuration file set it.
    Config,
    /// The vehicle's own parameter of this name (read over MAVLink or from a log).
    Parameter(String),
    /// The first battery voltage seen (the cell counts whose resting window holds it).
    FirstVoltage,
    /// What the pack delivered on this many earlier flights of the vehicle (the vehicle
    /// store's effective capacity).
    Learned { flights: usize },
    /// Assumed where nothing says (the cell count when no voltage fits, LiPo for the
    /// chemistry): said, and the estimate's band widened.
    #[default]
    Default,
    /// A pack named for the run (`--pack`, the M100 data set's TB48D, a vehicle profile's
    /// `[battery]`): what it was.
    Named(String),
}

impl fmt::Display for Provenance {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Provenance::Config => f.write_str("config"),
            Provenance::Parameter(name) => write!(f, "vehicle parameter {name}"),
            Provenance::FirstVoltage => f.write_str("first battery voltage"),
            Provenance::Learned { flights } => write!(f, "learned over {flights} flight(s)"),
            Provenance::Default => f.write_str("assumed (not known)"),
            Provenance::Named(name) => f.write_str(name),
        }
    }
}

impl Serialize for Provenance {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// Read back as [`Provenance`]'s `Display` writes it (a fleet worker's checkpoint); a text
/// of no other form is a pack's name.
impl<'de> serde::Deserialize<'de> for Provenance {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        let learned = s
            .strip_prefix("learned over ")
            .and_then(|r| r.strip_suffix(" flight(s)"))
            .and_then(|n| n.parse().ok());
        Ok(match s.as_str() {
            "config" => Provenance::Config,
            "first battery voltage" => Provenance::FirstVoltage,
            "assumed (not known)" => Provenance::Default,
            _ if learned.is_some() => Provenance::Learned {
                flights: learned.unwrap_or(0),
            },
            _ => match s.strip_prefix("vehicle parameter ") {
                Some(name) => Provenance::Parameter(name.to_string()),
                None => Provenance::Named(s),
            },
        })
    }
}

impl PartialEq<&str> for Provenance {
    #[allow(clippy::cmp_owned)] // the text is made by Display, as the JSON and the terminal say it
    fn eq(&self, other: &&str) -> bool {
        self.to_string() == *other
    }
}

/// A value and where it came from.
#[derive(Debug, Clone, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct Sourced<T> {
    pub value: T,
    pub source: Provenance,
}

impl<T> Sourced<T> {
    pub fn new(value: T, source: Provenance) -> Self {
        Self { value, source }
    }
}

/// The DJI TB48D (the M100's pack): 5700 mAh × 22.8 V, Wh. Only ever the M100's: the data
/// set's flights and the M100's vehicle profile ([`BatteryFacts::m100`]), never a default.
pub const M100_CAPACITY_WH: f64 = 5.7 * 22.8;
/// The TB48D's cells in series.
pub const M100_CELL_COUNT: u32 = 6;
/// The cell count assumed when nothing says and no voltage fits (said: `assumed`).
pub const DEFAULT_CELL_COUNT: u32 = 6;
/// Why the capacity is not known, as `capacity_source` says it beside a null capacity.
pub const CAPACITY_UNKNOWN: &str = "not known: no BATT_CAPACITY / BAT1_CAPACITY, BATTERY_INFO, vehicle store, [energy] capacity_wh or --pack";

/// The battery figures the energy stage works with, each with its provenance
/// (resolved by `vehicle::resolve_battery`: config, vehicle parameter, default).
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
pub struct BatteryFacts {
    /// Usable energy when full, Wh; None: not known ([`CAPACITY_UNKNOWN`]), and nothing
    /// that needs it (remaining Wh, time to empty) is made up.
    pub capacity_wh: Option<Sourced<f64>>,
    /// Cells in series.
    pub cell_count: Sourced<u32>,
    /// Cell chemistry: `lipo`, `lihv` or `liion` (`crate::battery::Chemistry`).
    pub chemistry: Sourced<String>,
    /// The autopilot's low-battery voltage (whole pack), V, when it has one.
    pub low_voltage_v: Option<Sourced<f64>>,
    /// The autopilot's critical-battery voltage (whole pack), V, when it has one.
    pub critical_voltage_v: Option<Sourced<f64>>,
    /// When `capacity_wh` is learned from earlier flights: the rated capacity it replaced
    /// (vehicle parameter or default).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rated_capacity_wh: Option<Sourced<f64>>,
}

impl Default for BatteryFacts {
    /// Nothing known: no capacity, the cell count and chemistry (LiPo) assumed, said so.
    fn default() -> Self {
        Self {
            capacity_wh: None,
            cell_count: Sourced::new(DEFAULT_CELL_COUNT, Provenance::Default),
            chemistry: Sourced::new("lipo".into(), Provenance::Default),
            low_voltage_v: None,
            critical_voltage_v: None,
            rated_capacity_wh: None,
        }
    }
}

impl BatteryFacts {
    /// The M100's TB48D (6S LiHV, 129.96 Wh), named: the data set's pack, nobody else's.
    pub fn m100() -> Self {
        let m100 = || Provenance::Named(M100_PACK.into());
        Self {
            capacity_wh: Some(Sourced::new(M100_CAPACITY_WH, m100())),
            cell_count: Sourced::new(M100_CELL_COUNT, m100()),
            chemistry: Sourced::new("lihv".into(), m100()),
            ..Self::default()
        }
    }

    /// The capacity, Wh, when known.
    pub fn capacity(&self) -> Option<f64> {
        self.capacity_wh.as_ref().map(|c| c.value)
    }

    /// Where the capacity came from, or why it is not known.
    pub fn capacity_source(&self) -> String {
        self.capacity_wh
            .as_ref()
            .map_or_else(|| CAPACITY_UNKNOWN.to_string(), |c| c.source.to_string())
    }
}

/// How the M100's pack is named where it is the pack ([`BatteryFacts::m100`]).
pub const M100_PACK: &str = "the M100's pack (DJI TB48D)";

/// Serde for facts shared behind an `Arc` (the energy tracker's, each estimate's state):
/// written and read as the facts themselves (serde's `rc` feature is not on).
pub(crate) mod shared {
    use super::BatteryFacts;
    use std::sync::Arc;

    pub(crate) fn serialize<S: serde::Serializer>(
        b: &Arc<BatteryFacts>,
        s: S,
    ) -> Result<S::Ok, S::Error> {
        serde::Serialize::serialize(b.as_ref(), s)
    }

    pub(crate) fn deserialize<'de, D: serde::Deserializer<'de>>(
        d: D,
    ) -> Result<Arc<BatteryFacts>, D::Error> {
        <BatteryFacts as serde::Deserialize>::deserialize(d).map(Arc::new)
    }
}
