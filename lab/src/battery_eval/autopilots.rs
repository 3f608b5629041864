//! What the autopilots compute for the pack today, run over a flight's raw rows as their
//! battery monitors would: `battery-eval`'s baselines, as the autopilots are now (the facts
//! in `shared/design/battery-baselines.md`, checked against PX4's `src/lib/battery/battery.cpp`
//! and ArduPilot's `AP_BattMonitor_Backend::update_resistance_estimate`; written here from
//! those descriptions, not copied). Model code: numbers in, numbers out.
//!
//! - [`Px4Battery`]: PX4's `Battery` with its defaults: `BAT1_R_INTERNAL` = −1, so the
//!   resistance is the online estimate (a two-parameter recursive least squares on
//!   V = V_oc − R·I, forgetting factor 0.95, an update kept only where the covariance
//!   shrinks); the cell voltage compensated by R·I and low-passed (τ = 1 s), linear from
//!   `BAT1_V_EMPTY` 3.6 V to `BAT1_V_CHARGED` 4.05 V; the voltage alone for the first 2 s
//!   after the pack is seen, then fused with coulomb counting (weight 0.03·(1 − SoC_v) an
//!   update), capped at 1 − used/capacity.
//! - [`ArduBattery`]: ArduPilot's monitor: mAh counted from boot against `BATT_CAPACITY`
//!   (full at every boot), and the resistance estimate behind `voltage_resting_estimate`
//!   (V and I low-passed with τ = 0.5 s, the instantaneous −ΔV/ΔI blended in with gain
//!   0.1·|ΔI|/I_max, capped by the drop from the highest voltage seen; starts at 0).
//!
//! Both update once a row, at the data set's rate (~10 Hz); PX4's analog monitor runs
//! faster, and its fusion weight is per update, so its voltage pull acts over ~7 s here
//! instead of under one: a difference of seconds in a flight of minutes.

/// PX4's `BAT1_V_EMPTY` (since 2024) and `BAT1_V_CHARGED`, V a cell.
pub const PX4_V_EMPTY: f64 = 3.6;
pub const PX4_V_CHARGED: f64 = 4.05;
/// PX4's RLS: forgetting factor, start resistance (Ω a cell), start OCV (V a cell), and the
/// start covariance's diagonal (a cell: OCV, R).
const LAMBDA: f64 = 0.95;
const R_DEFAULT: f64 = 0.005;
const OCV_DEFAULT: f64 = 4.2;
const OCV_COVARIANCE: f64 = 1.5;
const R_COVARIANCE: f64 = 0.1;
/// PX4 takes the voltage alone this long after the pack is seen, s.
const PX4_SETTLE_S: f64 = 2.0;
/// Below this a pack is not connected (PX4's LITHIUM_BATTERY_RECOGNITION_VOLTAGE), V.
const RECOGNITION_V: f64 = 2.1;
/// PX4's `BAT_LOW_THR`: the low-battery warning below this state of charge.
pub const PX4_LOW_SOC: f64 = 0.15;
/// ArduPilot's `BATT_LOW_TIMER`: the voltage must stay under `BATT_LOW_VOLT` this long, s.
pub const AP_LOW_TIMER_S: f64 = 10.0;

/// PX4's battery estimator for one pack of `n_cells` and `capacity_mah`.
#[derive(Debug, Clone)]
pub struct Px4Battery {
    n: f64,
    capacity_mah: f64,
    /// Time since the pack was seen, s.
    connected_s: f64,
    /// RLS state [V_oc, R·n] (pack), its covariance and that covariance's norm.
    rls: [f64; 2],
    p: [[f64; 2]; 2],
    p_norm: f64,
    /// The resistance in use, Ω a cell.
    r_cell: f64,
    /// Compensated cell voltage, low-passed (None until the first update).
    cell_v: Option<f64>,
    discharged_mah: f64,
    soc: f64,
}

impl Px4Battery {
    pub fn new(n_cells: u32, capacity_mah: f64) -> Self {
        let n = f64::from(n_cells.max(1));
        let mut b = Self {
            n,
            capacity_mah,
            connected_s: 0.0,
            rls: [OCV_DEFAULT * n, R_DEFAULT * n],
            p: [[0.0; 2]; 2],
            p_norm: 0.0,
            r_cell: R_DEFAULT,
            cell_v: None,
            discharged_mah: 0.0,
            soc: 0.0,
        };
        b.reset_covariance();
        b
    }

    fn reset_covariance(&mut self) {
        self.p = [[OCV_COVARIANCE * self.n, 0.0], [0.0, R_COVARIANCE * self.n]];
        self.p_norm = norm(&self.p);
    }

    /// The resistance estimate restarted at this voltage (PX4 does so on every update
    /// until the pack has settled, so the estimate starts from the settled reading).
    fn reset(&mut self, v: f64, i: f64) {
        self.rls = [v, R_DEFAULT * self.n];
        self.reset_covariance();
        self.r_cell = R_DEFAULT;
        self.cell_v = Some(v / self.n + self.r_cell * i);
    }

    fn update_resistance(&mut self, v: f64, i: f64) {
        let x = [1.0, -i];
        let px = [
            self.p[0][0] * x[0] + self.p[0][1] * x[1],
            self.p[1][0] * x[0] + self.p[1][1] * x[1],
        ];
        let xpx = x[0] * px[0] + x[1] * px[1];
        let err = v - (x[0] * self.rls[0] + x[1] * self.rls[1]);
        let gamma = [px[0] / (LAMBDA + xpx), px[1] / (LAMBDA + xpx)];
        // P ← (P − γ·xᵀP) / λ, and xᵀP is (Px)ᵀ: P stays symmetric.
        let mut p = [[0.0; 2]; 2];
        for (r, row) in p.iter_mut().enumerate() {
            for (c, cell) in row.iter_mut().enumerate() {
                *cell = (self.p[r][c] - gamma[r] * px[c]) / LAMBDA;
            }
        }
        let p_norm = norm(&p);
        if p_norm < self.p_norm {
            self.rls = [self.rls[0] + gamma[0] * err, self.rls[1] + gamma[1] * err];
            self.p = p;
            self.p_norm = p_norm;
            self.r_cell = (self.rls[1] / self.n).max(0.0);
        } else {
            self.rls[0] = v + self.rls[1] * i;
        }
    }

    /// One battery reading `dt` s after the last: pack voltage (V), current (A).
    pub fn update(&mut self, dt: f64, v: f64, i: f64) {
        if !(v.is_finite() && i.is_finite()) {
            return;
        }
        let connected = v >= RECOGNITION_V;
        self.connected_s = if connected {
            self.connected_s + dt.max(0.0)
        } else {
            0.0
        };
        let settled = connected && self.connected_s > PX4_SETTLE_S;
        if connected && !settled {
            self.reset(v, i);
        }
        // −1 A is PX4's "no current measurement": nothing counted.
        let used = if i == -1.0 {
            0.0
        } else {
            i * 1e3 * dt.max(0.0) / 3600.0
        };
        self.discharged_mah += used;
        // The voltage-based state of charge: the cell voltage compensated for the load.
        let mut cell = v / self.n;
        if i > f64::EPSILON {
            self.update_resistance(v, i);
            cell += self.r_cell * i;
        }
        let a = dt.max(0.0) / (1.0 + dt.max(0.0));
        let filtered = match self.cell_v {
            Some(f) => f + a * (cell - f),
            None => cell,
        };
        self.cell_v = Some(filtered);
        let soc_v = ((filtered - PX4_V_EMPTY) / (PX4_V_CHARGED - PX4_V_EMPTY)).clamp(0.0, 1.0);
        if self.capacity_mah > 0.0 && settled {
            let w = 0.03 * (1.0 - soc_v);
            self.soc = (1.0 - w) * self.soc + w * soc_v;
            self.soc = (self.soc - used / self.capacity_mah).max(0.0);
            let counted = (1.0 - self.discharged_mah / self.capacity_mah).max(0.0);
            // A negative current (charging, or a sensor's offset) counts back up: the report
            // stays in 0-1, as PX4's does.
            self.soc = self.soc.min(counted).min(1.0);
        } else {
            self.soc = soc_v;
        }
    }

    /// The state of charge PX4 reports, 0–1.
    pub fn soc(&self) -> f64 {
        self.soc
    }

    /// The resistance in use, Ω a cell.
    pub fn r_cell(&self) -> f64 {
        self.r_cell
    }

    /// The load-compensated, low-passed pack voltage its state of charge reads (V): PX4's
    /// idea of the resting voltage.
    pub fn compensated_v(&self) -> f64 {
        self.cell_v.map_or(f64::NAN, |c| c * self.n)
    }
}

/// The covariance norm PX4 compares: sqrt(P00² + 2·P10² + P11²).
fn norm(p: &[[f64; 2]; 2]) -> f64 {
    (p[0][0].powi(2) + 2.0 * p[1][0].powi(2) + p[1][1].powi(2)).sqrt()
}

/// ArduPilot's battery monitor for one pack of `capacity_mah`.
#[derive(Debug, Clone, Default)]
pub struct ArduBattery {
    capacity_mah: f64,
    consumed_mah: f64,
    resistance: f64,
    v_filt: f64,
    i_filt: f64,
    i_max: f64,
    v_ref: f64,
    i_ref: f64,
    /// Whether the resistance estimate has run once (its first interval is "since boot").
    started: bool,
    /// The raw-voltage low failsafe: since when the voltage has been under the threshold,
    /// and when the failsafe fired.
    low_since_s: Option<f64>,
    failsafe_s: Option<f64>,
}

/// ArduPilot's resistance estimate: the filters' time constant (s) and the blend gain.
const AP_TC_1: f64 = 0.5;
const AP_TC_2: f64 = 0.1;

impl ArduBattery {
    pub fn new(capacity_mah: f64) -> Self {
        Self {
            capacity_mah,
            ..Self::default()
        }
    }

    /// One reading `dt` s after the last: pack voltage (V), current (A).
    pub fn update(&mut self, dt: f64, v: f64, i: f64) {
        if !(v.is_finite() && i.is_finite()) {
            return;
        }
        self.consumed_mah += i * 1e3 * dt.max(0.0) / 3600.0;
        if i <= 0.0 {
            return;
        }
        self.i_max = self.i_max.max(i);
        let di = i - self.i_filt;
        if di == 0.0 {
            return;
        }
        if v > self.v_ref {
            (self.v_ref, self.i_ref) = (v, i);
        }
        // The first interval runs from boot: long, so the filters take half the reading.
        let filt_alpha = if self.started {
            (dt / (dt + AP_TC_1)).clamp(0.0, 0.5)
        } else {
            0.5
        };
        self.started = true;
        let r_alpha = (AP_TC_2 * (di / self.i_max).abs()).min(1.0);
        let r = -(v - self.v_filt) / di;
        if r > 0.0 {
            self.resistance = self.resistance * (1.0 - r_alpha) + r * r_alpha;
        }
        if self.v_ref > v && i > self.i_ref {
            self.resistance = self.resistance.min((self.v_ref - v) / (i - self.i_ref));
        }
        self.v_filt += filt_alpha * (v - self.v_filt);
        self.i_filt += filt_alpha * (i - self.i_filt);
    }

    /// The low-voltage failsafe with `BATT_FS_VOLTSRC` = 0 (raw voltage, the default): it
    /// fires once the voltage has stayed under `low_v` for [`AP_LOW_TIMER_S`]; a reading
    /// at or above it restarts the timer. Returns when it fired (s), once it has.
    pub fn low_failsafe(&mut self, t_s: f64, v: f64, low_v: f64) -> Option<f64> {
        if self.failsafe_s.is_none() && v.is_finite() && t_s.is_finite() {
            if v < low_v {
                let since = *self.low_since_s.get_or_insert(t_s);
                if t_s - since > AP_LOW_TIMER_S {
                    self.failsafe_s = Some(t_s);
                }
            } else {
                self.low_since_s = None;
            }
        }
        self.failsafe_s
    }

    /// `voltage_resting_estimate`: the voltage with the sag put back, never below it (V).
    pub fn resting_v(&self, v: f64, i: f64) -> f64 {
        v.max(v + i * self.resistance)
    }

    /// The resistance estimate, Ω (pack).
    pub fn resistance(&self) -> f64 {
        self.resistance
    }

    /// Remaining charge as ArduPilot reports it: (capacity − mAh since boot) / capacity,
    /// within 0-1 (a charging current never reads over full).
    pub fn remaining(&self) -> f64 {
        if self.capacity_mah > 0.0 {
            ((self.capacity_mah - self.consumed_mah) / self.capacity_mah).clamp(0.0, 1.0)
        } else {
            f64::NAN
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pack V = OCV − R·I with the current stepping between hover and climb.
    fn pack(k: usize, ocv: f64, r: f64) -> (f64, f64) {
        let i = if (k / 30).is_multiple_of(2) {
            15.0
        } else {
            30.0
        };
        (ocv - r * i, i)
    }

    proptest::proptest! {
        /// Whatever a monitor reads (a pack at 0 V, currents negative or huge, repeated or
        /// long gaps, NaN), both report a state of charge in 0-1, a finite resistance of
        /// zero or more, and a resting voltage never under the reading.
        #[test]
        fn the_autopilots_stay_in_range_on_any_readings(
            rows in proptest::collection::vec(
                (0.0f64..3.0, proptest::prop_oneof![0.0f64..30.0, proptest::strategy::Just(f64::NAN)], -5.0f64..200.0),
                1..400,
            ),
            cells in 0u32..14,
        ) {
            let mut px4 = Px4Battery::new(cells, 5000.0);
            let mut ap = ArduBattery::new(5000.0);
            for (k, (dt, v, i)) in rows.iter().copied().enumerate() {
                px4.update(dt, v, i);
                ap.update(dt, v, i);
                proptest::prop_assert!((0.0..=1.0).contains(&px4.soc()), "{}", px4.soc());
                proptest::prop_assert!(px4.r_cell().is_finite() && px4.r_cell() >= 0.0);
                proptest::prop_assert!(ap.resistance().is_finite() && ap.resistance() >= 0.0);
                proptest::prop_assert!((0.0..=1.0).contains(&ap.remaining()));
                if v.is_finite() {
                    proptest::prop_assert!(ap.resting_v(v, i.max(0.0)) >= v);
                }
                let fired = ap.low_failsafe(k as f64 * 0.1, v, 10.5);
                proptest::prop_assert!(fired.is_none_or(|t| t <= k as f64 * 0.1));
            }
        }
    }

    /// The case proptest found: a negative current after a reading counts the charge back up,
    /// and PX4's state of charge stayed over 1 (1.0005).
    #[test]
    fn a_negative_current_never_takes_px4_s_state_of_charge_over_1() {
        let mut px4 = Px4Battery::new(0, 5000.0);
        for (dt, v, i) in [
            (0.0, 17.700_051_549_400_24, 0.0),
            (
                2.220_318_082_234_523_4,
                4.036_537_779_354_386,
                -4.027_342_950_747_197,
            ),
        ] {
            px4.update(dt, v, i);
            assert!((0.0..=1.0).contains(&px4.soc()), "{}", px4.soc());
        }
    }

    #[test]
    fn px4_learns_the_resistance_and_compensates_the_sag() {
        // 6S, 24 mΩ a pack (4 mΩ a cell), resting at 23.4 V (3.9 V a cell).
        let mut b = Px4Battery::new(6, 5700.0);
        for _ in 0..30 {
            b.update(0.1, 23.4, 0.5);
        }
        for k in 0..600 {
            let (v, i) = pack(k, 23.4, 0.024);
            b.update(0.1, v, i);
        }
        assert!((b.r_cell() - 0.004).abs() < 0.001, "{}", b.r_cell());
        // The compensated voltage is back near the resting one, not 0.36-0.72 V under it.
        assert!(
            (b.compensated_v() - 23.4).abs() < 0.1,
            "{}",
            b.compensated_v()
        );
        // 3.9 V a cell on the 3.6-4.05 V line is 2/3; a minute at 15-30 A used ~6 % more.
        assert!((0.55..0.68).contains(&b.soc()), "{}", b.soc());
    }

    #[test]
    fn px4_starts_from_the_voltage_and_never_above_the_coulomb_count() {
        // A full pack (4.05 V a cell) reads 1 once settled; with half its capacity counted
        // out, the state of charge is capped at one half whatever the voltage says.
        let mut b = Px4Battery::new(4, 1000.0);
        for _ in 0..30 {
            b.update(0.1, 16.2, 0.0);
        }
        assert!((b.soc() - 1.0).abs() < 1e-9, "{}", b.soc());
        for _ in 0..1800 {
            b.update(0.1, 16.2, 10.0);
        }
        assert!(b.soc() <= 0.5 + 1e-9, "{}", b.soc());
        // Garbage in (NaN) changes nothing.
        let s = b.soc();
        b.update(0.1, f64::NAN, 5.0);
        assert_eq!(b.soc(), s);
    }

    #[test]
    fn ardupilot_counts_from_full_and_learns_a_positive_resistance() {
        let mut b = ArduBattery::new(5700.0);
        assert_eq!(b.remaining(), 1.0, "full at boot, whatever the voltage");
        // A charging current (the proptest's first find) never reads over full.
        let mut charging = ArduBattery::new(5700.0);
        charging.update(1.8, 0.0, -4.05);
        assert_eq!(charging.remaining(), 1.0);
        b.update(0.1, 23.4, 0.5);
        for k in 0..600 {
            let (v, i) = pack(k, 23.4, 0.024);
            b.update(0.1, v, i);
        }
        assert!(
            b.resistance() > 0.005 && b.resistance() < 0.05,
            "{}",
            b.resistance()
        );
        let (v, i) = pack(0, 23.4, 0.024);
        assert!(b.resting_v(v, i) > v);
        // The raw-voltage failsafe: a 9 s dip under 21.0 V is forgiven, 11 s is not.
        let mut fs = ArduBattery::new(5700.0);
        for k in 0..=90 {
            assert_eq!(fs.low_failsafe(f64::from(k) * 0.1, 20.8, 21.0), None);
        }
        assert_eq!(
            fs.low_failsafe(9.1, 21.2, 21.0),
            None,
            "back above: the timer restarts"
        );
        let fired = (0..=110)
            .filter_map(|k| fs.low_failsafe(10.0 + f64::from(k) * 0.1, 20.8, 21.0))
            .next();
        assert!(fired.is_some_and(|t| (t - 20.1).abs() < 1e-9), "{fired:?}");
        // 60 s at 22.5 A mean: 375 mAh of 5700.
        assert!(
            (b.remaining() - (1.0 - 375.0 / 5700.0)).abs() < 0.01,
            "{}",
            b.remaining()
        );
    }
}
