//! The `[energy]` table: the battery and home-return assumptions, their checks (each naming
//! its key), and what of them may be left to the vehicle.

use super::select;
use crate::vehicle::BatteryConfig;

/// Battery and home-return assumptions (the `[energy]` table).
#[derive(Debug, Clone, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct EnergyConfig {
    /// Usable battery energy when full, Wh. Absent: what the vehicle store learned, else the
    /// vehicle's capacity parameter (`BATT_CAPACITY` / `BAT1_CAPACITY`, mAh × cells ×
    /// `nominal_cell_v`), else not known (remaining energy and time to empty are null).
    pub capacity_wh: Option<f64>,
    /// Cells in series, for per-cell voltage alerts and the capacity in Wh. Absent: from
    /// the vehicle (`BAT1_N_CELLS`, the cells BATTERY_STATUS reports, else the first
    /// battery voltage seen in the chemistry's resting window), else assumed (said).
    pub cell_count: Option<u32>,
    /// Nominal cell voltage, V: a capacity in mAh times cells times this is Wh. Default: the
    /// chemistry's (LiPo 3.7, LiHV 3.8, Li-ion 3.6).
    pub nominal_cell_v: Option<f64>,
    /// Cell chemistry: `lipo` (4.20 V full), `lihv` (4.35 V full, the TB48D), `liion`
    /// (4.20 V full, a lower floor) or `lifepo4` (3.65 V full). It picks the cell count's
    /// voltage window, the nominal voltage and the default OCV curve. Default: LiHV when
    /// `MOT_BAT_VOLT_MAX` is cells × 4.35, else LiPo, said as assumed.
    pub chemistry: Option<crate::battery::Chemistry>,
    /// Take remaining energy from the autopilot's battery percentage when it reports one
    /// (`capacity_wh` × %), rather than `capacity_wh` − energy used. Default true.
    pub use_battery_pct: bool,
    /// Energy kept in reserve at landing, % of capacity. Default 20.
    pub reserve_pct: f64,
    /// Model whose prediction is the forecast (and is integrated when nothing is measured),
    /// always (no online selection). Default: the vehicle profile's `[forecast] model`, else
    /// `lstm`, while it runs (else the forecast follows measured power), moving to the model
    /// with the lowest recent error on this vehicle as `[energy.select]` allows.
    pub model: Option<String>,
    /// Online selection of the forecast model (`[energy.select]`).
    pub select: select::SelectConfig,
    /// Time constant of the forecast power's moving average, s. Default 10.
    pub smoothing_s: f64,
    /// Ground speed flying home, m/s. Default: `[mission] speed_m_s`, else 10.
    pub cruise_speed_m_s: Option<f64>,
    /// Descent rate for the final descent, m/s. Default 2 (the M100 allows 4).
    pub descent_speed_m_s: f64,
    /// Time for the final approach and touchdown, s, at hover power. Default 15.
    pub landing_s: f64,
    /// Longest step integrated as one, s; longer gaps are capped. Default 1.
    pub max_dt_s: f64,
    /// What named the pack, when not the config file (`--pack …`, the M100 data set):
    /// said as the provenance of its figures. Not a TOML key.
    #[serde(skip)]
    pub named: Option<String>,
}

impl Default for EnergyConfig {
    fn default() -> Self {
        Self {
            capacity_wh: None,
            cell_count: None,
            nominal_cell_v: None,
            chemistry: None,
            use_battery_pct: true,
            reserve_pct: 20.0,
            model: None,
            select: select::SelectConfig::default(),
            smoothing_s: 10.0,
            cruise_speed_m_s: None,
            descent_speed_m_s: 2.0,
            landing_s: 15.0,
            max_dt_s: 1.0,
            named: None,
        }
    }
}

impl EnergyConfig {
    /// Range checks; each message names the key (several errors: one per line).
    pub fn validate(&self) -> Result<(), String> {
        use crate::validate::above;
        let mut errs = crate::validate::Errors::new();
        if let Some(v) = self.capacity_wh {
            errs.range("energy.capacity_wh", v, above(0.0), "Wh");
        }
        errs.range("energy.smoothing_s", self.smoothing_s, above(0.0), "s");
        errs.range(
            "energy.descent_speed_m_s",
            self.descent_speed_m_s,
            above(0.0),
            "m/s",
        );
        errs.range("energy.max_dt_s", self.max_dt_s, above(0.0), "s");
        if let Some(v) = self.cruise_speed_m_s {
            errs.range("energy.cruise_speed_m_s", v, above(0.0), "m/s");
        }
        errs.range("energy.landing_s", self.landing_s, 0.0.., "s");
        errs.range("energy.reserve_pct", self.reserve_pct, 0.0..100.0, "%");
        if let Some(n) = self.cell_count {
            errs.range("energy.cell_count", n, 1..=24, "cells");
        }
        if let Some(v) = self.nominal_cell_v {
            errs.range("energy.nominal_cell_v", v, 1.0..=5.0, "V");
        }
        errs.extend(self.select.validate());
        errs.into_result()
    }
}

impl EnergyConfig {
    /// The `[energy]` keys the vehicle may answer for instead.
    pub fn battery(&self) -> BatteryConfig {
        BatteryConfig {
            capacity_wh: self.capacity_wh,
            cell_count: self.cell_count,
            nominal_cell_v: self.nominal_cell_v,
            chemistry: self.chemistry,
            named: self.named.clone(),
        }
    }

    /// Take a pack named for the run (`--pack`, the M100 data set) where the `[energy]`
    /// keys are silent: the config file's own keys win.
    pub fn fill_pack(&mut self, pack: &BatteryConfig) {
        if self.capacity_wh.is_none() && self.cell_count.is_none() && self.chemistry.is_none() {
            self.capacity_wh = pack.capacity_wh;
            self.cell_count = pack.cell_count;
            self.chemistry = pack.chemistry;
            self.nominal_cell_v = self.nominal_cell_v.or(pack.nominal_cell_v);
            self.named.clone_from(&pack.named);
        }
    }
}
