//! What the store gives a flight at its start (the vehicle's learned capacity, resistance,
//! adaptation and profile: [`lookup`]) and keeps of it at its end ([`remember`]). A store that
//! cannot be opened is a warning: the flight goes on without it.

use std::path::Path;

use super::*;
use crate::vehicle::params::Identity;

/// What earlier flights taught about a vehicle.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Learned {
    /// The models' adaptation fits.
    pub fits: Option<Vec<(String, ModelFit)>>,
    /// The pack's capacity, Wh: the posterior over the last [`CAPACITY_FLIGHTS`] flights
    /// that measured one ([`Store::learned_capacity`]), and how many did.
    pub capacity_wh: Option<(f64, usize)>,
    /// The profile `dronewatt learn` wrote for it.
    pub profile: Option<LearnedProfile>,
    /// What its last flight left of its pack, and each identified pack's last flight.
    pub pack: crate::battery::PackHistories,
}

/// Flights the learned capacity is learned over.
pub const CAPACITY_FLIGHTS: usize = 3;

/// What earlier flights taught about this vehicle, for the warm start; any store problem is
/// a warning and nothing learned (the run goes on as a first flight).
/// `now_log_s`: the source's time now (its clock is used for the gap since the last flight
/// when it is a Unix time: [`Store::pack_history`]). `sig`: the pack the vehicle reported,
/// which tells vehicles with no uid apart (`matching`).
pub fn lookup(dir: &Path, id: &Identity, sig: &PackSig, now_log_s: Option<f64>) -> Learned {
    let got = Store::open(dir).and_then(|s| {
        let m = s.resolve(id, sig)?;
        matching::say(id, &m);
        let key = m.key;
        let l = Learned {
            fits: s.learned_fits(&key)?,
            capacity_wh: s.learned_capacity(&key)?,
            profile: s.learned_profile(&key.key)?,
            pack: s.pack_histories(&key, now_log_s)?,
        };
        Ok((l, key))
    });
    match got {
        Ok((l, key)) => {
            let found = l.fits.is_some() || l.capacity_wh.is_some() || l.profile.is_some();
            tracing::info!(
                "vehicle {} ({}): {}",
                key.key,
                key.kind,
                if found {
                    "found what earlier flights learned"
                } else {
                    "first flight in the store"
                }
            );
            l
        }
        Err(e) => {
            tracing::warn!(
                "vehicle store: {e:#}; this run neither starts from nor keeps what was learned"
            );
            Learned::default()
        }
    }
}

/// At the end of a run: keep the vehicle, its fits and the flight. Any store problem is a
/// warning (the run's results stand without it).
pub fn remember(
    dir: &Path,
    id: Option<&Identity>,
    sig: &PackSig,
    fits: Option<&[(String, ModelFit)]>,
    log: &FlightLog,
) {
    let Some(id) = id else {
        tracing::info!("vehicle store: no autopilot heartbeat heard, so no vehicle to remember");
        return;
    };
    let flight = log.summary();
    let result = Store::open(dir).and_then(|mut s| {
        let m = s.resolve(id, sig)?;
        s.record_matched(id, &m, sig, fits, flight.as_ref())?;
        Ok((s.path().to_path_buf(), m.key.key))
    });
    match result {
        Ok((path, key)) => tracing::info!(
            "vehicle {key}: {} in {}",
            match &flight {
                Some(f) => format!(
                    "flight remembered ({:.2} Wh, {:.0} s airborne)",
                    f.energy_wh, f.airborne_s
                ),
                None => "seen (no power measured, no flight)".to_string(),
            },
            path.display()
        ),
        Err(e) => tracing::warn!("vehicle store: {e:#}; what this run learned is not kept"),
    }
}

/// `dronewatt learn`: keep the profile it wrote for this vehicle. Any store problem is a
/// warning (the profile file stands without it).
pub fn remember_profile(dir: &Path, id: &Identity, path: &Path, forecast_model: Option<&str>) {
    let key = VehicleKey::of(id);
    match Store::open(dir).and_then(|mut s| {
        s.record_profile(id, path, forecast_model)?;
        Ok(s.path().to_path_buf())
    }) {
        Ok(db) => tracing::info!(
            "vehicle {}: the next run starts from {} (kept in {})",
            key.key,
            path.display(),
            db.display()
        ),
        Err(e) => {
            tracing::warn!("vehicle store: {e:#}; the learned profile is not kept for the vehicle")
        }
    }
}
