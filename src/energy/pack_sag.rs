//! Whether the pack sags at all: a simulator's fixed battery, a stuck reading or a sensor
//! behind a regulator shows no I·R, and its voltage forecast is withheld.

/// Detects a pack that does not sag: over [`SagCheck::MIN_LOADED_S`] of readings under load
/// the current swings by [`SagCheck::MIN_SWING_A`] or more while the voltage moves by less
/// than a quarter of the sag the prior resistance gives that swing (and at most
/// [`SagCheck::MAX_SPREAD_V_CELL`] a cell). Any real pack sags by I·R, and discharging only
/// adds to the voltage's spread.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct SagCheck {
    /// Seconds under load seen.
    pub loaded_s: f64,
    i: Option<(f64, f64)>,
    v: Option<(f64, f64)>,
    /// Decided: the pack does not sag.
    pub flat: bool,
}

impl SagCheck {
    pub const MIN_SWING_A: f64 = 2.0;
    pub const MAX_SPREAD_V_CELL: f64 = 0.01;
    pub const MIN_LOADED_S: f64 = 10.0;

    /// Take one reading under load (`dt` s since the last); `r_prior` the pack's prior
    /// resistance, Ω.
    pub fn update(&mut self, dt: f64, v: f64, i: f64, cells: u32, r_prior: f64) -> bool {
        let span =
            |r: Option<(f64, f64)>, x: f64| r.map_or((x, x), |(lo, hi)| (lo.min(x), hi.max(x)));
        self.loaded_s += dt;
        self.i = Some(span(self.i, i));
        self.v = Some(span(self.v, v));
        let swing = self.i.map_or(0.0, |(lo, hi)| hi - lo);
        let spread = self.v.map_or(f64::INFINITY, |(lo, hi)| hi - lo);
        if self.loaded_s >= Self::MIN_LOADED_S
            && swing >= Self::MIN_SWING_A
            && spread
                <= (Self::MAX_SPREAD_V_CELL * f64::from(cells.max(1))).min(0.25 * swing * r_prior)
        {
            self.flat = true;
        }
        self.flat
    }
}
