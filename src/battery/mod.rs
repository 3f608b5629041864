//! Lithium pack model: resting-voltage → energy, loaded-voltage prediction, online
//! estimation and voltage forecasting.
//!
//! Why: a drone's remaining energy is not "rated − used" (packs rarely start full) and
//! a percentage read from the loaded voltage is wrong by the I·R sag. This module turns a
//! *resting* voltage into energy through a monotone OCV table, and models the *loaded*
//! voltage so sag can be predicted ahead of a power profile.
//!
//! Units: volts (pack unless a name says `cell`), amperes (discharge positive),
//! ohms (pack), seconds, watt-hours, heat in A²·s.
//!
//! Model (one RC pair + a heat proxy; fitted on the DJI Matrice 100 data set,
//! Rodrigues et al. 2021, doi:10.1184/R1/12683453, CC BY 4.0):
//!
//! ```text
//! E      : energy above floor (Wh), E -= V·I·dt/3600          (energy counting)
//! OCV    = n · v_cell(E)                                      (ocv.rs table)
//! H      : heat proxy, dH/dt = I² − H/τh                      (pack warms in flight, R falls)
//! f      = 1 + a·exp(−H/Hs)                                   (resistance factor)
//! x1     : dx1/dt = (f·I − x1)/τ1                             (polarisation, unit gain)
//! V      = OCV − b − R0·f·I − R1·x1
//! ```
//!
//! Per-pack resistance scale: packs differ (and cold packs sag more) by ±30 % in R; the
//! estimator accumulates this flight's least-squares scale k ([`Estimator::pack_scale`]) and
//! the next flight on the same pack starts from R·(1 + 0.555·(k − 1))
//! ([`CircuitParams::carried_over`]). First flights of a pack have no such information.
//!
//! The online estimator runs a 3×3 RLS with forgetting on θ = [R0, R1, b], so warm-up,
//! ageing and OCV offsets are tracked in flight (the modelled voltage now, `internal_r_ohm`).
//! A forecast flies on the flight's own fit instead, which splits the resistance into the
//! part that stays and the cold part that fades as the pack warms on ([`split`]). The
//! forecast solves P = V·I (a quadratic in I) each step. The lowest point of a smooth power forecast is deepened by the
//! transients it lacks ([`forecast::dip`]; chosen by by-flight CV on the training flights,
//! `lab/scripts/battery/NOTES-min-voltage.md`).

pub mod chemistry;
pub mod circuit;
pub mod deep;
pub mod forecast;
pub mod history;
pub mod ocv;
pub mod split;
pub mod trend;

pub use chemistry::{cell_candidates, Chemistry};
pub use circuit::{CircuitParams, Estimate, Estimator, PACK_SCALE_CARRY};
pub use forecast::{forecast, Forecast};
pub use history::{PackHistories, PackHistory, SAME_PACK_GAP_S};
pub use ocv::OcvCurve;
