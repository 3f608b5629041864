//! Flying the mission in hand on paper, live: the whole plan from home in the current wind,
//! the legs already flown, and where along it the vehicle is now.

use super::*;

impl LiveMission {
    /// Fly the mission in hand again when the wind estimate has moved away from the wind it
    /// was flown in (see [`REFLY_WIND_M_S`]); the status after it, when it did.
    pub(super) fn refly_in_wind(&mut self, t_s: f64) -> Option<MissionStatus> {
        let fl = self.flown.as_ref()?;
        let (a, b) = (self.wind.velocity_enu(), fl.wind.velocity_enu());
        if (a - b).norm() <= REFLY_WIND_M_S || t_s - fl.flown_at < REFLY_EVERY_S {
            return None;
        }
        let (plan, seq_offset, items) = (fl.plan.clone(), fl.seq_offset, fl.items);
        let source = plan.source.clone();
        self.flown = self.fly(&source, plan, seq_offset, items, t_s);
        self.status(t_s, true)
    }

    /// Fly `plan` on paper in the current wind and forecast it.
    pub(super) fn fly(
        &mut self,
        source: &str,
        plan: Plan,
        seq_offset: u16,
        items: u16,
        t_s: f64,
    ) -> Option<Flown> {
        let s = &self.setup;
        let cond = Conditions {
            wind: self.wind,
            payload_g: s.payload_g,
            speed_m_s: s.speed_m_s,
            rate_hz: s.rate_hz,
        };
        let class = self.class();
        let traj = fly_as(class, &plan, &s.forecast.kinematics, &s.flight, &cond);
        if traj.samples.is_empty() {
            tracing::warn!("{source}: the mission flies nowhere (no take-off, no waypoint); no mission forecast");
            return None;
        }
        let cal = self.live_calibration(class);
        let live_weight = cal.live_weight;
        // only the members run (the slice `forecast` is given); the models' order is restored after
        let (ran, rest): (Vec<_>, Vec<_>) = std::mem::take(&mut self.setup.models)
            .into_iter()
            .enumerate()
            .partition(|(_, m)| cal.members.iter().any(|c| c.model == m.name()));
        let (order, mut members): (Vec<usize>, Vec<_>) = ran.into_iter().unzip();
        let f = forecast(
            &traj,
            &mut members,
            &cal,
            self.setup.window,
            crate::mission::MODEL_STRIDE,
        );
        let mut back: Vec<_> = order.into_iter().zip(members).chain(rest).collect();
        back.sort_by_key(|(i, _)| *i);
        self.setup.models = back.into_iter().map(|(_, m)| m).collect();
        tracing::info!(
            "{source}: {items} items, {:.0} m, {:.0} s, {:.1} Wh (P50), {:.1} Wh (P90) with the return and landing, wind {:.1} m/s from {:.0}°",
            f.distance_m,
            f.duration_s,
            f.energy_p50_wh,
            f.energy_p90_wh,
            self.wind.speed_m_s,
            self.wind.from_deg
        );
        let route_stride = traj
            .enu_m
            .len()
            .div_ceil(MissionStatus::ROUTE_POINTS)
            .max(1);
        let route = std::sync::Arc::new(
            traj.enu_m
                .iter()
                .step_by(route_stride)
                .map(|p| [p[0], p[1]])
                .collect(),
        );
        Some(Flown {
            plan,
            seq_offset,
            items,
            traj,
            forecast: f,
            wind: self.wind,
            class,
            flown_at: t_s,
            route,
            route_stride,
            live_weight,
        })
    }
    /// The forecast's calibration for the models that run live: each fitted correction
    /// belongs to its model, so the members that do not run are left out.
    fn live_calibration(&self, class: VehicleClass) -> crate::mission::forecast::Calibration {
        // Each fitted correction belongs to its model: the members that do not run are left
        // out; with none of them, no correction (the P90 ratio, the by-flight spread, still
        // applies). Only the members' models run: live, nothing reads the others.
        let fitted = &self.setup.forecast.calibration;
        let runs = |name: &str| self.setup.models.iter().any(|m| m.name() == name);
        let missing: Vec<&str> = fitted
            .members
            .iter()
            .map(|m| m.model.as_str())
            .filter(|n| !runs(n))
            .collect();
        let mut cal = if missing.len() < fitted.members.len() {
            if !missing.is_empty() {
                tracing::warn!("mission forecast: {missing:?} do not run (no [forecast.live] calibrated_profile?); the P50 is the mean of the others");
            }
            crate::mission::forecast::Calibration {
                members: fitted
                    .members
                    .iter()
                    .filter(|m| runs(&m.model))
                    .cloned()
                    .collect(),
                ..fitted.clone()
            }
        } else {
            let first = self
                .setup
                .models
                .first()
                .map(|m| m.name().to_string())
                .unwrap_or_default();
            tracing::warn!("mission forecast: {missing:?} do not run (no [forecast.live] calibrated_profile); the P50 follows {first:?} uncorrected");
            crate::mission::forecast::Calibration {
                p90_ratio: fitted.p90_ratio,
                ..crate::mission::forecast::Calibration::uncorrected(&first)
            }
        };
        // A plane's wing-borne samples: the fixed-wing model, uncorrected (the fitted
        // correction and spread are the M100's); a plane has nothing else.
        if matches!(class, VehicleClass::FixedWing | VehicleClass::Vtol) && runs("fixed_wing") {
            if class == VehicleClass::FixedWing {
                cal.members.clear();
            }
            cal.members
                .push(crate::mission::forecast::Member::of("fixed_wing"));
            cal.p90_ratio = cal
                .p90_ratio
                .max(crate::mission::forecast::UNCALIBRATED_P90);
            // the live weight was fitted with the multirotor's members
            cal.live_weight = 0.0;
        }
        cal
    }
}

/// The trajectory sample the vehicle is at: among the legs of the item it flies to
/// (MISSION_CURRENT), nearest its position; the item's first sample without a position;
/// the end once past the last item.
pub(super) fn locate(fl: &Flown, seq: u16, position: Option<(f64, f64, f64)>) -> usize {
    let n = fl.traj.samples.len();
    let item = usize::from(seq.saturating_sub(fl.seq_offset));
    if item >= fl.plan.items.len() {
        return n.saturating_sub(1);
    }
    let from = fl.traj.first_sample_of_item(item).min(n.saturating_sub(1));
    let to = fl.traj.first_sample_of_item(item + 1).max(from + 1);
    match position {
        Some((lat, lon, up)) => {
            let (e, nn) = enu_of(&fl.plan.home, lat, lon);
            fl.traj
                .locate(from, to - from, [e as f32, nn as f32, up as f32])
        }
        None => from,
    }
}
