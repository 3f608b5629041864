//! A fleet worker's checkpoints on the pipeline's side ([`crate::source::nats::checkpoint`]
//! keeps them in NATS): what one vehicle's chain state is ([`VehicleState`]), the card
//! that says which chains may take it back ([`card`]), and the energy stage's part
//! (`Kept`): the state restored at its first estimate, and handed over about once a
//! second of source time.

use serde::{Deserialize, Serialize};

use super::stages::Taken;
use crate::alert::AlertEngine;
use crate::energy::EnergyTracker;
use crate::report::VehicleId;
use crate::source::nats::checkpoint;

/// One vehicle's chain state as a checkpoint keeps it (CBOR, which keeps the non-finite
/// numbers JSON cannot).
#[derive(Clone, Serialize, Deserialize)]
pub struct VehicleState {
    /// The source time of the last estimate accounted, s.
    pub t_s: f64,
    /// The energy stage's whole state: energy used, the pack's state and history, the
    /// mission's progress.
    pub energy: EnergyTracker,
    /// Where each alert rule stands, by name.
    pub alerts: Vec<(String, crate::alert::RuleState)>,
    /// What the vehicle said of itself (parameters, pack), as the energy stage took it.
    pub params: crate::vehicle::params::VehicleParams,
}

/// Read a vehicle state.
pub fn decode(bytes: &[u8]) -> Result<VehicleState, String> {
    ciborium::from_reader(bytes).map_err(|e| e.to_string())
}

/// Whether `bytes` read as a vehicle state (the worker's check before it restores).
pub fn check(bytes: &[u8]) -> Result<(), String> {
    decode(bytes).map(|_| ())
}

/// The card of a chain built from `cfg` and `vehicle`: a digest of the models, vehicle
/// profile, energy, alert, telemetry and mission tables, with dronewatt's version and the
/// checkpoints' layout. Two workers restore each other's states only when their cards are
/// equal.
pub fn card(cfg: &crate::config::Config, vehicle: &crate::model::LoadedProfile) -> String {
    use sha2::Digest as _;
    let text = format!(
        "{:?}|{:?}|{:?}|{:?}|{:?}|{:?}",
        cfg.models, vehicle.profile, cfg.energy, cfg.alerts, cfg.telemetry, cfg.mission
    );
    let digest = sha2::Sha256::digest(text.as_bytes());
    let hex: String = digest[..8].iter().map(|b| format!("{b:02x}")).collect();
    format!(
        "dronewatt {} layout {} {hex}",
        env!("CARGO_PKG_VERSION"),
        checkpoint::LAYOUT
    )
}

/// A fleet worker's checkpoint, on the energy stage's side: the state restored at the first estimate, the
/// time it reflects, and the state handed over about every second of source time.
#[derive(Default)]
pub(super) struct Kept {
    /// Looked for the restored state (once, at the first estimate).
    looked: bool,
    /// Estimates up to this source time are in the restored state already.
    until: Option<f64>,
    /// When the state was last handed over (source time).
    last: Option<f64>,
}

impl Kept {
    pub(super) fn restore(
        &mut self,
        vehicle: VehicleId,
        energy: &mut EnergyTracker,
        alerts: &mut AlertEngine,
        taken: &mut Taken,
    ) {
        if std::mem::replace(&mut self.looked, true) || !checkpoint::enabled() {
            return;
        }
        let Some(bytes) = checkpoint::take_restore(vehicle) else {
            return;
        };
        // The worker read these bytes before it restored the partition ([`check`]).
        let s = match decode(&bytes) {
            Ok(s) => s,
            Err(e) => {
                tracing::warn!(vehicle = %vehicle, "the fleet's checkpoint does not read ({e}): not restored");
                return;
            }
        };
        energy.restore(s.energy);
        alerts.restore(&s.alerts);
        taken.pack_id.clone_from(&s.params.pack_id);
        taken.params = s.params;
        taken.restored = true;
        self.until = Some(s.t_s);
        self.last = Some(s.t_s);
        tracing::info!(
            vehicle = %vehicle,
            "restored from the fleet's checkpoint at {:.1} s: {:.2} Wh used so far",
            s.t_s,
            energy.used_wh()
        );
    }

    /// Whether an estimate at `t_s` is in the restored state already.
    pub(super) fn reflects(&self, t_s: f64) -> bool {
        self.until.is_some_and(|u| t_s <= u)
    }

    pub(super) fn record(
        &mut self,
        vehicle: VehicleId,
        t_s: f64,
        energy: &EnergyTracker,
        alerts: &AlertEngine,
        taken: &Taken,
    ) {
        if !checkpoint::enabled() || self.last.is_some_and(|l| t_s - l < checkpoint::EVERY_S) {
            return;
        }
        self.last = Some(t_s);
        let state = VehicleState {
            t_s,
            energy: energy.clone(),
            alerts: alerts.standing(),
            params: taken.params.clone(),
        };
        let mut bytes = Vec::new();
        match ciborium::into_writer(&state, &mut bytes) {
            Ok(()) => checkpoint::record(vehicle, checkpoint::Saved { t_s, bytes }),
            Err(e) => tracing::warn!(vehicle = %vehicle, "checkpoint: {e}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_vehicle_state_survives_the_checkpoint_format_and_bad_bytes_are_said() {
        let cfg = crate::energy::EnergyConfig::default();
        let s = VehicleState {
            t_s: 12.5,
            energy: EnergyTracker::new(&cfg, Some(10.0)).unwrap(),
            alerts: vec![("low".into(), crate::alert::RuleState::default())],
            params: crate::vehicle::params::VehicleParams::from_pairs(&[("BATT_CAPACITY", 5200.0)]),
        };
        let mut b = Vec::new();
        ciborium::into_writer(&s, &mut b).unwrap();
        let back = decode(&b).unwrap();
        assert_eq!((back.t_s, &back.params), (12.5, &s.params));
        assert_eq!(back.alerts, s.alerts);
        assert!(check(&b[..b.len() / 2]).is_err());
        assert!(check(b"not cbor").is_err());
    }
}
